"""A tree's harvest: the order, the chained cycles, skips, a replaced queue."""

import itertools

import numpy as np
import pytest

from picking_core.harvest import Harvest, best_order, route_cost, synthetic_tree
from picking_core.kinematics import pose_matrix
from picking_core.kinematics.paths import check_joint_limits
from picking_core.pick_cycle import PickCycle, PickSettings
from picking_core.planning import Planner, PlannerSettings


@pytest.fixture(scope='module')
def harvest(arm):
    """The shipped settings: jerk-limited, blended, corners rounded."""
    planner = Planner(arm, PlannerSettings(speed_scale=1.0, method='optimal', path_method='optimal',
                                           limit_jerk=True, cartesian_profile='optimal'))
    settings = PickSettings(approach_method='optimal', transfer_method='optimal', blend=True,
                            blend_radius=0.02).validate(arm)
    return Harvest(PickCycle(planner, settings))


@pytest.fixture(scope='module')
def home(harvest):
    z = np.zeros(harvest.arm.dof)
    return harvest.home, z, z


@pytest.fixture(scope='module')
def five(harvest, home):
    apples = synthetic_tree(5, seed=4)
    return apples, harvest.plan(home, apples)


@pytest.mark.parametrize('seed', range(20))
def test_the_order_is_never_worse_than_the_given_one_and_finds_the_best_of_a_small_tree(seed):
    rng = np.random.default_rng(seed)
    n = 6
    first, between, last = rng.uniform(0.5, 2, n), rng.uniform(0.5, 2, (n, n)), rng.uniform(0.5, 2, n)
    route = best_order(first, between, last)
    assert sorted(route) == list(range(n))
    cost = route_cost(route, first, between, last)
    assert cost <= route_cost(range(n), first, between, last)
    best = min(route_cost(r, first, between, last) for r in itertools.permutations(range(n)))
    assert cost == pytest.approx(best)


@pytest.mark.parametrize('seed', range(5))
def test_the_order_of_a_large_tree_beats_the_given_one_fast(seed):
    """30 apples on a plane, costs their distances (a metric, as move times are): the local search's
    route is never worse than the given order, and far better than a shuffled one."""
    p = np.random.default_rng(seed).uniform(0, 1, (30, 2))
    between = np.linalg.norm(p[:, None] - p[None], axis=2)
    to = np.linalg.norm(p, axis=1)
    route = best_order(to, between, to)
    assert sorted(route) == list(range(30))
    assert route_cost(route, to, between, to) < 0.5 * route_cost(range(30), to, between, to)


def test_apples_that_line_up_are_visited_in_line():
    """Apples on a line, costs their distances, given shuffled, the start at one end: visited from
    there to the other end."""
    x = np.array([3.0, 0.0, 4.0, 1.0, 2.0])
    between = np.abs(x[:, None] - x[None, :])
    route = best_order(np.abs(x), between, np.zeros(5))
    assert [x[k] for k in route] == [0, 1, 2, 3, 4]


def test_a_harvest_goes_box_to_next_apple_and_home_after_the_last_within_every_limit(harvest, home, five):
    apples, hp = five
    plan = hp.plan
    assert len(hp.apples) == 5 and not hp.skipped
    assert sorted(a.index for a in hp.apples) == list(range(5))
    labels = [s.label for s in plan.segments]
    # Home once at the start (already there) and once after the last apple; between apples, out of the box.
    assert sum('back home' in label for label in labels) == 1 and labels[-1] == 'home: P0 back home'
    assert sum('P4 out of the box' in label for label in labels) == 5          # 4 to the next apple, 1 home
    assert sum(label.endswith(': grasp') for label in labels) == 5
    for a, b in zip(hp.apples, hp.apples[1:]):
        assert b.start == pytest.approx(a.end)
    # One continuous motion within the limits: sampled finely, and exactly across every break.
    t = np.union1d(np.arange(0.0, plan.duration, 0.002), plan.trajectory.breaks)
    q, qd, qdd = plan.trajectory.sample(t)
    check_joint_limits(harvest.arm, t, q[:, :6], qd[:, :6], qdd[:, :6], slack=1e-6)
    for b in plan.trajectory.breaks[1:-1]:
        before, after = plan.trajectory.state_at(b - 1e-9), plan.trajectory.state_at(b + 1e-9)
        for x, y, tol in zip(before, after, (1e-6, 1e-5, 1e-2)):
            assert np.abs(x - y).max() < tol, b
    end = plan.trajectory.end_state()
    assert end[0][:6] == pytest.approx(home[0], abs=1e-6) and np.abs(end[1]).max() < 1e-9
    # Each apple is in the box (the tool at the drop point, at rest, gripper open) when its time ends.
    for a in hp.apples:
        q_end, qd_end, _ = plan.trajectory.state_at(a.end)
        assert np.linalg.norm(harvest.arm.fk(q_end[:6])[:3, 3] - harvest.cycle.s.box_position) < 1e-3
        assert np.abs(qd_end).max() < 1e-6 and q_end[6] == pytest.approx(harvest.cycle.s.gripper_open)


