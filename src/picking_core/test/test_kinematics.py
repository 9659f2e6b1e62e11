"""Arm model, forward and inverse kinematics (Sec. 2.2, Eq. 1-2) and the reachability check (Sec. 3.1 C)."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from picking_core import geometry, kinematics
from picking_core.kinematics import Unreachable, pose_matrix

SHOULDER = 0.35
UPPER, FORE, TOOL = 0.45, 0.40, 0.15


def test_urdf_chain_limits_and_solver(arm):
    assert arm.joint_names == ('shoulder_pan_joint', 'shoulder_lift_joint', 'elbow_joint',
                               'wrist_1_joint', 'wrist_2_joint', 'wrist_3_joint')
    assert arm.solver == 'spherical_wrist'
    assert arm.upper[2] == pytest.approx(2.6) and arm.max_velocity[0] == pytest.approx(2.0)
    assert arm.max_acceleration[2] == pytest.approx(8.0)          # from the joint-limits YAML
    assert arm.max_jerk[5] == pytest.approx(120.0)
    assert arm.base_frame == 'base_link' and arm.tool_frame == 'tool0'


@pytest.mark.parametrize('q, position, rotation', [
    ([0, 0, 0, 0, 0, 0], [0, 0, SHOULDER + UPPER + FORE + TOOL], np.eye(3)),
    ([0, np.pi / 2, 0, 0, 0, 0], [UPPER + FORE + TOOL, 0, SHOULDER],
     Rotation.from_euler('y', 90, degrees=True).as_matrix()),
    ([np.pi / 2, np.pi / 2, 0, 0, 0, 0], [0, UPPER + FORE + TOOL, SHOULDER],
     Rotation.from_euler('ZY', [90, 90], degrees=True).as_matrix()),
    ([0, 0, np.pi / 2, 0, 0, 0], [FORE + TOOL, 0, SHOULDER + UPPER],
     Rotation.from_euler('y', 90, degrees=True).as_matrix()),
    ([0, 0, np.pi / 2, 0, -np.pi / 2, 0], [FORE, 0, SHOULDER + UPPER + TOOL], np.eye(3)),
])
def test_fk_against_poses_worked_out_by_hand(arm, q, position, rotation):
    T = arm.fk(q)
    assert T[:3, 3] == pytest.approx(position, abs=1e-12)
    assert T[:3, :3] == pytest.approx(rotation, abs=1e-12)


def test_fk_is_batched(arm):
    Q = np.random.default_rng(1).uniform(arm.lower, arm.upper, (50, 6))
    batched = arm.fk(Q)
    assert batched.shape == (50, 4, 4)
    assert batched[17] == pytest.approx(arm.fk(Q[17]))


def test_ik_of_fk_for_10000_random_configurations(arm):
    rng = np.random.default_rng(2026)
    Q = rng.uniform(arm.lower, arm.upper, (10_000, 6))
    T = arm.fk(Q)
    seeds = np.clip(Q + rng.normal(0.0, 0.05, Q.shape), arm.lower, arm.upper)
    q, ok, reasons = arm.ik_batch(T, seeds)
    assert ok.mean() >= 0.999, set(reasons)
    assert np.all(arm.within_limits(q[ok]))
    F = arm.fk(q[ok])
    assert np.abs(F[:, :3, 3] - T[ok, :3, 3]).max() <= 1e-6
    angle = Rotation.from_matrix(np.swapaxes(F[:, :3, :3], 1, 2) @ T[ok, :3, :3]).magnitude()
    assert angle.max() <= 1e-6
    # The seed picks the nearest valid solution: never farther than the configuration
    # that made the pose, and that configuration itself when it is the seed.
    nearest = np.sum((q[ok] - seeds[ok]) ** 2, axis=1)
    assert np.all(nearest <= np.sum((Q[ok] - seeds[ok]) ** 2, axis=1) + 1e-9)
    q_exact, ok_exact, _ = arm.ik_batch(T, Q)
    assert ok_exact.mean() >= 0.999
    assert np.abs(q_exact[ok_exact] - Q[ok_exact]).max() < 1e-6


def test_ik_returns_the_valid_solution_nearest_the_seed(arm):
    q_true = np.array([0.4, 0.3, 1.1, 0.5, 0.8, -0.6])
    T = arm.fk(q_true)
    solutions = arm.ik_all(T)
    assert len(solutions) == 8
    valid = [s for s in solutions if arm.within_limits(s)]
    for s in valid:
        assert arm.fk(s) == pytest.approx(T, abs=1e-9) or not arm.within_limits(s)
    for s in valid:
        # Seeded at any valid solution, IK gives that solution back.
        assert arm.ik(T, seed=s) == pytest.approx(s, abs=1e-9)


def test_out_of_reach_is_refused_with_the_distance(arm):
    T = pose_matrix([2.0, 0.0, 0.5])
    with pytest.raises(Unreachable, match='out of reach.*m from the shoulder'):
        arm.ik(T)
    with pytest.raises(Unreachable, match='out of reach'):
        arm.check_reachable(T)


def test_beyond_joint_limits_is_refused(arm):
    # The elbow folded to 2.9 rad (limit 2.6): every branch needs |q3| = 2.9.
    T = arm.fk([0.0, 0.0, 2.9, 0.0, 0.0, 0.0])
    with pytest.raises(Unreachable, match='beyond joint limits'):
        arm.ik(T)


@pytest.mark.parametrize('bad', [
    np.full((4, 4), np.nan), np.eye(3), np.diag([1.0, 1.0, -1.0, 1.0]),
])
def test_malformed_or_non_finite_poses_are_value_errors(arm, bad):
    with pytest.raises(ValueError) as info:
        arm.ik(bad)
    assert not isinstance(info.value, Unreachable)


@pytest.mark.parametrize('bad', [[np.nan] * 6, [0.0] * 5, [0.0, 0.1, 1.0, 0.0, np.inf, 0.0]])
def test_malformed_or_non_finite_seeds_are_value_errors(arm, bad):
    with pytest.raises(ValueError, match='seed') as info:
        arm.ik(arm.fk([0.0, 0.3, 1.2, 0.0, 0.5, 0.0]), bad)
    assert not isinstance(info.value, Unreachable)


def test_pose_matrix_refuses_zero_quaternion():
    with pytest.raises(ValueError, match='quaternion is zero'):
        pose_matrix([0.5, 0, 0.5], [0, 0, 0, 0])


def test_check_reachable_returns_the_solution(arm):
    q = np.array([0.2, 0.5, 1.0, 0.0, 0.6, 0.0])
    assert arm.check_reachable(arm.fk(q), seed=q) == pytest.approx(q)


def test_three_joint_arm_solves_position_only(arm3):
    assert arm3.solver == 'elbow_3r' and arm3.dof == 3
    rng = np.random.default_rng(3)
    Q = rng.uniform(arm3.lower, arm3.upper, (2000, 3))
    T = arm3.fk(Q)
    T[:, :3, :3] = np.eye(3)                                  # orientation is ignored
    q, ok, _ = arm3.ik_batch(T, Q)
    assert ok.mean() >= 0.999
    assert np.abs(arm3.fk(q[ok])[:, :3, 3] - T[ok, :3, 3]).max() < 1e-9
    assert np.abs(q[ok] - Q[ok]).max() < 1e-6


def test_any_other_chain_gets_the_numeric_solver():
    from conftest import URDF
    urdf = URDF.read_text()
    # A 10 cm shoulder offset breaks the closed form's assumptions.
    urdf = urdf.replace('<origin xyz="0 0 0.45" rpy="0 0 0"/>', '<origin xyz="0 0.1 0.45" rpy="0 0 0"/>')
    arm = kinematics.ArmModel.from_urdf_string(urdf)
    assert arm.solver == 'numeric'
    rng = np.random.default_rng(4)
    for _ in range(5):
        q_true = rng.uniform(arm.lower * 0.5, arm.upper * 0.5)
        T = arm.fk(q_true)
        q = arm.ik(T, seed=np.clip(q_true + 0.1, arm.lower, arm.upper))
        assert arm.fk(q) == pytest.approx(T, abs=1e-7)
        assert arm.within_limits(q)
    with pytest.raises(Unreachable, match='out of reach'):
        arm.ik(pose_matrix([3.0, 0, 0]))


def test_cartesian_line_to_joints_reports_deviation_and_limits(arm):
    down = Rotation.from_euler('y', 180, degrees=True).as_quat()
    seed = arm.ik(pose_matrix([0.6, -0.15, 0.45], down), seed=[0, 0.5, 1.2, 0, 1.4, 0])
    line = geometry.Line((0.6, -0.15, 0.45), (0.6, 0.15, 0.45))
    path = geometry.CartesianPath.timed(line, 2.0, 'quintic', orientations=[down])
    result = kinematics.cartesian_to_joint(arm, path, seed)
    assert result.max_deviation < 1e-4
    assert np.all(result.peak_velocity <= arm.max_velocity)
    T_end = arm.fk(result.trajectory.sample(2.0)[0][0])
    assert T_end[:3, 3] == pytest.approx([0.6, 0.15, 0.45], abs=1e-9)


def test_cartesian_path_through_a_singularity_is_refused(arm):
    # Straight over the base: the wrist centre crosses the waist axis (shoulder singularity).
    down = Rotation.from_euler('y', 180, degrees=True).as_quat()
    start = [0.3, -0.3, 0.6]
    seed = arm.ik(pose_matrix(start, down), seed=[0, 0.3, 1.0, 0, 1.0, 0])
    line = geometry.Line(start, (-0.3, 0.3, 0.6))
    path = geometry.CartesianPath.timed(line, 3.0, 'quintic', orientations=[down])
    with pytest.raises(Unreachable, match=r'path fails at t = .*(jump|singular)'):
        kinematics.cartesian_to_joint(arm, path, seed)


def test_a_cartesian_path_timed_over_hours_is_refused_before_it_is_sampled(arm):
    line = geometry.Line((0.5, 0.0, 0.5), (0.5, 0.1, 0.5))
    path = geometry.CartesianPath.timed(line, 1e5)                  # far more samples than any pick needs
    with pytest.raises(ValueError, match='lasts 100000 s: over 100000 samples'):
        kinematics.cartesian_to_joint(arm, path, [0.0, 0.2, 1.6, 0.0, 1.3, 0.0])


def test_cartesian_path_too_fast_breaks_a_velocity_limit(arm):
    down = Rotation.from_euler('y', 180, degrees=True).as_quat()
    seed = arm.ik(pose_matrix([0.6, -0.3, 0.45], down), seed=[0, 0.5, 1.2, 0, 1.4, 0])
    line = geometry.Line((0.6, -0.3, 0.45), (0.6, 0.3, 0.45))
    path = geometry.CartesianPath.timed(line, 0.2, 'quintic', orientations=[down])
    with pytest.raises(Unreachable, match='(velocity|acceleration) limit broken'):
        kinematics.cartesian_to_joint(arm, path, seed, max_joint_step=10.0)


@pytest.mark.parametrize('fixture', ['arm', 'arm3', 'ur5e'])
def test_compiled_ik_agrees_with_the_vectorised_closed_form(fixture, request):
    model = request.getfixturevalue(fixture)
    assert model.load_ik(), 'the compiled IK did not load (numba is a requirement)'
    rng = np.random.default_rng(6)
    n = 10_000
    Q = rng.uniform(model.lower, model.upper, (n, model.dof))
    if model.dof == 6:
        Q[: n // 10, 4] = 0.0                                  # singular wrists
    T = model.fk(Q)
    T[-n // 10:, :3, 3] *= 1.6                                 # many out of reach
    seeds = Q + rng.normal(0.0, 1.0, Q.shape)                  # far seeds, some beyond the limits
    expected, ok, reasons = model._solver.solve(T, seeds)      # the vectorised closed form
    assert 0.5 < ok.mean() < 0.95
    batched, batch_ok, batch_reasons = model.ik_batch(T, seeds)
    assert np.array_equal(batch_ok, ok) and batch_reasons == reasons
    assert batched[ok] == pytest.approx(expected[ok], abs=1e-9) and np.isnan(batched[~ok]).all()
    for i in range(n):
        if ok[i]:
            assert model.ik(T[i], seeds[i]) == pytest.approx(expected[i], abs=1e-9)
        else:
            with pytest.raises(Unreachable, match=reasons[i].split(':')[0]):
                model.ik(T[i], seeds[i])


def test_compiled_ik_takes_any_array_without_compiling_again(arm):
    # A read-only, Fortran-ordered or integer input would make numba compile a new version
    # (seconds, in the middle of planning): the arrays are made plain first.
    q_true = np.array([0.4, 0.3, 1.1, 0.5, 0.8, -0.6])
    T = np.asfortranarray(arm.fk(q_true))
    seed = q_true + 0.01
    T.flags.writeable = seed.flags.writeable = False
    assert arm.ik(T, seed) == pytest.approx(q_true, abs=1e-9)
    assert arm.ik(T, [0, 0, 1, 0, 1, 0]) is not None
    assert arm.ik(T.tolist(), tuple(seed)) == pytest.approx(q_true, abs=1e-9)
    q, ok, _ = arm.ik_batch(np.stack([T, T]), seed)            # a read-only seed broadcast to both
    assert ok.all() and q == pytest.approx(np.stack([q_true, q_true]), abs=1e-9)
    compiled = arm._solver.compiled
    assert len(compiled.one.func.signatures) == len(compiled.many.func.signatures) == 1


def test_ik_without_numba_runs_the_vectorised_solver(arm, monkeypatch):
    monkeypatch.setattr(arm._solver, 'compiled', None)
    q_true = np.array([0.4, 0.3, 1.1, 0.5, 0.8, -0.6])
    assert not arm.load_ik()
    assert arm.ik(arm.fk(q_true), q_true + 0.01) == pytest.approx(q_true, abs=1e-9)
    with pytest.raises(Unreachable, match='out of reach'):
        arm.ik(pose_matrix([2.0, 0.0, 0.5]))


def test_joint_limits_are_checked_for_the_joints_named_gripper_included(arm):
    from picking_core.kinematics import Unreachable
    from picking_core.kinematics.paths import check_joint_limits
    names = list(arm.all_joint_names)
    lower, upper, vmax, amax = arm.all_limits
    t = np.array([0.0, 0.01])
    q = np.tile(0.5 * (lower + upper), (2, 1))
    zero = np.zeros_like(q)
    check_joint_limits(arm, t, q, zero, zero, names=names)                  # within every limit
    fast = zero.copy()
    fast[1, -1] = 1.01 * vmax[-1]
    with pytest.raises(Unreachable, match=f'velocity limit broken: {names[-1]} .* at t = 0.010 s'):
        check_joint_limits(arm, t, q, fast, zero, names=names)
    # in another order, and only some joints
    some = [names[2], names[0]]
    check_joint_limits(arm, t, q[:, [2, 0]], zero[:, :2], zero[:, :2], names=some)
    with pytest.raises(ValueError, match='unknown joints'):
        check_joint_limits(arm, t, q[:, :1], zero[:, :1], zero[:, :1], names=['tail_joint'])
    with pytest.raises(ValueError, match='needs times'):
        check_joint_limits(arm, t, q, zero, zero, names=some)


def test_joint_limits_checked_compiled_name_what_numpy_names(arm, monkeypatch):
    """The compiled scan (a planner's) and numpy find the same first sample beyond a limit, in
    the same order (position, then velocity, then acceleration; by time, then by joint), and
    refuse a non-finite value anywhere as numpy does, before any limit."""
    pytest.importorskip('numba')
    from picking_core import trajectory
    from picking_core.kinematics.paths import check_joint_limits
    from picking_core.trajectory import piecewise
    assert trajectory.use_compiled_kernels()
    rng = np.random.default_rng(4)
    t = np.linspace(0.0, 1.0, 120)
    inside = rng.uniform(0.3, 0.7, (120, arm.dof))
    q = arm.lower + inside * (arm.upper - arm.lower)
    v, a = (inside - 0.5) * arm.max_velocity, (inside - 0.5) * arm.max_acceleration
    limit = (arm.upper, arm.max_velocity, arm.max_acceleration)

    def broken(*where):
        """The samples with each ``(array, i, j, times its limit)`` set beyond it."""
        arrays = [x.copy() for x in (q, v, a)]
        for which, i, j, factor in where:
            arrays[which][i, j] = factor * limit[which][j] + (0.01 if which == 0 else 0.0)
        return tuple(arrays)
    cases = [(q, v, a), broken((0, 70, 4, 1.0)), broken((1, 30, 2, 2.5)), broken((2, 90, 0, -2.5)),
             broken((2, 10, 3, 2.0), (1, 30, 2, 2.5), (1, 30, 1, -2.5)),     # velocity first; joint 1 first
             broken((0, 70, 4, 1.0), (2, 119, 5, np.nan))]                   # a NaN: a ValueError first
    def outcome(arrays):
        try:
            check_joint_limits(arm, t, *[x.T.copy().T for x in arrays])      # strided, as samples are
        except ValueError as exc:                 # Unreachable too
            return type(exc).__name__, str(exc)
        return 'ok', ''
    compiled = [outcome(c) for c in cases]
    monkeypatch.setattr(piecewise, '_kernels', None)
    assert [outcome(c) for c in cases] == compiled
    assert compiled[0] == ('ok', '') and compiled[-1][0] == 'ValueError'
    assert [c[1].split(':')[0] for c in compiled[1:-1]] == [
        'position limit broken', 'velocity limit broken', 'acceleration limit broken', 'velocity limit broken']
    assert 'at t = 0.252 s' in compiled[2][1] and f'{arm.joint_names[1]} reaches' in compiled[4][1]


PRISMATIC_URDF = """<robot name="slide">
  <link name="base_link"/><link name="a"/><link name="b"/><link name="c"/><link name="tool0"/>
  <joint name="turn" type="revolute"><parent link="base_link"/><child link="a"/>
    <origin xyz="0 0 0.3" rpy="0 0 0"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" velocity="1" effort="1"/></joint>
  <joint name="slide" type="prismatic"><parent link="a"/><child link="b"/>
    <origin xyz="0.1 0 0" rpy="0.2 0 0"/><axis xyz="1 0 0"/><limit lower="0" upper="0.5" velocity="1" effort="1"/></joint>
  <joint name="tilt" type="continuous"><parent link="b"/><child link="c"/>
    <origin xyz="0 0.05 0" rpy="0 0.3 0.1"/><axis xyz="0.6 0 0.8"/></joint>
  <joint name="flange" type="fixed"><parent link="c"/><child link="tool0"/><origin xyz="0 0 0.1" rpy="0 0 0"/></joint>
</robot>"""


@pytest.mark.parametrize('fixture', ['arm', 'arm3', 'slide'])
def test_compiled_forward_kinematics_agree_with_numpy(fixture, request):
    """Frames, the tool's alone (FK) and the Jacobian's smallest singular value, compiled, against
    the numpy versions: 10 000 configurations, singular ones among them; no input type compiles anew."""
    model = (kinematics.ArmModel.from_urdf_string(PRISMATIC_URDF) if fixture == 'slide'
             else request.getfixturevalue(fixture))
    assert model.load_fk(), 'the compiled forward kinematics did not load (numba is a requirement)'
    rng = np.random.default_rng(7)
    finite = np.isfinite(model.lower) & np.isfinite(model.upper)
    Q = rng.uniform(np.where(finite, model.lower, -7.0), np.where(finite, model.upper, 7.0), (10_000, model.dof))
    if model.dof == 6:
        Q[:1000, 4] = 0.0                                      # singular wrists
        Q[1000:2000, 2] = 0.0                                  # stretched elbows
    reference = model._joint_frames_numpy(Q)
    assert model.joint_frames(Q) == pytest.approx(reference, rel=0.0, abs=1e-12)
    assert np.array_equal(model.fk(Q), model.joint_frames(Q)[:, -1])         # the tool's frame alone
    sigma = model.min_singular_values(Q)
    assert sigma == pytest.approx(model._min_singular_values_numpy(Q), rel=0.0, abs=1e-9)
    if model.dof == 6:
        assert sigma[:1000].max() < 1e-7                       # the singular wrists are found
    ro = Q[:5].copy()
    ro.flags.writeable = False
    for q in (ro, np.asfortranarray(Q[:5]), Q[:5].round().astype(int), Q[0], Q[0].tolist()):
        assert model.fk(q) == pytest.approx(model._joint_frames_numpy(np.atleast_2d(np.asarray(q, float)))[:, -1]
                                            .reshape(np.shape(model.fk(q))), abs=1e-12)
        model.min_singular_values(q)
    kernels = model._fk_compiled
    assert len(kernels.frames.func.signatures) == len(kernels.min_singular_values.func.signatures) == 1


def test_singular_values_in_lockstep_are_each_configurations_own(arm):
    """The compiled kernel takes BLOCK Jacobians through Jacobi together: each configuration's
    value is exactly (to the bit) the one it gets alone, whatever its neighbours, singular or
    quick to converge, and across block borders."""
    from picking_core.kinematics import fast_fk
    assert arm.load_fk()
    rng = np.random.default_rng(11)
    Q = rng.uniform(arm.lower, arm.upper, (2 * fast_fk.BLOCK + 7, arm.dof))
    Q[::5, 4] = 0.0                                            # singular wrists among them
    Q[3::10] = Q[1]                                            # the same configuration in other company
    together = arm.min_singular_values(Q)
    alone = np.array([arm.min_singular_values(q[None])[0] for q in Q])
    assert np.array_equal(together, alone)
    assert np.array_equal(together[3::10], np.full(len(Q[3::10]), together[1]))
    assert together[::5].max() < 1e-7 < together[1::5].min()


def test_forward_kinematics_without_numba_run_with_numpy(arm, monkeypatch):
    q = np.array([[0.4, 0.3, 1.1, 0.5, 0.8, -0.6], [0.0, 0.2, 1.6, 0.0, 0.0, 0.0]])
    compiled = arm.fk(q), arm.min_singular_values(q), arm.jacobian(q[0])
    monkeypatch.setattr(arm, '_fk_compiled', None)
    assert not arm.load_fk()
    numpy = arm.fk(q), arm.min_singular_values(q), arm.jacobian(q[0])
    for a, b in zip(compiled, numpy):
        assert a == pytest.approx(b, abs=1e-12)
    assert numpy[1][1] < 1e-9                                  # q5 = 0: the wrist is singular
