"""Linear segments with parabolic blends (paper Sec. 2.4.2, Eq. 15-20, Figs. 6-12).

``lspb`` is one move between two points; ``via_lspb`` passes a sequence of
via points in Craig's scheme (Fig. 12): the first and last points are reached
exactly, the interior ones are rounded by parabolic blends of the given
acceleration centred on their times.

Both are built as "phases" per joint (constant acceleration each: blend,
cruise, blend, ...), whose boundaries differ from joint to joint; they are then
merged into one piecewise polynomial with the union of the boundaries.
"""

from __future__ import annotations

import functools

import numpy as np

from ._checks import as_duration, as_durations, as_joint_vector, as_points
from .piecewise import PiecewisePolynomial, compiled_kernels, merge_joint_pieces
from .polynomial import _end_points

# Relative slack for "exactly the minimum acceleration": a value equal to the
# bound up to rounding gives the triangular profile instead of an error.
_RTOL = 1e-9


def _accel(accel, n):
    a = as_joint_vector(accel, 'accel', n)
    if (a <= 0.0).any():
        raise ValueError(f'accel must be > 0 (a magnitude, unit/s^2), got {a.tolist()}')
    return a


def _from_phases(bounds, q, v, a):
    """Merge constant-acceleration phases (P per joint) into breaks and coeffs."""
    coeffs = np.zeros((q.shape[0], 6, q.shape[1]))
    coeffs[:, 0], coeffs[:, 1], coeffs[:, 2] = q, v, 0.5 * a
    return merge_joint_pieces(bounds, coeffs)


class Lspb(PiecewisePolynomial):
    """A one-segment LSPB move; see :func:`lspb`.

    Attributes
    ----------
    blend_time : ndarray, shape (n_joints,)
        ``t_a`` of Eq. 19, s.
    blend_position : ndarray, shape (n_joints,)
        ``theta_a``, the position where the first blend ends (Eq. 16).
    cruise_velocity : ndarray, shape (n_joints,)
        Velocity of the linear part, ``theta_ddot * t_a`` (signed).
    accel : ndarray, shape (n_joints,)
        Blend acceleration magnitude used.
    min_accel : ndarray, shape (n_joints,)
        ``4 |qf - q0| / tf^2`` of Eq. 20.
    """

    __slots__ = ('blend_time', 'blend_position', 'cruise_velocity', 'accel', 'min_accel')


def min_lspb_accel(q0, qf, duration):
    """Smallest blend acceleration for which an LSPB move exists (Eq. 20).

    Returns ``4 |qf - q0| / duration^2`` per joint, unit/s^2.
    """
    q0, qf = _end_points(q0, qf)
    duration = as_duration(duration)
    return 4.0 * np.abs(qf - q0) / duration**2


def lspb(q0, qf, duration, accel):
    """Linear segment with parabolic blends between two points (Eq. 15-20).

    Every joint starts and ends at rest and takes ``duration``; each joint
    accelerates at ``accel`` for its blend time ``t_a`` (Eq. 19), cruises, and
    decelerates symmetrically: the profile is symmetric about
    ``(tf/2, (q0 + qf)/2)`` (Fig. 8).

    Parameters
    ----------
    q0, qf : float or array_like, shape (n_joints,)
        Start and goal positions.
    duration : float
        Move time ``tf``, s (> 0).
    accel : float or array_like, shape (n_joints,)
        Blend acceleration magnitude, unit/s^2 (> 0).

    Returns
    -------
    Lspb
        Its per-joint attributes (``blend_time``, ``blend_position``, ``cruise_velocity``,
        ``accel``, ``min_accel``) are arrays of one value per joint, or plain floats when
        ``q0`` and ``qf`` are given as plain numbers (one joint); ``sample`` keeps its
        (len(t), n_joints) arrays either way.

    Raises
    ------
    ValueError
        If ``accel < 4 |qf - q0| / duration^2`` for a joint (Eq. 20); the
        message names the minimum. Exactly the minimum gives a triangular
        velocity profile (no cruise).
    """
    one_joint = np.ndim(q0) == 0 and np.ndim(qf) == 0
    q0, qf = _end_points(q0, qf)
    duration = as_duration(duration)
    n = q0.size
    a = _accel(accel, n)
    h = qf - q0
    s = np.sign(h)
    amin = 4.0 * np.abs(h) / duration**2
    short = a < amin * (1.0 - _RTOL)
    if np.any(short):
        j = int(np.argmax(short))
        raise ValueError(
            f'accel {a[j]:.6g} is too small for joint {j}: moving {h[j]:.6g} in {duration:.6g} s '
            f'needs at least 4|qf-q0|/duration^2 = {amin[j]:.6g} (Eq. 20)')
    disc = np.maximum(a**2 * duration**2 - 4.0 * a * np.abs(h), 0.0)
    tb = np.minimum(duration / 2.0 - np.sqrt(disc) / (2.0 * a), duration / 2.0)
    acc = s * a
    vc = acc * tb
    qa = q0 + 0.5 * acc * tb**2
    zeros = np.zeros(n)
    bounds = np.stack([zeros, tb, duration - tb, np.full(n, duration)])
    breaks, coeffs = _from_phases(
        bounds,
        q=np.stack([q0, qa, qf - 0.5 * acc * tb**2]),
        v=np.stack([zeros, vc, vc]),
        a=np.stack([acc, zeros, -acc]))
    out = Lspb(breaks, coeffs)
    per_joint = (float(x[0]) for x in (tb, qa, vc, a, amin)) if one_joint else (tb, qa, vc, a, amin)
    out.blend_time, out.blend_position, out.cruise_velocity, out.accel, out.min_accel = per_joint
    return out


