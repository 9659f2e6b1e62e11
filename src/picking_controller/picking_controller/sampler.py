"""Sampling a joint trajectory between its points (pure core, no rclpy).

As ros2_controllers' joint_trajectory_controller does, the spline between two
points is chosen from what the points carry: positions only -> linear, with
velocities -> cubic, with accelerations too -> quintic (closed-form Hermite
coefficients). The result is a picking_planner PiecewisePolynomial, so the
coefficients are computed once per trajectory and every controller tick is
one polynomial evaluation.

Unlike ros2_controllers, positions-only input is not left piecewise-linear by
default (a velocity step at every point: the jerky motion its users complain
about): the points are joined by quintics whose velocities come from a
shape-preserving (PCHIP) interpolant and whose accelerations are zero at the
points, which is C2 and does not overshoot. ``smooth_positions=False`` gives
the linear interpolation of ros2_controllers.

With accelerations, two points less than two microseconds apart are one instant where the
acceleration steps (:mod:`picking_core.trajectory.waypoints`): the first point ends the segment
before it, the second begins the one after it, so the planner's LSPB blends and cubic joins run
exactly as planned instead of through a quintic that overshoots the step.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import PchipInterpolator

from picking_core.trajectory import PiecewisePolynomial, concatenate, hermite_coeffs, quintic
from picking_core.trajectory.waypoints import step_pairs, through_waypoints


def _block(values, name, shape):
    if values is None:
        return None
    arr = np.asarray(values, dtype=float)
    if arr.size == 0:
        return None
    if arr.shape != shape:
        raise ValueError(f'{name} must have one value per joint at every point, shape {shape}, '
                         f'got {arr.shape}')
    if not np.all(np.isfinite(arr)):
        raise ValueError(f'{name} must be finite')
    return arr


def from_points(times, positions, velocities=None, accelerations=None, start=None,
                smooth_positions=True):
    """The trajectory through timed points.

    Parameters
    ----------
    times : array_like, shape (m,)
        ``time_from_start`` of each point, s, strictly increasing, >= 0.
    positions : array_like, shape (m, n)
    velocities, accelerations : array_like, shape (m, n), optional
        Both given -> quintic segments, velocities only -> cubic, none -> linear.
    start : tuple of (q, qd, qdd), optional
        The state at time 0 (the current reference). When the first point is
        later than 0, a segment from this state leads into it, so a new
        trajectory splices onto the motion without a jump.
    smooth_positions : bool
        For positions-only points: C2 shape-preserving quintics (default), or
        straight lines (False).

    Returns
    -------
    PiecewisePolynomial
        Starting at time 0 (or at the first point if no ``start`` is given).

    Raises
    ------
    ValueError
        Empty, unordered, non-finite or inconsistently sized input.
    """
    t = np.asarray(times, dtype=float)
    if t.ndim != 1 or t.size == 0:
        raise ValueError('a trajectory needs at least one point')
    if not np.all(np.isfinite(t)) or t[0] < 0.0:
        raise ValueError('time_from_start must be finite and >= 0')
    if np.any(np.diff(t) <= 0.0):
        k = int(np.argmax(np.diff(t) <= 0.0)) + 1
        raise ValueError(f'time_from_start must increase strictly: point {k} at {t[k]:.6g} s '
                         f'is not after point {k - 1} at {t[k - 1]:.6g} s')
    try:
        q = np.asarray(positions, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError('positions must have one value per joint at every point') from exc
    if q.ndim != 2 or q.shape[0] != t.size or q.shape[1] == 0:
        raise ValueError(f'positions must have shape (points={t.size}, joints), got {q.shape}')
    if not np.all(np.isfinite(q)):
        raise ValueError('positions must be finite')
    v = _block(velocities, 'velocities', q.shape)
    a = _block(accelerations, 'accelerations', q.shape)
    if a is not None and v is None:
        raise ValueError('accelerations need velocities too')
    if v is None and smooth_positions:
        return _smooth_positions(t, q, start)
    main = _through(t, q, v, a, smooth_positions)
    if start is None or t[0] == 0.0:
        return main
    # Lead in from the current state to the first point with a quintic that meets
    # the first point's own velocity and acceleration: no jump at the splice.
    q0, v0, a0 = (np.broadcast_to(np.asarray(x, dtype=float), (q.shape[1],)) for x in start)
    # (The first point's own state: a step pair there starts the trajectory after the step.)
    q1, v1, a1 = (q[0], v[0], a[0]) if a is not None else main.start_state()
    lead = quintic(q0, q1, t[0], v0, v1, a0, a1)
    return concatenate([lead, main])


def _smooth_positions(t, q, start):
    """Quintics with PCHIP velocities and zero accelerations at the points; from ``start`` if given."""
    v0 = a0 = None
    if start is not None and t[0] > 0.0:
        q0, v0, a0 = (np.broadcast_to(np.asarray(x, dtype=float), (q.shape[1],)) for x in start)
        t = np.concatenate(([0.0], t))
        q = np.vstack([q0, q])
    if t.size == 1:
        return _through(t, q, None, None, False)
    vel = PchipInterpolator(t, q, axis=0).derivative()(t) if t.size > 2 else np.zeros_like(q)
    vel[-1] = 0.0
    acc = np.zeros_like(q)
    if v0 is not None:
        vel[0], acc[0] = v0, a0
    elif t[0] == 0.0 and start is None:
        vel[0] = 0.0
    c = hermite_coeffs(q[:-1], vel[:-1], acc[:-1], q[1:], vel[1:], acc[1:], np.diff(t)[:, None])
    return PiecewisePolynomial(t, c.transpose(0, 2, 1))


def _through(t, q, v, a, smooth_positions):
    if t.size == 1:
        coeffs = np.zeros((1, 6, q.shape[1]))
        coeffs[0, 0] = q[0]
        return PiecewisePolynomial([t[0], t[0] + 1e-3], coeffs)
    if a is not None:
        # Velocities and accelerations: the convention of picking_planner's waypoints (one
        # instant for two points a microsecond apart), quintics between the points otherwise.
        if (~step_pairs(t)).sum() < 2:
            return _through(t[:1], q[:1], None, None, False)
        return through_waypoints(t, q, v, a)
    dt = np.diff(t)
    c = hermite_coeffs(q[:-1], None if v is None else v[:-1], None if a is None else a[:-1],
                       q[1:], None if v is None else v[1:], None if a is None else a[1:], dt[:, None])
    return PiecewisePolynomial(t, c.transpose(0, 2, 1))
