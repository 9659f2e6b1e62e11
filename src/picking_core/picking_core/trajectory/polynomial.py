"""Point-to-point polynomial moves: the paper's cubic (Sec. 2.4.1) and the quintic.

Both are Hermite polynomials fixed by the end conditions; the closed forms
below are the solution of the paper's Eq. 10 (cubic) and its quintic analogue.
"""

from __future__ import annotations

import numpy as np

from ._checks import as_duration, as_joint_vector
from .piecewise import PiecewisePolynomial, _stack_derivatives


def hermite_coeffs(q0, v0, a0, q1, v1, a1, duration):
    """Power-basis coefficients of the quintic meeting both end states.

    Vectorised: every argument broadcasts, ``duration`` included, so one call
    builds all segments of a spline. With ``a0 = a1 = None`` it returns the
    cubic through positions and velocities; with velocities also ``None``, the
    straight line.

    Parameters
    ----------
    q0, v0, a0, q1, v1, a1 : array_like
        Start and end position, velocity, acceleration (``a*``/``v*`` may be None).
    duration : array_like
        Segment length, s (> 0).

    Returns
    -------
    ndarray, shape (..., 6)
        ``c0..c5`` with ``q(tau) = sum c_i tau^i``, ``0 <= tau <= duration``.
    """
    T = np.asarray(duration, dtype=float)
    q0 = np.asarray(q0, dtype=float)
    h = np.asarray(q1, dtype=float) - q0
    shape = np.broadcast_shapes(q0.shape, h.shape, T.shape)
    c = np.zeros(shape + (6,))
    c[..., 0] = q0
    if v0 is None:                      # linear
        c[..., 1] = h / T
        return c
    v0 = np.asarray(v0, dtype=float)
    v1 = np.asarray(v1, dtype=float)
    c[..., 1] = v0
    if a0 is None:                      # cubic (Eq. 11 when v0 = v1 = 0)
        c[..., 2] = (3.0 * h - (2.0 * v0 + v1) * T) / T**2
        c[..., 3] = (-2.0 * h + (v0 + v1) * T) / T**3
        return c
    a0 = np.asarray(a0, dtype=float)
    a1 = np.asarray(a1, dtype=float)
    c[..., 2] = 0.5 * a0
    c[..., 3] = (20.0 * h - (8.0 * v1 + 12.0 * v0) * T - (3.0 * a0 - a1) * T**2) / (2.0 * T**3)
    c[..., 4] = (-30.0 * h + (14.0 * v1 + 16.0 * v0) * T + (3.0 * a0 - 2.0 * a1) * T**2) / (2.0 * T**4)
    c[..., 5] = (12.0 * h - 6.0 * (v1 + v0) * T + (a1 - a0) * T**2) / (2.0 * T**5)
    return c


def _end_points(q0, qf):
    """q0 and qf as equal-length joint vectors (a scalar broadcasts)."""
    a = as_joint_vector(q0, 'q0')
    b = as_joint_vector(qf, 'qf')
    if a.size == 1 and b.size > 1:
        a = np.full(b.size, a[0])
    elif b.size == 1 and a.size > 1:
        b = np.full(a.size, b[0])
    if a.size != b.size:
        raise ValueError(f'q0 has {a.size} joints but qf has {b.size}')
    return a, b


#: The cubic's and the quintic's profile from rest to rest over a unit time, ``s(u) = sum c_i u^i``
#: from 0 to 1 (Eq. 11 with v0 = vf = 0; the minimum-jerk quintic).
_REST_TO_REST = {'cubic': np.array([0.0, 0.0, 3.0, -2.0, 0.0, 0.0]),
                 'quintic': np.array([0.0, 0.0, 0.0, 10.0, -15.0, 6.0])}


def _at_rest(*values):
    """True when every end velocity and acceleration given is the number 0 (the default)."""
    return all(isinstance(x, (int, float)) and x == 0 for x in values)


def _synchronised(q0, h, duration, kind):
    """The move of every joint along one profile from rest to rest, scaled by its distance
    ``h``: ``q_j(tau) = q0_j + h_j s(tau / duration)``. The trajectory knows it shares that
    profile (a long sampling evaluates it once and scales it per joint, see
    :func:`.piecewise._shared_profile`) without searching its coefficients for it."""
    s = _REST_TO_REST[kind] * duration ** -np.arange(6.0)      # s in the segment's own time
    coeffs = s[:, None] * h
    coeffs[0] = q0
    traj = PiecewisePolynomial([0.0, duration], coeffs[None])
    traj._shared = (_stack_derivatives(s[None, :, None])[0], h, q0)
    return traj


