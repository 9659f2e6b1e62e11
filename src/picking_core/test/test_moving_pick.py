"""A pick aimed at a moving apple: the closing instant read off the plan, the aim at the prediction for it, the
instant kept across re-plans from the moving arm, and the approach that carries on from a moving arm."""

import numpy as np
import pytest
from conftest import shipped_harvest
from scipy.spatial.transform import Rotation

from picking_core.harvest import SIDEWAYS, Harvest
from picking_core.trajectory import PiecewisePolynomial
from picking_core.moving_pick import (
    AGREE,
    DECIDE,
    Aim,
    Follow,
    aim,
    closing_margin,
    closing_time,
    final_approach,
    holds_off,
    sure,
)

ROTATION = Rotation.from_euler('xyz', SIDEWAYS).as_matrix()
APPLE = np.array([0.70, 0.15, 0.65])
WIDTH = 0.07


@pytest.fixture(scope='module')
def cycle():
    return shipped_harvest().cycle


def _home(cycle):
    home = np.asarray(cycle.s.home_positions, float)
    return home, 0 * home, 0 * home


def _pose(p):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = ROTATION, p
    return T


def test_the_fingers_meet_an_apple_during_the_grasp_a_narrower_one_later(cycle):
    plan = cycle.plan(_home(cycle), _pose(APPLE))
    wide, narrow = closing_time(plan, 0.08), closing_time(plan, 0.06)
    assert plan.extra['grasp_start'] < wide < narrow < plan.extra['grasp_end']
    opening = plan.trajectory.sample([narrow])[0][0, -1]
    assert opening == pytest.approx(0.06, abs=1e-3)
    assert final_approach(plan) < plan.extra['grasp_start']


def test_a_still_apple_gets_the_plan_it_gets_today(cycle):
    def still(s):
        return APPLE, np.eye(3) * 1e-6
    a = aim(lambda T, least: cycle.plan(_home(cycle), T, approach_time=least), still, ROTATION, WIDTH)
    today = cycle.plan(_home(cycle), _pose(APPLE))
    assert np.allclose(a.T, _pose(APPLE)) and a.plan.duration == pytest.approx(today.duration, rel=1e-9)
    assert a.at == pytest.approx(closing_time(today, WIDTH))


def test_the_aim_is_where_the_apple_will_be_when_the_fingers_close(cycle):
    """An apple moving at 0.1 m/s along y: the grasp pose is its place at the plan's own closing instant."""
    def moving(s):
        return APPLE + [0.0, 0.1 * s, 0.0], np.eye(3) * 1e-6
    a = aim(lambda T, least: cycle.plan(_home(cycle), T, approach_time=least), moving, ROTATION, WIDTH)
    closes = closing_time(a.plan, WIDTH)
    assert abs(closes - a.at) < 1e-9
    assert np.linalg.norm(a.T[:3, 3] - moving(closes)[0]) < 0.1 * AGREE + 1e-6
    assert closing_margin(a) > 0.01


def test_a_re_plan_from_the_moving_arm_keeps_the_closing_instant_or_is_not_taken(cycle):
    first = cycle.plan(_home(cycle), _pose(APPLE))
    at = closing_time(first, WIDTH)
    t = 0.3                                                    # into the move to P1
    q, qd, qdd = (x[0] for x in first.trajectory.sample([t]))
    moved = APPLE + [0.0, 0.004, 0.0]

    def plan_to(T, least):
        return cycle.plan((q[:-1], qd[:-1], qdd[:-1]), T, float(q[-1]), approach_time=least)
    kept = aim(plan_to, lambda s: (moved, np.eye(3) * 1e-6), ROTATION, WIDTH, at + 0.05 - t)
    assert closing_time(kept.plan, WIDTH) == pytest.approx(at + 0.05 - t, abs=AGREE)   # stretched to the instant
    assert [s.label for s in kept.plan.segments][0] == 'P1 approach'                     # no brake, no way home
    assert np.allclose(kept.plan.trajectory.sample([0.0])[1][0][:-1], qd[:-1], atol=1e-9)
    assert aim(plan_to, lambda s: (moved, np.eye(3) * 1e-6), ROTATION, WIDTH, 0.2) is None   # cannot close so soon


def test_an_uncertain_or_stray_prediction_is_not_sure_enough_to_close_on():
    T = _pose(APPLE)
    certain = Aim(None, T, 1.0, APPLE, np.eye(3) * 0.001 ** 2)
    unsure = Aim(None, T, 1.0, APPLE, np.eye(3) * 0.025 ** 2)
    off = Aim(None, T, 1.0, APPLE + [0.0, 0.025, 0.0], np.eye(3) * 0.001 ** 2)
    assert closing_margin(certain) == pytest.approx(0.02 - 0.001)       # the fingers' 2 cm less one deviation
    assert closing_margin(unsure) == pytest.approx(-0.005) and closing_margin(off) == pytest.approx(-0.006)
    assert sure(certain) and not sure(unsure) and not sure(off)


