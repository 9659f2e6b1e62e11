"""Jerk-limited, time-optimal moves from the Ruckig library, as piecewise polynomials.

Ruckig (Berscheid and Kröger, RSS 2021) computes, for every joint at once, the
fastest motion between two states (position, velocity, acceleration) that keeps
velocity, acceleration and jerk within their limits, all joints arriving
together. Each joint's profile is at most seven constant-jerk phases (plus a
braking pre-phase when the start state breaks a limit); every phase is a cubic
in time, so the result is exactly a :class:`PiecewisePolynomial` -- sampled,
concatenated and sent like every other profile here.
"""

from __future__ import annotations

import math

import numpy as np

from ._checks import MAX_MAGNITUDE, as_joint_vector
from .piecewise import PiecewisePolynomial, compiled_kernels, hold

#: s a move to where the arm already is, at rest, lasts: a hold (a trajectory needs a duration).
NO_MOVE = 0.01


def _limits(value, n, name):
    """``(array, list)`` of a limit for ``n`` joints (a number holds for every joint), finite and > 0."""
    arr = value if _is_vector(value, n) else np.broadcast_to(np.asarray(value, dtype=float), (n,)).copy()
    values = arr.tolist()
    if not all(0.0 < x < math.inf for x in values):
        raise ValueError(f'{name} must be finite and > 0 for every joint, got {values}')
    return arr, values


def _is_vector(x, n):
    """Whether ``x`` is already what the checks make of a vector: n float64 values (the planner's moves)."""
    return type(x) is np.ndarray and x.shape == (n,) and x.dtype == np.float64


def _state(x, name, n):
    """A start or target state vector of ``n`` values as a list (None: zeros), checked as
    :func:`as_joint_vector` checks it."""
    if x is None:
        return [0.0] * n
    values = (x if _is_vector(x, n) else as_joint_vector(x, name, n)).tolist()
    if not all(abs(v) <= MAX_MAGNITUDE for v in values):
        as_joint_vector(x, name, n)                      # raises, naming the argument
    return values


def time_optimal(q0, qf, max_velocity, max_acceleration, max_jerk, v0=None, a0=None, vf=None, af=None,
                 min_duration=0.0):
    """The fastest jerk-limited move from ``(q0, v0, a0)`` to ``(qf, vf, af)``.

    Parameters
    ----------
    q0, qf : array_like, shape (n,)
        Start and target positions.
    max_velocity, max_acceleration, max_jerk : float or array_like, shape (n,)
        Limits per joint (finite, > 0).
    v0, a0, vf, af : array_like, shape (n,), optional
        Start and target velocities and accelerations (default 0).
    min_duration : float
        Take at least this long, s (0: as fast as the limits allow).

    Returns
    -------
    PiecewisePolynomial
        Cubic phases, breaks at the union of every joint's phase boundaries.

    Raises
    ------
    ValueError
        For non-finite input, non-positive limits, or a target Ruckig cannot
        reach within the limits (e.g. a target velocity above the limit).
    """
    from ruckig import InputParameter, Result, Ruckig, RuckigError, Trajectory

    q0 = q0 if _is_vector(q0, np.size(q0)) else as_joint_vector(q0, 'q0')
    n = q0.size
    qf = qf if _is_vector(qf, n) else as_joint_vector(qf, 'qf', n)
    q0_list, qf_list = _state(q0, 'q0', n), _state(qf, 'qf', n)
    _, vmax = _limits(max_velocity, n, 'max_velocity')
    _, amax = _limits(max_acceleration, n, 'max_acceleration')
    jmax, jmax_list = _limits(max_jerk, n, 'max_jerk')
    inp = InputParameter(n)
    inp.current_position, inp.target_position = q0_list, qf_list
    inp.current_velocity, inp.current_acceleration = _state(v0, 'v0', n), _state(a0, 'a0', n)
    inp.target_velocity, inp.target_acceleration = _state(vf, 'vf', n), _state(af, 'af', n)
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = vmax, amax, jmax_list
    if not (np.isfinite(min_duration) and min_duration >= 0):
        raise ValueError(f'min_duration must be >= 0 s, got {min_duration}')
    if min_duration > 0:
        inp.minimum_duration = float(min_duration)
    traj = Trajectory(n)
    used = jmax
    for _ in range(4):
        try:
            result = _calculate(Ruckig(n), inp, traj)
        except RuckigError as exc:              # an input Ruckig refuses (e.g. a target beyond a limit)
            raise ValueError(f'no jerk-limited move: {" ".join(str(exc).split())}') from None
        if result != Result.Working and result != Result.Finished:
            raise ValueError(f'no jerk-limited move reaches the target within the limits (Ruckig: {result.name})')
        if traj.duration <= 0.0:                # already there, at rest: nothing to move
            return hold(qf, max(float(min_duration), NO_MOVE))
        breaks, coeffs = _pieces(traj, n)
        if breaks.size < 2:                     # a move too short for two distinct breaks: nothing to move
            return hold(qf, max(float(min_duration), NO_MOVE))
        # _ending_at's correction jerks up to 60 e / T^3: on a move of a few ms, at the jerk limit
        # already, a few nanoradians of e went beyond it. Planned again with that much room left.
        error = qf - _end_position(breaks, coeffs)
        added = 60.0 * np.abs(error) / (breaks[-1] - breaks[0]) ** 3
        if np.all(used + added <= jmax * (1.0 + 1e-12)):
            break
        # (The error is rounding: it moves from joint to joint from one plan to the next; room on every joint.)
        used = np.minimum(used, jmax * max(1.0 - 2.0 * float(np.max(added / jmax)), 0.5))
        inp.max_jerk = used.tolist()
    return PiecewisePolynomial(breaks, _ending_at(breaks, coeffs, error))


