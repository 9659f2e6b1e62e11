"""Every plan runs as planned: the planner's points (picking_core.trajectory.waypoints) through the
controller's core give, at every tick, the plan's own position, velocity and acceleration, for every
method, and never a limited command.

The bound (docs/controller.md): within 1e-9 rad, 1e-7 rad/s and 1e-4 rad/s^2 of the plan.
"""

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from picking_controller.core import ControllerCore, Tolerances
from picking_core.kinematics import ArmModel, pose_matrix
from picking_core.pick_cycle import PickCycle, PickSettings
from picking_core.planning import PATH_METHODS, POSE_METHODS, Planner, PlannerSettings
from picking_core.trajectory import concatenate, waypoints
from picking_description import default_urdf

BOUND = (1e-9, 1e-7, 1e-4)
ARM = ArmModel.from_urdf(default_urdf())
HOME = np.array([0.0, 0.2, 1.6, 0.0, -0.23, 0.0])
Z = np.zeros(6)
DOWN = Rotation.from_euler('xyz', [180, 0, 0], degrees=True).as_quat()
APPLE = pose_matrix([0.70, 0.15, 0.65], [0.0, np.sqrt(0.5), 0.0, np.sqrt(0.5)])
JERK_LIMITED = dict(method='optimal', path_method='optimal', limit_jerk=True, cartesian_profile='optimal')


def controller(q):
    names = ARM.all_joint_names
    core = ControllerCore(names, *ARM.all_limits, Tolerances(), optional=names[ARM.dof:])
    core.on_state(np.concatenate([q, np.full(len(names) - len(q), 0.09)]), None, 0.0, now=0.0)
    return core


def send(core, plan, start_time, now, before=None):
    """The plan's points as the planner sends them, stamped to start at ``start_time``."""
    names = list(plan.joint_names or ARM.joint_names)
    t, q, qd, qdd = waypoints(plan.trajectory, 0.01, before=before)
    event = core.load(names, t, q, qd, qdd, start_time, now=now)
    assert event.level == 'OK', event.message
    return names


def run_and_compare(core, plans, since, until, rng):
    """Tick every ms (random phase) from ``since`` to ``until``: the command against the plan ``plans`` (a list of
    ``(start_time, plan, names)``, newest last) says is active then. Returns the largest deviations."""
    worst = np.zeros(3)
    for now in rng.uniform(0, 1e-3) + np.arange(since, until, 1e-3):
        (q, qd, qdd), events = core.command(now)
        assert not events, events[0].message
        start, plan, names = next(p for p in reversed(plans) if p[0] <= now or p is plans[0])
        # (Before the first plan starts, the arm rests where it begins.)
        want = plan.trajectory.state_at(now - start) if now >= start else \
            (plan.trajectory.start_state()[0], 0.0, 0.0)
        cols = [core.names.index(n) for n in names]
        got = (q[cols], qd[cols], qdd[cols])
        worst = np.maximum(worst, [np.abs(g - w).max() for g, w in zip(got, want)])
    assert core.guard.limited == 0
    return worst


def _check(plan, start=HOME, seed=0):
    core = controller(start)
    names = send(core, plan, 0.3, now=0.0, before=Z)
    worst = run_and_compare(core, [(0.3, plan, names)], 0.0, 0.3 + plan.duration + 0.2, np.random.default_rng(seed))
    assert (worst <= BOUND).all(), worst


@pytest.mark.parametrize('jerk', [False, True], ids=['paper', 'jerk-limited'])
@pytest.mark.parametrize('method', POSE_METHODS)
def test_pose_goals_run_as_planned(method, jerk):
    settings = PlannerSettings(speed_scale=1.0, **(JERK_LIMITED if jerk else {}))
    if jerk and method in ('cubic', 'lspb'):
        pytest.skip('refused with limit_jerk: their acceleration steps')
    plan = Planner(ARM, settings).plan_pose((HOME, Z, Z), pose_matrix([0.6, 0.1, 0.4], DOWN), method)
    _check(plan)


