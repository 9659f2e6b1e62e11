"""Piecewise quintics through via points with positions, velocities, accelerations.

The paper's Sec. 3.1 step D gives each via point its position, velocity and
acceleration; a quintic per segment meets all six end conditions, so the path
passes every via point exactly with continuous position, velocity and
acceleration.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import lapack

from ._checks import as_durations, as_points
from .piecewise import PiecewisePolynomial, compiled_kernels
from .polynomial import hermite_coeffs


def _per_point(values, name, shape):
    arr = as_points(values, name, min_points=shape[0])
    if arr.shape != shape:
        raise ValueError(f'{name} must have shape {shape} (one row per via point), got {arr.shape}')
    return arr


def quintic_via(points, durations, velocities=None, accelerations=None, free_ends=(False, False)):
    """Quintic segments through via points, exact at every point (Sec. 3.1 D).

    Parameters
    ----------
    points : array_like, shape (m + 1, n_joints)
        Via points; a 1-D sequence is one joint.
    durations : float or array_like, shape (m,)
        Time of each segment, s (a scalar for all).
    velocities : array_like, shape (m + 1, n_joints), optional
        Velocity at each via point. When omitted, the path starts and ends at
        rest and the interior velocities and accelerations are those of the
        C2 cubic spline through the points (clamped to zero end velocity), so
        the motion is smooth without any tuning.
    accelerations : array_like, shape (m + 1, n_joints), optional
        Acceleration at each via point. When omitted with velocities given,
        the ends get zero and interior points the central difference of the
        given velocities.
    free_ends : (bool, bool)
        Without velocities: the start, the end, not at rest. Such an end takes
        the spline's own velocity and acceleration (not-a-knot end condition):
        what a path sampled while moving through its end point has there.

    Returns
    -------
    PiecewisePolynomial
        ``m`` quintic segments, breaks at the via times.
    """
    points = as_points(points)
    m = points.shape[0] - 1
    td = as_durations(durations, m)
    times = np.concatenate(([0.0], np.cumsum(td)))
    if velocities is None:
        free = tuple(bool(f) and m > 1 for f in free_ends)     # not-a-knot needs 3 points or more
        kernels = compiled_kernels()
        if kernels is not None and accelerations is None and not (all(free) and m == 2):
            c = np.empty((m, 6, points.shape[1]))
            kernels.quintic_spline(np.ascontiguousarray(td), np.ascontiguousarray(points), *free, c)
            return PiecewisePolynomial(times, c)
        vel, acc = _cubic_spline(td, points, free)
        for end, f in zip((0, -1), free):
            if not f:
                acc[end] = 0.0
    else:
        vel = _per_point(velocities, 'velocities', points.shape)
        acc = np.zeros_like(points)
        acc[1:-1] = (vel[2:] - vel[:-2]) / (times[2:] - times[:-2])[:, None]
    if accelerations is not None:
        acc = _per_point(accelerations, 'accelerations', points.shape)
    c = hermite_coeffs(points[:-1], vel[:-1], acc[:-1], points[1:], vel[1:], acc[1:], td[:, None])
    return PiecewisePolynomial(times, c.transpose(0, 2, 1))



def _cubic_spline(h, points, free=(False, False)):
    """Velocities and accelerations at the knots of the C2 cubic spline through ``points``
    (m + 1, n) at intervals ``h`` (m,): the values of scipy's ``CubicSpline`` (a property test
    compares them), from one tridiagonal solve (LAPACK's gtsv) and no spline object, 5x
    quicker for a line's 50 samples (every Cartesian path takes it).

    An end is at rest (velocity 0), or ``free``: not-a-knot, the first (last) two cubics one
    polynomial, which needs m >= 2 (m >= 3 for both ends: three points free at both ends
    lie on one parabola, taken as such). Each interior knot's velocity ``v_i`` meets
    continuity of acceleration there::

        h_i v_(i-1) + 2 (h_(i-1) + h_i) v_i + h_(i-1) v_(i+1) = 3 (h_i d_(i-1) + h_(i-1) d_i)

    with ``d_i`` the slope of interval ``i``; a free start's row is the not-a-knot condition
    with ``v_2`` eliminated by the row of knot 1 (a free end's mirrors it). The cubic on
    interval ``i`` then has acceleration ``2 (3 d_i - 2 v_i - v_(i+1)) / h_i`` at its start.
    """
    slope = (points[1:] - points[:-1]) / h[:, None]
    n = points.shape[0]
    if free[0] and free[1] and n == 3:
        # One parabola through the three points: its slope at the middle knot is the
        # interval-weighted mean of the slopes, its acceleration constant.
        curvature = 2.0 * (slope[1] - slope[0]) / (h[0] + h[1])
        vel = np.stack([slope[0] - 0.5 * curvature * h[0], slope[0] + 0.5 * curvature * h[0],
                        slope[1] + 0.5 * curvature * h[1]])
        return vel, np.repeat(curvature[None], 3, axis=0)
    diag, upper, lower = np.ones(n), np.zeros(n - 1), np.zeros(n - 1)
    diag[1:-1] = 2.0 * (h[:-1] + h[1:])
    upper[1:] = h[:-1]
    lower[:-1] = h[1:]
    rhs = np.zeros_like(points)                       # the rows of an end at rest: v = 0
    rhs[1:-1] = 3.0 * (h[1:, None] * slope[:-1] + h[:-1, None] * slope[1:])
    if free[0]:
        span = h[0] + h[1]
        diag[0], upper[0] = h[1], span
        rhs[0] = ((3.0 * h[0] + 2.0 * h[1]) * h[1] * slope[0] + h[0] ** 2 * slope[1]) / span
    if free[1]:
        span = h[-1] + h[-2]
        diag[-1], lower[-1] = h[-2], span
        rhs[-1] = ((3.0 * h[-1] + 2.0 * h[-2]) * h[-2] * slope[-1] + h[-1] ** 2 * slope[-2]) / span
    *_, vel, info = lapack.dgtsv(lower, diag, upper, rhs, True, True, True, True)
    if info != 0:
        raise ValueError(f'the spline through the via points could not be solved (LAPACK gtsv info {info})')
    acc = np.empty_like(points)
    acc[:-1] = 2.0 * (3.0 * slope - 2.0 * vel[:-1] - vel[1:]) / h[:, None]
    acc[-1] = 2.0 * (vel[-2] + 2.0 * vel[-1] - 3.0 * slope[-1]) / h[-1]
    return vel, acc
