"""Cartesian path -> joint path: IK at every sample, seeded by the previous one.

The path is refused, with where and why, when a sample is unreachable, when it
passes a singularity, or when consecutive samples need a joint jump larger
than a threshold (MoveIt's jump-threshold idea: an IK branch flip). The result
reports the largest deviation of the tool from the requested path between the
samples, and its joint velocities and accelerations against the limits.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from .. import trajectory
from ..trajectory.piecewise import compiled_kernels
from .errors import Unreachable

#: The joint spline between two IK samples is checked (the tool's deviation from the path, the
#: joints' peaks and limits) at least this often, s, and at least at the quarters of each interval.
CHECK_STEP = 0.0025
#: The most IK samples a path may take: a path longer than that many sample periods is refused before it is
#: sampled (one timed over hours would otherwise be sampled and solved sample by sample first).
MAX_SAMPLES = 100_000


def pose_matrix(position, quaternion=(0.0, 0.0, 0.0, 1.0)):
    """4x4 pose from a position (m) and a quaternion (x, y, z, w), normalised.

    Raises ValueError for non-finite values or a zero quaternion.
    """
    p = np.asarray(position, dtype=float)
    qt = np.asarray(quaternion, dtype=float)
    if p.shape != (3,) or qt.shape != (4,) or not (np.all(np.isfinite(p)) and np.all(np.isfinite(qt))):
        raise ValueError('a pose needs a finite position (x, y, z) and quaternion (x, y, z, w)')
    norm = np.linalg.norm(qt)
    if norm < 1e-9:
        raise ValueError('the orientation quaternion is zero; it must be a unit quaternion (x, y, z, w)')
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat(qt / norm).as_matrix()
    T[:3, 3] = p
    return T


@dataclass(frozen=True)
class JointPath:
    """A Cartesian path converted to joints.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Sample times, s.
    q : ndarray, shape (N, dof)
        IK solution at each sample.
    trajectory : PiecewisePolynomial
        C2 quintic spline through the samples (what the controller runs).
    max_deviation : float
        Largest distance between the tool (by FK of the trajectory, between
        samples) and the requested path, m.
    peak_velocity, peak_acceleration : ndarray, shape (dof,)
        Largest |qd| and |qdd| along the trajectory.
    min_singular_value : float
        Smallest singular value of the Jacobian met along the path.
    checked : tuple of ndarray
        ``(t, q, qd, qdd)``: the trajectory at the times the deviation and the peaks were
        taken (the samples and points between them, at most :data:`CHECK_STEP` apart).
    """

    t: np.ndarray
    q: np.ndarray
    trajectory: trajectory.PiecewisePolynomial
    max_deviation: float
    peak_velocity: np.ndarray
    peak_acceleration: np.ndarray
    min_singular_value: float
    checked: tuple = ()


def cartesian_to_joint(arm, path, seed, dt=0.01, max_joint_step=0.25, singular_threshold=1e-3,
                       check_limits=True, free_ends=(False, False)):
    """Joint trajectory that moves the tool along ``path``.

    Parameters
    ----------
    arm : ArmModel
    path : CartesianPath
        Positions in the base frame; orientations (if set) followed too.
    seed : array_like, shape (dof,)
        Joints at the start (the current state); the first sample's IK is seeded by it.
    dt : float
        Sample period, s.
    max_joint_step : float
        Largest change of any joint between two samples, rad (m), before the
        path is refused as a jump.
    singular_threshold : float
        Smallest accepted singular value of the Jacobian.
    check_limits : bool
        Refuse paths whose joint velocity or acceleration breaks the arm's limits.
    free_ends : (bool, bool)
        The path starts, ends, moving (a progress that does not start or end at
        rest): the joint spline takes its own velocity and acceleration there
        instead of rest (see :func:`trajectory.quintic_via`).

    Raises
    ------
    Unreachable
        Naming the time and tool position where the path fails, and why.
    """
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f'dt must be a positive number of seconds, got {dt}')
    if not path.duration / dt <= MAX_SAMPLES:
        raise ValueError(f'the path lasts {path.duration:g} s: over {MAX_SAMPLES} samples of {dt:g} s (refused)')
    n = max(int(np.ceil(path.duration / dt - 1e-9)), 1) + 1
    # The samples, and the points between them where the spline is not pinned by IK: one
    # sampling of the path for both.
    between = max(4, int(np.ceil(dt / CHECK_STEP - 1e-9)))
    t_check = np.linspace(0.0, path.duration, (n - 1) * between + 1)
    t = t_check[::between]
    path_poses = path.poses(t_check)
    seed = arm.check_joints(seed, 'seed')
    if not path.oriented:
        path_poses[:, :3, :3] = arm.fk(seed)[:3, :3]
    poses = path_poses[::between]
    q = _batched(arm, poses, seed, max_joint_step)
    if q is None:
        q = _sequential(arm, poses, t, seed, max_joint_step)
    sigma = arm.min_singular_values(q)
    worst = int(np.argmin(sigma))
    if sigma[worst] < singular_threshold:
        raise Unreachable(f'path fails at t = {t[worst]:.3f} s (tool at '
                          f'{np.round(poses[worst, :3, 3], 4).tolist()} m): singular: the Jacobian\'s '
                          f'smallest singular value is {sigma[worst]:.2e} (threshold {singular_threshold})')
    traj = (trajectory.quintic_via(q, np.diff(t), free_ends=free_ends) if n > 2
            else trajectory.quintic(q[0], q[-1], path.duration))
    q_check, qd, qdd = traj.sample(t_check)
    tool = arm.fk(q_check)[:, :3, 3]
    deviation = float(np.linalg.norm(tool - path_poses[:, :3, 3], axis=1).max())
    peak_v, peak_a = np.abs(qd).max(axis=0), np.abs(qdd).max(axis=0)
    if check_limits:
        check_joint_limits(arm, t_check, q_check, qd, qdd)
    return JointPath(t, q, traj, deviation, peak_v, peak_a, float(sigma[worst]), (t_check, q_check, qd, qdd))


def _batched(arm, poses, seed, max_joint_step):
    """Every sample's IK at once, each nearest the seed: the result if it is continuous, else None."""
    q, ok, _ = arm.ik_batch(poses, seed)
    if not ok.all():
        return None
    # From sample to sample (the first may lie anywhere near the seed).
    return q if len(q) < 2 or np.abs(np.diff(q, axis=0)).max() <= max_joint_step else None