@pytest.mark.parametrize('method', PATH_METHODS)
def test_path_goals_run_as_planned(method):
    poses = [pose_matrix(p, DOWN) for p in ([0.6, 0.1, 0.4], [0.55, -0.1, 0.45], [0.6, -0.2, 0.35])]
    plan = Planner(ARM, PlannerSettings(speed_scale=1.0)).plan_path((HOME, Z, Z), poses, method)
    _check(plan)


@pytest.mark.parametrize('blend', [False, True], ids=['paper', 'jerk-limited-blended'])
def test_the_pick_cycle_runs_as_planned(blend):
    if blend:
        planner = Planner(ARM, PlannerSettings(speed_scale=1.0, **JERK_LIMITED))
        settings = PickSettings(approach_method='optimal', transfer_method='optimal', blend=True,
                                blend_radius=0.02).validate(ARM)
    else:
        planner, settings = Planner(ARM, PlannerSettings(speed_scale=1.0)), PickSettings().validate(ARM)
    _check(PickCycle(planner, settings).plan((HOME, Z, Z), APPLE))


def test_a_plan_carrying_on_mid_motion_takes_over_exactly_where_it_begins():
    """A new goal while the arm moves: planned from the state the running plan has at its start,
    stamped there, it takes over at that instant with no lead-in (the acceleration steps there)."""
    planner = Planner(ARM, PlannerSettings(speed_scale=1.0, method='lspb'))
    first = planner.plan_pose((HOME, Z, Z), pose_matrix([0.6, 0.1, 0.4], DOWN))
    core = controller(HOME)
    names = send(core, first, 0.1, now=0.0, before=Z)
    t_new = 0.1 + 0.4 * first.duration
    state = first.trajectory.state_at(t_new - 0.1)
    second = planner.plan_pose(state, pose_matrix([0.55, -0.15, 0.45], DOWN))
    rng = np.random.default_rng(1)
    plans = [(0.1, first, names)]
    worst = run_and_compare(core, plans, 0.0, t_new - 0.15, rng)
    plans.append((t_new, second, send(core, second, t_new, now=t_new - 0.15, before=state[2])))
    worst = np.maximum(worst, run_and_compare(core, plans, t_new - 0.15, t_new + second.duration + 0.2, rng))
    assert (worst <= BOUND).all(), worst


def test_a_plan_stamped_a_fraction_of_a_microsecond_off_still_takes_over_exactly_where_it_begins():
    """A harvest's next tree spliced where a release ends: the running plan rests there and its next move
    starts at once at its jerk limit. The new plan's stamp (float seconds of the epoch) places its first
    point a fraction of a microsecond off, where the reference's acceleration has already moved: it still
    takes over there as planned, not through a lead-in from wherever the arm is when it arrives."""
    planner = Planner(ARM, PlannerSettings(speed_scale=1.0, **JERK_LIMITED))
    there = pose_matrix([0.6, 0.1, 0.4], DOWN)
    move = planner.plan_pose((HOME, Z, Z), there)
    rest = move.trajectory.end_state()[0]
    onward = planner.plan_pose((rest, Z, Z), pose_matrix([0.55, -0.15, 0.45], DOWN))
    first = SimpleNamespace(trajectory=concatenate([move.trajectory, onward.trajectory]), joint_names=None)
    core = controller(HOME)
    names = send(core, first, 0.1, now=0.0, before=Z)
    t_new = 0.1 + move.duration
    second = planner.plan_pose((rest, Z, Z), pose_matrix([0.65, 0.2, 0.5], DOWN))
    rng = np.random.default_rng(2)
    plans = [(0.1, first, names)]
    worst = run_and_compare(core, plans, 0.0, t_new - 0.3, rng)        # sent while the arm still moves there
    plans.append((t_new + 4e-7, second, send(core, second, t_new + 4e-7, now=t_new - 0.3, before=Z)))
    worst = np.maximum(worst, run_and_compare(core, plans, t_new - 0.3, t_new + second.duration + 0.2, rng))
    assert (worst <= BOUND).all(), worst