def _single(coeffs, duration):
    """One-segment trajectory from (n_joints, 6) coefficients."""
    return PiecewisePolynomial([0.0, duration], coeffs.T[None, :, :])


def cubic(q0, qf, duration, v0=0.0, vf=0.0):
    """Cubic polynomial move (paper Sec. 2.4.1, Eq. 8-12).

    ``theta(t) = a0 + a1 t + a2 t^2 + a3 t^3`` with ``theta(0) = q0``,
    ``theta(tf) = qf`` and end velocities ``v0``, ``vf`` (zero by default, Eq. 7).

    Parameters
    ----------
    q0, qf : float or array_like, shape (n_joints,)
        Start and goal positions (rad, m, or any consistent unit).
    duration : float
        Move time ``tf``, s (> 0).
    v0, vf : float or array_like, shape (n_joints,)
        Start and end velocities, unit/s.

    Returns
    -------
    PiecewisePolynomial
        One segment; ``coeffs[0, :4]`` are ``a0..a3`` of Eq. 11.
    """
    q0, qf = _end_points(q0, qf)
    duration = as_duration(duration)
    if _at_rest(v0, vf):
        return _synchronised(q0, qf - q0, duration, 'cubic')
    n = q0.size
    v0 = as_joint_vector(v0, 'v0', n)
    vf = as_joint_vector(vf, 'vf', n)
    return _single(hermite_coeffs(q0, v0, None, qf, vf, None, duration), duration)


def quintic(q0, qf, duration, v0=0.0, vf=0.0, a0=0.0, af=0.0):
    """Quintic polynomial move with given end velocities and accelerations.

    Zero end velocities and accelerations by default, which gives the
    minimum-jerk profile; continuous acceleration, unlike the cubic.

    Parameters
    ----------
    q0, qf : float or array_like, shape (n_joints,)
        Start and goal positions.
    duration : float
        Move time, s (> 0).
    v0, vf : float or array_like
        End velocities, unit/s.
    a0, af : float or array_like
        End accelerations, unit/s^2.

    Returns
    -------
    PiecewisePolynomial
        One segment of degree 5.
    """
    q0, qf = _end_points(q0, qf)
    duration = as_duration(duration)
    if _at_rest(v0, vf, a0, af):
        return _synchronised(q0, qf - q0, duration, 'quintic')
    n = q0.size
    v0, vf, a0, af = (as_joint_vector(x, name, n) for name, x in
                      (('v0', v0), ('vf', vf), ('a0', a0), ('af', af)))
    return _single(hermite_coeffs(q0, v0, a0, qf, vf, af, duration), duration)


def held_within_limits(q, qd, qdd, lower, upper, max_velocity, max_accel):
    """A state ``(q, qd, qdd)`` held within position, velocity and acceleration limits, as a
    controller commands it: a joint at a position limit stops there; one at its speed limit
    stops accelerating past it; accelerations are clipped. Arrays of shape (n_joints,).
    """
    lo, hi, vmax, amax = lower, upper, max_velocity, max_accel
    q1 = np.minimum(np.maximum(q, lo), hi)
    stopped = ((q1 <= lo) & (qd < 0)) | ((q1 >= hi) & (qd > 0))
    qd1 = np.where(stopped, 0.0, np.minimum(np.maximum(qd, -vmax), vmax))
    outward = ((q1 <= lo) & (qdd < 0)) | ((q1 >= hi) & (qdd > 0)) | ((np.abs(qd1) >= vmax) & (qdd * qd1 > 0))
    return q1, qd1, np.where(outward, 0.0, np.minimum(np.maximum(qdd, -amax), amax))


def brake(q, qd, qdd, max_accel, min_duration=0.05):
    """Bring a moving state to rest smoothly: a quintic from ``(q, qd, qdd)`` to rest.

    The stop takes ``T = max(min_duration, 2 max|qd / max_accel|)`` and travels
    ``qd T / 2`` (the distance of a symmetric deceleration), so the peak
    deceleration stays near ``max_accel``.

    Parameters
    ----------
    q, qd, qdd : array_like, shape (n_joints,)
        Current state.
    max_accel : float or array_like
        Deceleration budget per joint, unit/s^2 (> 0; inf means "none given",
        then 10 unit/s^2 is assumed).
    """
    q = as_joint_vector(q, 'q')
    n = q.size
    qd = as_joint_vector(qd, 'qd', n)
    qdd = as_joint_vector(qdd, 'qdd', n)
    a = np.asarray(max_accel, dtype=float) * np.ones(n)
    a = np.where(np.isfinite(a) & (a > 0), a, 10.0)
    T = max(float(min_duration), 2.0 * float(np.max(np.abs(qd) / a)))
    return quintic(q, q + 0.5 * qd * T, T, qd, 0.0, qdd, 0.0)
