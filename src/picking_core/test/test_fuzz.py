"""Every public core function over arbitrary numbers and shapes: refused with ValueError, never a crash or a NaN.

NaN, +-inf, huge and tiny values, zero and negative durations, mismatched lengths,
repeated points. Only ``ValueError`` (``Unreachable`` is one) may come out; whatever
comes back is finite. The default run tries 60 examples per function; the long run
tries 10 000:

    pytest -m fuzz --hypothesis-profile=long src/picking_planner/test/test_fuzz.py    # make fuzz
"""

import math

import numpy as np
import pytest
from hypothesis import event, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from picking_core import geometry, trajectory
from picking_core.kinematics import cartesian_to_joint, pose_matrix
from picking_core.kinematics.paths import check_joint_limits
from picking_core.pick_cycle import PickCycle, PickSettings
from picking_core.planning import Planner, PlannerSettings

pytestmark = pytest.mark.fuzz

# Any float at all, and "reasonable" ones that still reach huge, tiny, zero and negative.
ANY = st.floats(allow_nan=True, allow_infinity=True, width=64)
WILD = st.one_of(ANY, st.sampled_from([0.0, -0.0, 1e-300, -1e-300, 1e300, -1e300, 1e-9, 1.0, -1.0]),
                 st.floats(-10, 10))
SMALL = st.integers(0, 4)


def arrays(ndim_max=2):
    shape = hnp.array_shapes(min_dims=0, max_dims=ndim_max, min_side=0, max_side=5)
    return hnp.arrays(np.float64, shape, elements=WILD)


def vectors(n_max=4):
    return st.one_of(WILD, hnp.arrays(np.float64, st.integers(0, n_max), elements=WILD))


def _finite(result):
    """Every number reachable in a result is finite (arrays, tuples, trajectories, plans)."""
    if result is None or isinstance(result, (str, bool)):
        return
    if isinstance(result, trajectory.PiecewisePolynomial):
        assert np.all(np.isfinite(result.coeffs)) and np.all(np.isfinite(result.breaks))
        return
    if hasattr(result, 'trajectory') and isinstance(result.trajectory, trajectory.PiecewisePolynomial):
        _finite(result.trajectory)
        return
    if isinstance(result, (tuple, list)):
        for r in result:
            _finite(r)
        return
    if isinstance(result, (float, int, np.floating, np.ndarray)):
        assert np.all(np.isfinite(np.asarray(result, dtype=float))), result


def refused_or_finite(fn, *args, **kwargs):
    try:
        result = fn(*args, **kwargs)
    except ValueError:
        return None
    _finite(result)
    return result


# -- trajectory ------------------------------------------------------------------------
@given(vectors(), vectors(), WILD, vectors())
def test_cubic(q0, qf, T, v0):
    refused_or_finite(trajectory.cubic, q0, qf, T, v0)


@given(vectors(), vectors(), WILD, vectors(), vectors(), vectors())
def test_quintic(q0, qf, T, v0, vf, a0):
    refused_or_finite(trajectory.quintic, q0, qf, T, v0, vf, a0)


@given(vectors(), vectors(), WILD, vectors())
def test_lspb_and_its_minimum(q0, qf, T, accel):
    refused_or_finite(trajectory.lspb, q0, qf, T, accel)
    refused_or_finite(trajectory.min_lspb_accel, q0, qf, T)


@given(arrays(), arrays(1), vectors())
def test_via_lspb(points, durations, accel):
    traj = refused_or_finite(trajectory.via_lspb, points, durations, accel)
    timing = refused_or_finite(trajectory.via_lspb_timing, points, durations, accel)
    assert (traj is None) == (timing is None)           # the timing refuses exactly what the trajectory does


@given(arrays(), arrays(1), st.one_of(st.none(), arrays()), st.one_of(st.none(), arrays()))
def test_quintic_via(points, durations, velocities, accelerations):
    refused_or_finite(trajectory.quintic_via, points, durations, velocities, accelerations)


@given(vectors(), vectors(), vectors(), vectors(), vectors(), vectors(), WILD)
def test_time_optimal(q0, qf, v, a, j, v0, min_duration):
    refused_or_finite(trajectory.time_optimal, q0, qf, v, a, j, v0, min_duration=min_duration)