def _sequential(arm, poses, t, seed, max_joint_step):
    """Sample by sample, each seeded by the one before; raises Unreachable with where and why."""
    n = len(poses)
    q = np.empty((n, arm.dof))
    prev = seed
    for i in range(n):
        try:
            sol = arm.ik(poses[i], prev)
        except Unreachable as exc:
            raise Unreachable(f'path fails at t = {t[i]:.3f} s (tool at '
                              f'{np.round(poses[i, :3, 3], 4).tolist()} m): {exc}') from None
        step = np.abs(sol - prev)
        if i > 0 and step.max() > max_joint_step:
            j = int(step.argmax())
            raise Unreachable(f'path fails at t = {t[i]:.3f} s (tool at {np.round(poses[i, :3, 3], 4).tolist()} m): '
                              f'joint {arm.joint_names[j]} would jump {step[j]:.3f} rad in one sample '
                              f'(threshold {max_joint_step} rad); the path passes near a singularity or '
                              'changes IK branch')
        q[i] = prev = sol
    return q


def check_joint_limits(arm, t, q, qd, qdd, slack=1e-6, names=None):
    """Raise Unreachable naming the first joint and time that break a position,
    velocity or acceleration limit of ``arm``.

    ``t`` has shape (N,); ``q``, ``qd``, ``qdd`` shape (N, dof), or (N, len(names)) for
    the joints ``names`` of :attr:`ArmModel.all_joint_names` (the gripper too)
    (ValueError otherwise, and for non-finite values or unknown names).
    """
    if names is None:
        names, limits = list(arm.joint_names), (arm.lower, arm.upper, arm.max_velocity, arm.max_acceleration)
    else:
        every = list(arm.all_joint_names)
        unknown = [n for n in names if n not in every]
        if unknown:
            raise ValueError(f'check_joint_limits: unknown joints {unknown}')
        idx = [every.index(n) for n in names]
        limits = tuple(np.asarray(x)[idx] for x in arm.all_limits)
    t = np.asarray(t, dtype=float)
    arrays = [np.asarray(x, dtype=float) for x in (q, qd, qdd)]
    if t.ndim != 1 or any(a.shape != (t.size, len(names)) for a in arrays):
        raise ValueError(f'check_joint_limits needs times (N,) and joint values (N, {len(names)}), got '
                         f'{t.shape} and {[a.shape for a in arrays]}')
    q, qd, qdd = arrays
    lower, upper, vmax, amax = limits
    checks = (('position', q, lower, upper, 'rad'),
              ('velocity', qd, -vmax, vmax, 'rad/s'),
              ('acceleration', qdd, -amax, amax, 'rad/s^2'))
    kernels = compiled_kernels()
    if kernels is not None:
        # One compiled pass per array: a planner checks every move this way.
        scans = [kernels.scan_limits(values, lo - slack, hi + slack) for _, values, lo, hi, _ in checks]
        if not np.isfinite(t).all() or any(nonfinite for _, nonfinite in scans):
            raise ValueError('check_joint_limits needs finite times and joint values')
        for (name, values, lo, hi, unit), (first, _) in zip(checks, scans):
            if first >= 0:
                _raise_beyond(name, values, lo, hi, unit, divmod(first, values.shape[1]), t, names)
        return
    if not (np.isfinite(t).all() and all(np.isfinite(a).all() for a in arrays)):
        raise ValueError('check_joint_limits needs finite times and joint values')
    for name, values, lo, hi, unit in checks:
        bad = (values < lo - slack) | (values > hi + slack)
        if bad.any():
            _raise_beyond(name, values, lo, hi, unit, np.argwhere(bad)[0], t, names)


def _raise_beyond(name, values, lo, hi, unit, where, t, names):
    """Unreachable for the ``name`` limit broken at sample ``where = (i, j)``."""
    i, j = where
    limit = hi[j] if values[i, j] > hi[j] else lo[j]
    raise Unreachable(f'{name} limit broken: {names[j]} reaches {values[i, j]:.4g} {unit} '
                      f'at t = {t[i]:.3f} s, limit {limit:.4g} {unit}; slow the motion down')