def test_the_planned_order_is_no_slower_than_the_given_one(harvest, home, five):
    apples, hp = five
    naive = harvest.plan(home, apples, ordered=False)
    assert [a.index for a in naive.apples] == list(range(5))
    assert hp.ordered <= hp.given + 1e-9
    assert hp.plan.duration <= naive.plan.duration * 1.02          # (planned moves, not the estimates)


def test_an_apple_out_of_reach_is_skipped_with_its_reason_and_the_rest_are_picked(harvest, home):
    apples = synthetic_tree(3, seed=1)
    apples.insert(1, pose_matrix([2.5, 0.0, 0.6], [0.0, np.sqrt(0.5), 0.0, np.sqrt(0.5)]))
    hp = harvest.plan(home, apples)
    assert [s.index for s in hp.skipped] == [1] and 'unreachable' in hp.skipped[0].reason
    assert sorted(a.index for a in hp.apples) == [0, 2, 3]
    with pytest.raises(ValueError, match='no apple can be picked .*apple 0: unreachable'):
        harvest.plan(home, apples[1:2])


def test_a_harvest_that_replaces_another_starts_from_the_box_after_the_apple_in_hand(harvest, five):
    """The state after the first apple's release (at rest in the box): the new harvest rises out of the
    box to its first apple, without going home."""
    apples, hp = five
    q, qd, qdd = hp.plan.trajectory.state_at(hp.apples[0].end)
    start = (q[:6], qd[:6], qdd[:6])
    assert harvest.in_box(start) and not harvest.in_box((harvest.home, qd[:6], qdd[:6]))
    again = harvest.plan(start, synthetic_tree(2, seed=9), gripper_start=q[6])
    assert again.plan.segments[0].label.endswith('P4 out of the box')
    assert again.plan.trajectory.start_state()[0][:6] == pytest.approx(q[:6], abs=1e-9)


def test_a_synthetic_tree_is_seeded_and_spaced():
    a, b = synthetic_tree(30, seed=3), synthetic_tree(30, seed=3)
    assert np.array_equal(np.array(a), np.array(b))
    p = np.array([T[:3, 3] for T in a])
    d = np.linalg.norm(p[:, None] - p[None], axis=2) + np.eye(30)
    assert d.min() >= 0.08
    with pytest.raises(ValueError, match='do not fit'):
        synthetic_tree(500, seed=0)


def test_a_running_harvest_reports_each_apple_once_and_sums_up_what_was_picked(five):
    from picking_core.harvest import REPORT_MARGIN, HarvestRun
    _, hp = five
    run = HarvestRun(hp, 100.0)
    ends = [100.0 + a.end + REPORT_MARGIN for a in hp.apples]
    assert run.newly_picked(ends[0] - 0.01) == []
    assert [(k, a.index) for k, a in run.newly_picked(ends[1])] == [(1, hp.apples[0].index), (2, hp.apples[1].index)]
    assert run.newly_picked(ends[1] + 0.01) == []
    # Aborted after the second apple: two picked, at their rate; finished: all five in the plan's time.
    aborted = run.summary(ends[1] + 0.5, finished=False)
    assert aborted['picked'] == 2 and aborted['planned'] == 5
    assert aborted['apples_per_hour'] == pytest.approx(3600 * 2 / (ends[1] + 0.5 - 100.0))
    done = run.summary(1e9, finished=True)
    assert done['picked'] == 5 and done['harvest_time'] == pytest.approx(hp.plan.duration)
    assert '5 of 5 apples picked, 0 skipped' in run.words(1e9, True)
    # A harvest sent meanwhile starts after the apple in hand; the replaced one counts what was picked by then.
    t = 100.0 + 0.5 * (hp.apples[2].start + hp.apples[2].end)
    assert run.after_apple_in_hand(t) == pytest.approx(100.0 + hp.apples[2].end)
    assert run.after_apple_in_hand(100.0 + hp.plan.duration) == 100.0 + hp.plan.duration
    run.until = 100.0 + hp.apples[2].end + REPORT_MARGIN
    assert run.summary(1e9, finished=False)['picked'] == 3
    # A rest that took over in the box and has not begun: its own start is the soonest time with no apple in hand.
    rest = HarvestRun(hp, 200.0, before=run)
    assert rest.after_apple_in_hand(150.0) == 200.0
    assert rest.after_apple_in_hand(200.0 + 0.5 * hp.apples[0].end) == pytest.approx(200.0 + hp.apples[0].end)