@given(vectors(), vectors(), vectors(), vectors(), vectors(), vectors())
def test_time_optimal_stop(q0, v0, a0, v, a, j):
    refused_or_finite(trajectory.time_optimal_stop, q0, v0, a0, v, a, j)


@given(vectors(), vectors(), vectors(), vectors(), WILD)
def test_brake_and_hold(q, qd, qdd, amax, T):
    refused_or_finite(trajectory.brake, q, qd, qdd, amax)
    refused_or_finite(trajectory.hold, q, T)


@given(arrays(1), hnp.arrays(np.float64, st.tuples(SMALL, st.integers(0, 7), SMALL), elements=WILD))
def test_piecewise_polynomial_construction(breaks, coeffs):
    refused_or_finite(trajectory.PiecewisePolynomial, breaks, coeffs)


@given(st.floats(0.01, 5.0), arrays(1), WILD)
def test_sampling_at_any_time(T, times, t):
    traj = trajectory.via_lspb([[0.0, 1.0], [0.5, -1.0], [1.0, 0.0]], [T, T], 1e6)
    refused_or_finite(traj.sample, times)
    refused_or_finite(traj.jerk, times)
    if math.isfinite(t):
        refused_or_finite(traj.state_at, t)


@given(st.lists(st.tuples(st.floats(0.01, 3.0), vectors(2)), min_size=0, max_size=3))
def test_concatenate_and_stack(parts):
    trajs = []
    for T, q in parts:
        try:
            trajs.append(trajectory.hold(q, T))
        except ValueError:
            pass
    refused_or_finite(trajectory.concatenate, trajs)
    refused_or_finite(trajectory.stack, trajs)


# -- geometry --------------------------------------------------------------------------
@given(arrays(1), arrays(1), arrays(1))
def test_arc_through_three_points(p1, p2, p3):
    arc = refused_or_finite(geometry.Arc.through, p1, p2, p3)
    if arc is not None:
        refused_or_finite(arc.at, np.linspace(0.0, arc.length, 7))
        refused_or_finite(arc.points, 5)


@given(arrays(1), arrays(1), WILD, st.sampled_from(['cubic', 'quintic', 'lspb', 'optimal', 'nonsense']))
def test_line_and_timed_path(a, b, T, profile):
    line = refused_or_finite(geometry.Line, a, b)
    if line is not None:
        path = refused_or_finite(geometry.CartesianPath.timed, line, T, profile)
        if path is not None:
            refused_or_finite(path.sample, np.linspace(0.0, path.duration, 5))
    refused_or_finite(geometry.progress_profile, T, profile)


@given(arrays(3), arrays(1))
def test_timed_path_orientations(orientations, keys):
    line = geometry.Line((0.0, 0.0, 0.0), (1.0, 0.0, 0.0))
    path = refused_or_finite(geometry.CartesianPath.timed, line, 1.0, orientations=orientations,
                             keys=None if keys.size == 0 else keys)
    if path is not None:
        refused_or_finite(path.poses, np.linspace(0.0, 1.0, 5))


# -- kinematics ------------------------------------------------------------------------
@given(arrays(3))
def test_fk_ik_and_reachability(arm, T):
    refused_or_finite(arm.fk, T[..., :6] if T.ndim else T)
    refused_or_finite(arm.ik, T)
    refused_or_finite(arm.check_reachable, T)
    try:
        q, ok, reasons = arm.ik_batch(T)
    except ValueError:
        return
    assert np.all(np.isfinite(q[ok]))


@given(vectors(3), vectors(4), vectors(7))
def test_ik_of_any_position_and_orientation_from_any_seed(arm, p, quat, seed):
    T = refused_or_finite(pose_matrix, p, quat)
    if T is not None:
        q = refused_or_finite(arm.ik, T, seed)
        if q is not None:
            assert np.all(arm.within_limits(q))


@given(vectors(3), vectors(4))
def test_pose_matrix(p, quat):
    refused_or_finite(pose_matrix, p, quat)