def test_only_an_aim_that_decides_the_closing_must_be_sure_of_it(cycle):
    """An unsure aim from home (its straight approach a second away, detections still to come) goes on; the same from
    the stand-off (the approach begins at once) holds off, as does any aim of a pick already waiting there; a sure
    one never does."""
    T = _pose(APPLE)
    from_home = cycle.plan(_home(cycle), T)
    P1 = cycle.arm.ik(cycle.key_poses(T)['P1'], seed=np.asarray(cycle.s.home_positions, float))
    at_stand_off = cycle.plan((P1, 0 * P1, 0 * P1), T, from_here=True)
    assert final_approach(from_home) > DECIDE >= final_approach(at_stand_off)
    unsure, certain = np.eye(3) * 0.025 ** 2, np.eye(3) * 0.001 ** 2
    assert not holds_off(Aim(from_home, T, 1.0, APPLE, unsure))
    assert holds_off(Aim(at_stand_off, T, 1.0, APPLE, unsure))
    assert holds_off(Aim(from_home, T, 1.0, APPLE, unsure), holding=True)
    assert not holds_off(Aim(at_stand_off, T, 1.0, APPLE, certain), holding=True)
    by_home = cycle.plan((P1, 0 * P1, 0 * P1), T)                   # a pick from rest anywhere else goes home first
    assert by_home.segments[0].label == 'P0 home' and final_approach(by_home) > final_approach(at_stand_off) + 0.5


def _sway(s):
    """A sway of ±20 mm at 1 Hz along y about the apple (its centre, s s into the plan)."""
    return APPLE + [0.0, 0.02 * np.sin(2 * np.pi * s), 0.0]


def test_riding_the_apple_keeps_it_where_a_still_one_lies_in_the_tool_frame(cycle):
    """From the grasp's start to the closing the ridden tool moves with the swaying apple: the apple lies where a
    still one at the closing place does (the plan as planned), within a millimetre; outside the ride the plan is the
    one planned, and the ridden plan keeps every joint limit."""
    planned = cycle.plan(_home(cycle), _pose(_sway(1.2)), rides=True)
    closes = closing_time(planned, WIDTH)
    ridden = cycle.ride(planned, _sway, closes)
    assert ridden.extra['rides'] and not planned.extra.get('rides')
    dof = cycle.arm.dof
    cycle.planner.check_limits(PiecewisePolynomial(ridden.trajectory.breaks, ridden.trajectory.coeffs[:, :, :dof]),
                               'ridden')
    t = np.linspace(planned.extra['grasp_start'], closes, 20)
    tool = cycle.arm.fk(ridden.trajectory.sample(t)[0][:, :dof])[:, :3, 3]
    still = cycle.arm.fk(planned.trajectory.sample(t)[0][:, :dof])[:, :3, 3]
    apple = np.array([_sway(s) for s in t])
    assert np.abs((apple - tool) - (_sway(closes) - still)).max() < 1e-3
    # The tool did move with the apple on its way in (the sway covers centimetres there) ...
    line = np.linspace(final_approach(planned), closes, 40)
    moved = [cycle.arm.fk(p.trajectory.sample(line)[0][:, :dof])[:, :3, 3] for p in (ridden, planned)]
    assert np.abs(moved[0] - moved[1]).max() > 0.01
    # ... and is on the plan again before the ride and after the lift.
    lift = next(s for s in planned.segments if s.label == 'P3 lift and detach')
    outside = np.concatenate([np.linspace(0.0, final_approach(planned) - 0.6, 20),
                              np.linspace(lift.start + lift.duration, planned.duration, 20)])
    assert np.allclose(ridden.trajectory.sample(outside)[0], planned.trajectory.sample(outside)[0], atol=1e-9)


def test_a_still_apple_or_a_plan_with_no_room_is_not_ridden(cycle):
    planned = cycle.plan(_home(cycle), _pose(APPLE), rides=True)
    closes = closing_time(planned, WIDTH)
    still = cycle.ride(planned, lambda s: APPLE, closes)
    assert not still.extra['rides'] and still.trajectory is planned.trajectory
    # Timed to the joints' limits (not planned to ride), a sway on top would break one: the plan is kept.
    full = cycle.plan(_home(cycle), _pose(_sway(1.2)))
    kept = cycle.ride(full, _sway, closing_time(full, WIDTH))
    assert not kept.extra['rides'] and kept.trajectory is full.trajectory