def time_optimal_stop(q0, v0, a0, max_velocity, max_acceleration, max_jerk):
    """The fastest jerk-limited stop from ``(q0, v0, a0)``: every joint at rest as soon as
    its limits allow (each on its own; the others then hold).

    A start beyond a limit gets Ruckig's braking pre-phase. Raises ValueError for
    non-finite input or non-positive limits.
    """
    from ruckig import ControlInterface, InputParameter, Result, Ruckig, RuckigError, Synchronization, Trajectory

    q0 = as_joint_vector(q0, 'q0')
    n = q0.size
    v0, a0 = as_joint_vector(v0, 'v0', n), as_joint_vector(a0, 'a0', n)
    inp = InputParameter(n)
    inp.control_interface = ControlInterface.Velocity
    inp.synchronization = Synchronization.No
    inp.current_position, inp.current_velocity, inp.current_acceleration = q0.tolist(), v0.tolist(), a0.tolist()
    inp.target_velocity, inp.target_acceleration = [0.0] * n, [0.0] * n
    inp.max_velocity = _limits(max_velocity, n, 'max_velocity')[1]
    inp.max_acceleration = _limits(max_acceleration, n, 'max_acceleration')[1]
    inp.max_jerk = _limits(max_jerk, n, 'max_jerk')[1]
    traj = Trajectory(n)
    try:
        result = _calculate(Ruckig(n), inp, traj)
    except RuckigError as exc:
        raise ValueError(f'no jerk-limited stop: {" ".join(str(exc).split())}') from None
    if result != Result.Working and result != Result.Finished:
        raise ValueError(f'no jerk-limited stop within the limits (Ruckig: {result.name})')
    if traj.duration <= 0.0:
        raise ValueError('already at rest: nothing to stop')
    return PiecewisePolynomial(*_pieces(traj, n))


#: Relative tightenings of the limits tried when Ruckig fails on the limits as given.
RETRY_SHRINK = (1e-9, 1e-6)


def _calculate(ruckig, inp, traj):
    """``ruckig.calculate(inp, traj)``, again with every limit a hair lower if it raises.

    Ruckig 0.19 fails ("error in step 1") on a few inputs that lie exactly on the border
    between two profile shapes: a line of 0.08 m at 0.6 m/s, 4 m/s^2 and 40 m/s^3 (as
    progress limits 7.5/s, 50/s^2, 500/s^3, give or take a rounding) fails, while 1e-15
    more or less length works; of 20 000 rest-to-rest moves drawn on such borders (the
    distance that just reaches the acceleration or the velocity limit, give or take a few
    roundings) it raised for 1282. Limits lower by a part in 1e-9 move the input off the
    border and keep every limit (none of the 20 000 failed then). An input Ruckig refuses for what it is (a target speed
    above the limit) fails again, and its first error is raised.
    """
    from ruckig import RuckigError

    if not len(inp.current_position):             # (Ruckig divides by the joints' count: a crash, not an error)
        raise ValueError('no joints to move: the positions are empty')
    try:
        return ruckig.calculate(inp, traj)
    except RuckigError as first:
        limits = (list(inp.max_velocity), list(inp.max_acceleration), list(inp.max_jerk))
        for shrink in RETRY_SHRINK:
            inp.max_velocity, inp.max_acceleration, inp.max_jerk = ([x * (1.0 - shrink) for x in lim]
                                                                  for lim in limits)
            try:
                return ruckig.calculate(inp, traj)
            except RuckigError:
                continue
        raise first


