"""A pick aimed at a moving apple: the closing instant read off the plan, the aim at the prediction for it, the
instant kept across re-plans from the moving arm, and the approach that carries on from a moving arm."""

import numpy as np
import pytest
from conftest import shipped_harvest
from scipy.spatial.transform import Rotation

from picking_core.harvest import SIDEWAYS
from picking_core.moving_pick import AGREE, Aim, aim, closing_margin, closing_time, final_approach

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


def test_an_uncertain_prediction_leaves_no_closing_margin():
    T = _pose(APPLE)
    sure = Aim(None, T, 1.0, APPLE, np.eye(3) * 0.001 ** 2)
    unsure = Aim(None, T, 1.0, APPLE, np.eye(3) * 0.01 ** 2)
    off = Aim(None, T, 1.0, APPLE + [0.0, 0.015, 0.0], np.eye(3) * 0.001 ** 2)
    assert closing_margin(sure) == pytest.approx(0.02 - 0.003)
    assert closing_margin(unsure) < 0 and closing_margin(off) < closing_margin(sure) - 0.01