@given(arrays(1), arrays(1), WILD)
def test_cartesian_to_joint(arm, a, b, T):
    try:
        path = geometry.CartesianPath.timed(geometry.Line(a, b), T)
    except ValueError:
        return
    refused_or_finite(cartesian_to_joint, arm, path, [0.0, 0.2, 1.6, 0.0, 1.3, 0.0])


@given(arrays(2))
def test_check_joint_limits(arm, q):
    t = np.arange(len(q)) if q.ndim else np.zeros(1)
    refused_or_finite(check_joint_limits, arm, t, q, q, q)


# -- planning --------------------------------------------------------------------------
HOME = np.array([0.0, 0.2, 1.6, 0.0, 1.3, 0.0])


@given(vectors(3), vectors(4), vectors(6), st.sampled_from(['cubic', 'quintic', 'lspb', 'optimal', 'line', 'x']))
def test_plan_pose(arm, p, quat, qd, method):
    try:
        T = pose_matrix(p, quat)
    except ValueError:
        return
    refused_or_finite(Planner(arm).plan_pose, (HOME, qd, np.zeros(6)), T, method)


@given(st.lists(st.tuples(vectors(3), vectors(4)), max_size=3),
       st.sampled_from(['via_lspb', 'quintic_via', 'optimal', 'line', 'arc']))
def test_plan_path(arm, poses, method):
    mats = []
    for p, quat in poses:
        try:
            mats.append(pose_matrix(p, quat))
        except ValueError:
            return
    refused_or_finite(Planner(arm).plan_path, (HOME, np.zeros(6), np.zeros(6)), mats, method)


@given(st.fixed_dictionaries({'speed_scale': WILD, 'duration': WILD, 'sample_period': WILD,
                              'cartesian_speed': WILD, 'max_joint_step': WILD}))
def test_planner_settings(values):
    refused_or_finite(PlannerSettings(**values).validate)


@given(vectors(3), st.fixed_dictionaries({'approach_distance': WILD, 'lift_height': WILD, 'grasp_time': WILD,
                                          'transfer_lift': WILD}))
def test_pick_cycle(arm, p, values):
    try:
        settings_ = PickSettings(**values).validate(arm)
        T = pose_matrix(p, [0.0, math.sqrt(0.5), 0.0, math.sqrt(0.5)])
    except ValueError:
        return
    refused_or_finite(PickCycle(Planner(arm, PlannerSettings(speed_scale=1.0)), settings_).plan,
                      (np.array(settings_.home_positions), np.zeros(6), np.zeros(6)), T)


ROUNDED = st.fixed_dictionaries({'blend_radius': st.floats(0.0, 0.06), 'lift_height': st.floats(0.01, 0.12),
                                 'approach_distance': st.floats(0.01, 0.15), 'box_drop_height': st.floats(0.01, 0.2),
                                 'box_blend_radius': st.floats(0.0, 0.2),
                                 'lift_method': st.sampled_from(['line', 'arc', 'back'])})


@settings(max_examples=60)          # a blended cycle takes about 0.1 s to plan: 60 even in the long profile
@given(st.floats(0.55, 0.8), st.one_of(ROUNDED, st.fixed_dictionaries({
    'blend_radius': WILD, 'lift_height': WILD, 'approach_distance': WILD, 'box_drop_height': WILD,
    'box_blend_radius': WILD})))
def test_blended_pick_cycle_with_rounded_corners(arm, x, values):
    try:
        settings_ = PickSettings(approach_method='optimal', transfer_method='optimal', blend=True,
                                 **values).validate(arm)
    except ValueError:
        return
    planner = Planner(arm, PlannerSettings(speed_scale=1.0, method='optimal', path_method='optimal', limit_jerk=True,
                                           cartesian_profile='optimal'))
    T = pose_matrix([x, 0.15, 0.65], [0.0, math.sqrt(0.5), 0.0, math.sqrt(0.5)])
    plan = refused_or_finite(PickCycle(planner, settings_).plan, (np.array(settings_.home_positions),
                                                                  np.zeros(6), np.zeros(6)), T)
    event('planned' if plan is not None else 'refused while planning')