def _ending_at(breaks, coeffs, error):
    """The pieces ``coeffs`` (K, 6, n) on ``breaks`` moved by ``error`` (n,) at their end, exactly (in
    place: they are the move's own, fresh from :func:`_pieces`).

    Ruckig meets a target position within its precision (up to about 1e-8 rad), while
    a move that the next one continues (a blend into a line, a via point) must end
    where that one starts (:func:`concatenate` checks 1e-9). The remainder is added
    as a smoothstep over the whole move, ``e (10 s^3 - 15 s^4 + 6 s^5)``: it leaves
    the start and both ends' velocities and accelerations as they are, and changes
    velocities by at most ``1.875 e / T`` (of order 1e-8 rad/s). Each piece gets the
    smoothstep's Taylor coefficients about its own start (its k-th derivative there over k!).
    """
    if not error.any():
        return coeffs
    kernels = compiled_kernels()
    if kernels is not None:
        kernels.add_smoothstep(breaks, coeffs, error)
        return coeffs
    T = breaks[-1] - breaks[0]
    T2 = T * T
    T3, T4, T5 = T2 * T, T2 * T2, T2 * T2 * T
    x = ((breaks[:-1] - breaks[0]) / T)[:, None]                       # (K, 1)
    x2 = x * x
    e = error[None, :]
    out = coeffs
    out[:, 0] += e * (x2 * x) * (10.0 - 15.0 * x + 6.0 * x2)
    out[:, 1] += e / T * x2 * (30.0 - 60.0 * x + 30.0 * x2)
    out[:, 2] += e / T2 * x * (30.0 - 90.0 * x + 60.0 * x2)
    out[:, 3] += e / T3 * (10.0 - 60.0 * x + 60.0 * x2)
    out[:, 4] += e / T4 * (-15.0 + 30.0 * x)
    out[:, 5] += e / T5 * 6.0
    return out


def _end_position(breaks, coeffs):
    """Where the pieces end: the last cubic (Ruckig's phases are cubics) at the last break."""
    h = breaks[-1] - breaks[-2]
    c = coeffs[-1]
    return c[0] + h * (c[1] + h * (c[2] + h * c[3]))


def _pieces(traj, n):
    """``(breaks, coeffs)`` of Ruckig's per-joint phases (brake pre-phase, seven jerk phases, a
    final hold) on the union of every joint's phase boundaries.

    Every phase is a cubic from its start state, so each joint's polynomial on each interval
    of the union is its phase's state at the interval's start: no re-expansion needed.
    """
    duration = traj.duration
    profiles = traj.profiles[0]
    # Per joint, the 9 phases' durations, start states (p, v, a) and jerks; then the hold at the end.
    phases = np.array([[prof.brake.t + prof.t for prof in profiles], [prof.brake.p + prof.p[:7] for prof in profiles],
                       [prof.brake.v + prof.v[:7] for prof in profiles],
                       [prof.brake.a + prof.a[:7] for prof in profiles], [prof.brake.j + prof.j for prof in profiles]])
    end = np.array([prof.p[7] for prof in profiles])
    kernels = compiled_kernels()
    if kernels is not None:
        breaks, coeffs = np.empty(11 * n), np.zeros((11 * n, 6, n))
        k = kernels.phase_pieces(phases, end, duration, breaks, coeffs)
        return breaks[:k + 1].copy(), coeffs[:k].copy()
    t, p, v, a, j = phases                                                              # (n, 9) each
    starts = np.zeros((n, 11))
    np.cumsum(t, axis=1, out=starts[:, 1:10])
    # Hold the end from each joint's finish to the common end (zero width when synchronised).
    starts[:, 10] = np.maximum(starts[:, 9], duration)
    union = np.unique(starts)
    span = union[-1] - union[0]
    # Fold boundaries that differ only by rounding into one.
    union = union[np.concatenate(([True], np.diff(union) > 1e-12 * max(span, 1.0)))]
    union[-1] = starts[:, 10].max()
    mids = 0.5 * (union[:-1] + union[1:])
    # Each joint's phase on each interval (the last that starts before its middle), and the time into it.
    piece = np.minimum((mids[:, None, None] >= starts[None, :, 1:10]).sum(axis=2), 9)   # (K, n)
    cols = np.arange(n)[None, :]
    dt = union[:-1, None] - starts[cols, piece]
    zero = np.zeros((n, 1))
    P, V, A, J = (np.concatenate([x, tail], axis=1)[cols, piece]
                  for x, tail in ((p, end[:, None]), (v, zero), (a, zero), (j, zero)))
    coeffs = np.zeros((len(mids), 6, n))
    coeffs[:, 0] = P + dt * (V + dt * (0.5 * A + dt * J / 6.0))
    coeffs[:, 1] = V + dt * (A + 0.5 * dt * J)
    coeffs[:, 2] = 0.5 * (A + dt * J)
    coeffs[:, 3] = J / 6.0
    return union, coeffs