class ViaLspb(PiecewisePolynomial):
    """A multi-segment LSPB through via points; see :func:`via_lspb`.

    Attributes
    ----------
    via_times : ndarray, shape (m + 1,)
        Times at which the via points are due, s (first 0, last the duration).
    blend_times : ndarray, shape (m + 1, n_joints)
        Blend length at each point, s (end blends lie inside the segment,
        interior blends are centred on the via time).
    segment_velocities : ndarray, shape (m, n_joints)
        Velocity of each linear part.
    """

    __slots__ = ('via_times', 'blend_times', 'segment_velocities')


def via_lspb(points, durations, accel, timing=None):
    """Linear segments with parabolic blends through via points (Fig. 12).

    Craig's scheme: the path starts and ends at rest exactly at the first and
    last points; between, straight lines join consecutive via points at their
    times, and at each interior via point a parabolic blend of acceleration
    ``accel`` rounds the corner (the via point itself is approached, not passed,
    as the paper notes for Fig. 12).

    Parameters
    ----------
    points : array_like, shape (m + 1, n_joints)
        Via points; a 1-D sequence is one joint.
    durations : float or array_like, shape (m,)
        Time between consecutive via points, s.
    accel : float or array_like, shape (n_joints,)
        Blend acceleration magnitude, unit/s^2.
    timing : (ndarray, ndarray), optional
        What :func:`via_lspb_timing` returned for these same points, durations
        and accel, when a caller has it already (a search for a feasible
        timing): not computed again.

    Returns
    -------
    ViaLspb

    Raises
    ------
    ValueError
        If a segment is too short for its blends at this acceleration; the
        message names the segment, the joint and the time the blends need.
    """
    points = as_points(points)
    m = points.shape[0] - 1
    td = as_durations(durations, m)
    n = points.shape[1]
    a = _accel(accel, n)
    if m == 1:
        single = lspb(points[0], points[1], td[0], a)
        out = ViaLspb(single.breaks, single.coeffs)
        out.via_times = np.array([0.0, td[0]])
        out.blend_times = np.stack([single.blend_time, single.blend_time])
        out.segment_velocities = single.cruise_velocity[None, :]
        return out
    tb, vel = _via_timing(points, td, a) if timing is None else timing
    times = np.concatenate(([0.0], np.cumsum(td)))
    # Phase boundaries, per joint: blend_0, line_0, blend_1, line_1, ..., blend_m.
    bounds = np.empty((2 * m + 2, n))
    bounds[0] = 0.0
    bounds[1] = tb[0]
    bounds[2:2 * m:2] = times[1:m, None] - 0.5 * tb[1:m]
    bounds[3:2 * m:2] = times[1:m, None] + 0.5 * tb[1:m]
    bounds[2 * m] = times[m] - tb[m]
    bounds[2 * m + 1] = times[m]
    bounds = np.maximum.accumulate(np.clip(bounds, 0.0, times[m]), axis=0)

    starts = bounds[:-1]                                            # (2m+1, n)
    line, anchor = _phase_lines(m)
    q_start = points[anchor] + vel[line] * (starts - times[anchor, None])
    v_start = vel[line]
    q_start[0], v_start[0] = points[0], 0.0
    acc = np.empty((2 * m + 1, n))
    acc[0] = np.sign(vel[0]) * a
    acc[1:2 * m:2] = 0.0
    acc[2:2 * m:2] = np.sign(vel[1:] - vel[:-1]) * a
    acc[2 * m] = -np.sign(vel[-1]) * a

    breaks, coeffs = _from_phases(bounds, q_start, v_start, acc)
    out = ViaLspb(breaks, coeffs)
    out.via_times, out.blend_times, out.segment_velocities = times, tb, vel
    return out


