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

import numpy as np

from ._checks import as_joint_vector
from .piecewise import PiecewisePolynomial, hold, merge_joint_pieces, taylor_shift
from .polynomial import hermite_coeffs

#: s a move to where the arm already is, at rest, lasts: a hold (a trajectory needs a duration).
NO_MOVE = 0.01


def _limits(value, n, name):
    arr = np.broadcast_to(np.asarray(value, dtype=float), (n,)).copy()
    if not np.all(np.isfinite(arr)) or np.any(arr <= 0):
        raise ValueError(f'{name} must be finite and > 0 for every joint, got {arr.tolist()}')
    return arr


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

    q0 = as_joint_vector(q0, 'q0')
    n = q0.size
    qf = as_joint_vector(qf, 'qf', n)
    states = [as_joint_vector(np.zeros(n) if x is None else x, name, n)
              for x, name in ((v0, 'v0'), (a0, 'a0'), (vf, 'vf'), (af, 'af'))]
    vmax = _limits(max_velocity, n, 'max_velocity')
    amax = _limits(max_acceleration, n, 'max_acceleration')
    jmax = _limits(max_jerk, n, 'max_jerk')
    inp = InputParameter(n)
    inp.current_position, inp.target_position = q0.tolist(), qf.tolist()
    inp.current_velocity, inp.current_acceleration = states[0].tolist(), states[1].tolist()
    inp.target_velocity, inp.target_acceleration = states[2].tolist(), states[3].tolist()
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = vmax.tolist(), amax.tolist(), jmax.tolist()
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
        raw = _to_piecewise(traj, n)
        # _ending_at's correction jerks up to 60 e / T^3: on a move of a few ms, at the jerk limit
        # already, a few nanoradians of e went beyond it. Planned again with that much room left.
        added = 60.0 * np.abs(qf - raw.end_state()[0]) / raw.duration ** 3
        if np.all(used + added <= jmax * (1.0 + 1e-12)):
            break
        # (The error is rounding: it moves from joint to joint from one plan to the next; room on every joint.)
        used = np.minimum(used, jmax * max(1.0 - 2.0 * float(np.max(added / jmax)), 0.5))
        inp.max_jerk = used.tolist()
    return _ending_at(raw, qf)


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
    inp.max_velocity = _limits(max_velocity, n, 'max_velocity').tolist()
    inp.max_acceleration = _limits(max_acceleration, n, 'max_acceleration').tolist()
    inp.max_jerk = _limits(max_jerk, n, 'max_jerk').tolist()
    traj = Trajectory(n)
    try:
        result = _calculate(Ruckig(n), inp, traj)
    except RuckigError as exc:
        raise ValueError(f'no jerk-limited stop: {" ".join(str(exc).split())}') from None
    if result != Result.Working and result != Result.Finished:
        raise ValueError(f'no jerk-limited stop within the limits (Ruckig: {result.name})')
    if traj.duration <= 0.0:
        raise ValueError('already at rest: nothing to stop')
    return _to_piecewise(traj, n)


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


def _ending_at(traj, qf):
    """``traj`` moved onto the target position ``qf`` at its end, exactly.

    Ruckig meets a target position within its precision (up to about 1e-8 rad), while
    a move that the next one continues (a blend into a line, a via point) must end
    where that one starts (:func:`concatenate` checks 1e-9). The remainder is added
    as a smoothstep over the whole move, ``e (10 s^3 - 15 s^4 + 6 s^5)``: it leaves
    the start and both ends' velocities and accelerations as they are, and changes
    velocities by at most ``1.875 e / T`` (of order 1e-8 rad/s).
    """
    error = qf - traj.end_state()[0]
    if not error.any():
        return traj
    # The quintic from 0 to the remainder, at rest at both ends, re-expanded about every break.
    smoothstep = hermite_coeffs(0.0, 0.0, 0.0, error, 0.0, 0.0, traj.duration).T     # (6, n)
    pieces = np.broadcast_to(smoothstep, (len(traj.breaks) - 1,) + smoothstep.shape)
    local = taylor_shift(pieces, traj.breaks[:-1] - traj.breaks[0])
    return PiecewisePolynomial(traj.breaks, traj.coeffs + local)


def _to_piecewise(traj, n):
    """Ruckig's per-joint phases (brake pre-phase, seven jerk phases, a final hold) merged."""
    duration = traj.duration
    pieces = 10
    breaks = np.zeros((pieces + 1, n))
    coeffs = np.zeros((pieces, 6, n))
    for j, prof in enumerate(traj.profiles[0]):
        phases = []
        brake = prof.brake
        for k in range(2):
            phases.append((brake.t[k], brake.p[k], brake.v[k], brake.a[k], brake.j[k]))
        for k in range(7):
            phases.append((prof.t[k], prof.p[k], prof.v[k], prof.a[k], prof.j[k]))
        t = 0.0
        for k, (dt, p, v, a, jerk) in enumerate(phases):
            breaks[k, j] = t
            coeffs[k, :4, j] = (p, v, 0.5 * a, jerk / 6.0)
            t += dt
        # Hold the end from this joint's finish to the common end (zero width when synchronised).
        breaks[9, j] = t
        coeffs[9, 0, j] = prof.p[7]
        breaks[10, j] = max(t, duration)
    return PiecewisePolynomial(*merge_joint_pieces(breaks, coeffs))