def test_the_apple_in_hand_when_a_harvest_ends_early_is_the_one_whose_cycle_ran(five):
    from picking_core.harvest import HarvestRun
    _, hp = five
    run = HarvestRun(hp, 10.0)
    third = hp.apples[2]
    assert run.in_hand(10.0 + 0.5 * (third.start + third.end)) == third
    assert run.in_hand(10.0 + hp.plan.duration + 1.0) is None          # all in the box, on the way home
    run.until = 10.0 + third.end                        # replaced: the new harvest began once it was in the box
    assert run.in_hand(1e9) is None and [a.index for a in run.picked_by(1e9)] == [a.index for a in hp.apples[:3]]


def test_the_rest_of_a_harvest_planned_again_keeps_each_apples_index_in_the_goal(harvest, five):
    """The apples not started when the world changed, planned again from the box after the apple in hand:
    labels, times and skips name each apple by its index in the goal, and the run carries on from the
    first one (what it put in the box counts, each apple reported once)."""
    from picking_core.harvest import REPORT_MARGIN, HarvestGoal, HarvestRun
    apples, hp = five
    goal = HarvestGoal(harvest, apples)
    first = hp.apples[0]
    left = [a.index for a in hp.apples[2:]]
    rest = goal.rest(harvest, left, 'a branch grew', 100.0 + hp.apples[1].end)
    assert rest.continues and rest.indices == left and not goal.continues and goal.after == np.inf
    q, qd, qdd = hp.plan.trajectory.state_at(hp.apples[1].end)
    again = rest((q[:6], qd[:6], qdd[:6]), q[6])
    assert sorted(a.index for a in rest.last.apples) == sorted(left)
    assert {s.label.split(':')[0] for s in again.segments} <= {f'apple {i}' for i in left} | {'home'}
    run = HarvestRun(hp, 100.0)
    assert [a.index for _, a in run.newly_picked(100.0 + first.end + REPORT_MARGIN)] == [first.index]
    splice = 100.0 + hp.apples[1].end
    run.until = splice
    carried = HarvestRun(rest.last, splice, before=run)
    assert carried.in_hand(splice - 0.1) == hp.apples[1]
    assert [a.index for _, a in carried.newly_picked(splice + REPORT_MARGIN)] == [hp.apples[1].index]
    ends = carried.summary(1e9, finished=True)
    assert ends['picked'] == 5 and ends['planned'] == 5
    assert sorted(int(i) for i in ends['picked_apples'].split()) == list(range(5))
    assert ends['harvest_time'] == pytest.approx(splice + rest.last.plan.duration - 100.0)
    assert len(carried.newly_picked(1e9)) == 3


def test_the_apple_in_hand_when_a_rest_is_planned_is_still_watched_in_the_fingers(harvest, five):
    """The run that takes over is the one the planner watches from then on; the apple the run before it still
    carries until then is measured all the same: held or missed by the fingers, never claimed by the plan."""
    from picking_core.harvest import GRIP_SETTLE, HarvestGoal, HarvestRun
    apples, hp = five
    second = hp.apples[1]
    splice = 100.0 + second.end
    rest = HarvestGoal(harvest, apples).rest(harvest, [a.index for a in hp.apples[2:]], 'a new apple', splice)
    q, qd, qdd = hp.plan.trajectory.state_at(second.end)
    rest((q[:6], qd[:6], qdd[:6]), q[6])
    run = HarvestRun(hp, 100.0)
    run.until = splice
    carried = HarvestRun(rest.last, splice, before=run)
    during = 100.0 + 0.5 * (second.held[0] + GRIP_SETTLE + second.held[1])
    carried.watch(during, 0.0)                            # closed on nothing while the run before carried it
    assert carried.holding(second) is False
    carried.watch(splice + 0.01, 0.0)                     # (past the splice: the run before carries nothing)
    first_of_rest = rest.last.apples[0]
    assert carried.holding(first_of_rest) is None


def test_new_apples_are_those_no_harvest_knows_away_from_the_box():
    from picking_core.harvest import BOX_CLEAR, KNOWN_APPLE, new_apples

    def at(*p):
        T = np.eye(4)
        T[:3, 3] = p
        return T
    known = np.array([[0.7, 0.1, 0.6], [0.7, 0.3, 0.6]])
    box = np.array([0.0, -0.5, 0.3])
    seen = [at(0.7, 0.1 + 0.8 * KNOWN_APPLE, 0.6),                     # a known apple, seen a little off
            at(0.7, 0.1 + 1.2 * KNOWN_APPLE, 0.6),                     # a new one between the two
            at(0.7, 0.1 + 1.2 * KNOWN_APPLE + 0.01, 0.6),              # the same new one, seen twice
            at(*(box + [0.0, 0.0, 0.9 * BOX_CLEAR])),                  # one over the box: let go of
            at(0.55, -0.2, 0.8)]                                        # a new one
    new = new_apples(seen, known, box)
    assert [tuple(np.round(T[:3, 3], 3)) for T in new] == [(0.7, 0.1 + round(1.2 * KNOWN_APPLE, 3), 0.6),
                                                            (0.55, -0.2, 0.8)]
    assert new_apples([], known, box) == [] and len(new_apples(seen[-1:], np.empty((0, 3)), box)) == 1