@functools.cache
def _phase_lines(m):
    """For the 2m + 1 phases of m segments: the line each phase starts on, and the via point
    that line passes at its time (read-only index arrays).

    Phase p: 0 is the start blend, odd p = 2k+1 is line k, even p = 2k >= 2 is the blend
    at via point k, which starts on line k-1. Line k passes via point k+1 at its time (the
    last line: via point m-1) with velocity vel[k]; Craig's end-segment velocities make the
    first and last lines meet the end blends.
    """
    p = np.arange(2 * m + 1)
    line = np.clip(np.where(p % 2 == 1, (p - 1) // 2, p // 2 - 1), 0, m - 1)
    anchor = np.where(line < m - 1, line + 1, m - 1)
    line.flags.writeable = anchor.flags.writeable = False
    return line, anchor


def via_lspb_timing(points, durations, accel):
    """The timing of :func:`via_lspb` without building the trajectory (microseconds).

    Returns ``(blend_times, segment_velocities)``, shapes (m + 1, n) and (m, n);
    raises the same ValueError when a segment is too short for its blends. Its
    largest speed is that of the trajectory (blends only join the lines), so a
    timing can be searched for with this alone.
    """
    points = as_points(points)
    m = points.shape[0] - 1
    td = as_durations(durations, m)
    a = _accel(accel, points.shape[1])
    if m == 1:
        single = lspb(points[0], points[1], td[0], a)
        return np.stack([single.blend_time, single.blend_time]), single.cruise_velocity[None, :]
    return _via_timing(points, td, a)


def _via_timing(points, td, a):
    """Craig's blend times (m + 1, n) and line velocities (m, n) for m >= 2 segments (compiled
    when the planner's kernels are loaded: the planner searches durations with it)."""
    kernels = compiled_kernels()
    if kernels is None:
        return _via_timing_numpy(points, td, a)
    points, td, a = (np.ascontiguousarray(x) for x in (points, td, a))
    tb, vel = np.empty_like(points), np.empty((points.shape[0] - 1, points.shape[1]))
    failed, k, j, need = kernels.via_timing(points, td, a, tb, vel)
    if failed == 1:
        raise ValueError(_end_too_short(points, td, a, k, j))
    if failed == 2:
        raise ValueError(_blends_too_long(td, a, k, j, need))
    return tb, vel


def _end_too_short(points, td, a, end, j):
    """The refusal of the first (``end`` 0) or last (1) segment of joint ``j``."""
    k = 0 if end == 0 else td.size - 1
    dq = points[k + 1, j] - points[k, j]
    return (f'accel {a[j]:.6g} is too small for the {("first", "last")[end]} segment of joint {j}: '
            f'moving {dq:.6g} in {td[k]:.6g} s needs at least 2|dq|/duration^2 = {2.0 * abs(dq) / td[k] ** 2:.6g}')


def _blends_too_long(td, a, k, j, need):
    """The refusal of segment ``k`` of joint ``j``, whose blends need ``need`` s."""
    return (f'segment {k} (between via points {k} and {k + 1}) of joint {j} is too short for '
            f'its blends at accel {a[j]:.6g}: the blends need {need:.6g} s but the segment '
            f'lasts {td[k]:.6g} s; raise accel or lengthen the segment')


def _via_timing_numpy(points, td, a):
    """:func:`_via_timing` with numpy (without numba, and the compiled version's reference)."""
    m = points.shape[0] - 1
    dq = points[1:] - points[:-1]                                   # (m, n)
    vel = dq / td[:, None]
    # The first and the last segment together: each blends from (to) rest at its end point and
    # runs on at the velocity that meets the next (previous) line at its via point.
    ends = [0, m - 1]
    span = td[ends][:, None]                                        # (2, 1)
    moved = dq[ends]                                                # (2, n)
    disc = span ** 2 - 2.0 * np.abs(moved) / a
    short = disc < -_RTOL * span ** 2
    if short.any():
        k = 0 if short[0].any() else 1
        raise ValueError(_end_too_short(points, td, a, k, int(np.argmin(disc[k]))))
    blend = span - np.sqrt(np.maximum(disc, 0.0))
    vel[ends] = moved / (span - 0.5 * blend)
    tb = np.empty((m + 1, points.shape[1]))
    tb[0], tb[m] = blend
    tb[1:m] = np.abs(vel[1:] - vel[:-1]) / a
    linear = td[:, None] - 0.5 * tb[:-1] - 0.5 * tb[1:]
    linear[0] -= 0.5 * tb[0]
    linear[-1] -= 0.5 * tb[-1]
    if (linear < -_RTOL * td[:, None]).any():
        k, j = np.unravel_index(int(np.argmin(linear)), linear.shape)
        raise ValueError(_blends_too_long(td, a, k, j, td[k] - linear[k, j]))
    return tb, vel