def test_a_ride_that_would_break_a_limit_takes_on_the_share_of_the_sway_the_limits_allow(cycle):
    """From the stand-off the straight approach begins at once: the ride's ramp is squeezed into it, and taking on
    all of a ±30 mm sway along the approach would break a joint limit. The ride takes on the largest share that
    keeps them rather than none (sent unridden, the line meets an apple swinging toward the arm early)."""
    def sway(s):
        return APPLE + [0.03 * np.sin(2 * np.pi * s), 0.0, 0.0]
    T = _pose(APPLE)
    P1 = cycle.arm.ik(cycle.key_poses(T)['P1'], seed=np.asarray(cycle.s.home_positions, float))
    planned = cycle.plan((P1, 0 * P1, 0 * P1), _pose(sway(1.0)), from_here=True, rides=True)
    closes = closing_time(planned, WIDTH)
    ridden = cycle.ride(planned, sway, closes)
    share = ridden.extra['ride_share']
    assert ridden.extra['rides'] and 0.0 < share < 1.0
    dof = cycle.arm.dof
    cycle.planner.check_limits(PiecewisePolynomial(ridden.trajectory.breaks, ridden.trajectory.coeffs[:, :, :dof]),
                               'ridden')
    t = np.linspace(planned.extra['grasp_start'], closes, 10)
    tool, still = (cycle.arm.fk(p.trajectory.sample(t)[0][:, :dof])[:, :3, 3] for p in (ridden, planned))
    apple = np.array([sway(s) for s in t])
    assert np.abs((tool - still) - share * (apple - sway(closes))).max() < 1e-3


def test_an_aimed_pick_rides_its_apple_when_asked(cycle):
    def swaying(s):
        return _sway(s), np.eye(3) * 1e-6
    a = aim(lambda T, least: cycle.plan(_home(cycle), T, approach_time=least, rides=True), swaying, ROTATION,
            WIDTH, ride=cycle.ride)
    assert a.plan.extra['rides'] and closing_time(a.plan, WIDTH) == pytest.approx(a.at)


def test_a_harvest_aims_its_first_apple_at_its_sway_and_rides_it_the_others_planned_as_today(cycle):
    """Two apples, the first swaying (its Follow's clock starting 100 s before the harvest): its cycle closes the
    fingers where it will be then, the tool riding it, within every joint limit; the still apple's cycle after it is
    the one a harvest without follows plans, and a swaying apple later in the plan is planned where it hangs (the
    rest is aimed again before its turn). A first apple whose sway is too unsure to close on waits for a later turn,
    and is left on the tree, saying why, when no other is left."""
    harvest = Harvest(cycle)
    still, swaying = APPLE + [0.0, -0.25, 0.0], APPLE
    t0 = 100.0
    follow = Follow(lambda t: (_sway(t - t0), np.eye(3) * 1e-6), WIDTH)
    plain = harvest.plan(_home(cycle), [_pose(swaying), _pose(still)], ordered=False)
    aimed = harvest.plan(_home(cycle), [_pose(swaying), _pose(still)], ordered=False, follows={0: follow}, t0=t0)
    first, second = aimed.apples
    assert second.end - second.start == pytest.approx(plain.apples[1].end - plain.apples[1].start)
    dof = cycle.arm.dof
    cycle.planner.check_limits(PiecewisePolynomial(aimed.plan.trajectory.breaks,
                                                   aimed.plan.trajectory.coeffs[:, :, :dof]), 'harvest')
    # The fingers meet the apple's width where the swaying apple is then.
    t = np.arange(first.start, first.held[0], 1e-3)
    opening = aimed.plan.trajectory.sample(t)[0][:, -1]
    closes = t[np.flatnonzero(opening <= WIDTH)[0]]
    tool = cycle.arm.fk(aimed.plan.trajectory.sample([closes])[0][:, :dof])[0, :3, 3]
    assert np.linalg.norm(tool - _sway(closes)) < 1e-3
    later = harvest.plan(_home(cycle), [_pose(still), _pose(swaying)], ordered=False, follows={1: follow}, t0=t0)
    today = harvest.plan(_home(cycle), [_pose(still), _pose(swaying)], ordered=False)
    assert later.plan.duration == pytest.approx(today.plan.duration)
    # Unsure: put off behind the still apple (planned where it hangs, aimed again in its turn); left when alone.
    unsure = Follow(lambda t: (_sway(t - t0), np.eye(3) * 0.03 ** 2), WIDTH)
    put_off = harvest.plan(_home(cycle), [_pose(swaying), _pose(still)], ordered=False, follows={0: unsure}, t0=t0)
    assert [a.index for a in put_off.apples] == [1, 0] and not put_off.skipped
    with pytest.raises(ValueError, match='apple 0: its sway is too unsure to close on'):
        harvest.plan(_home(cycle), [_pose(swaying)], follows={0: unsure}, t0=t0)


def test_a_follow_says_how_far_and_how_fast_its_apple_strays():
    follow = Follow(lambda t: (_sway(t), np.eye(3) * 1e-6))
    extent, speed = follow.reach(APPLE, 3.0)
    assert extent == pytest.approx(0.02, rel=1e-3) and speed == pytest.approx(2 * np.pi * 0.02, rel=1e-3)
    assert Follow(lambda t: (APPLE, np.eye(3) * 1e-6)).reach(APPLE, 0.0) == (0.0, 0.0)
