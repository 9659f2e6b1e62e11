"""The limits a plan keeps: the scaled limits, the shortest durations within them, where and how a
plan is checked, and the state a plan starts from."""

from __future__ import annotations

import functools

import numpy as np

from .. import trajectory
from ..kinematics import Unreachable
from ..kinematics.paths import check_joint_limits
from .settings import _PEAKS, DEFAULT_JERK_PER_ACCEL, PLAN_MARGIN


def _check_times(traj):
    """Where the limits of ``traj`` (its own clock starting at 0) are checked: every 2.5 ms, at
    least 50 times; for a trajectory of parabolas (LSPB: each piece of degree <= 2), exactly
    where its extremes lie instead: the breaks (its velocity is linear in each piece), the
    middle of each piece (its constant acceleration; at a break the piece that ends there
    answers) and where a joint turns inside a piece (its position's extreme there)."""
    b, c = traj.breaks, traj.coeffs
    if c[:, 3:].any():
        return np.linspace(0.0, traj.duration, max(50, int(traj.duration / 0.0025)))
    span = b[1:] - b[:-1]
    v0 = c[:, 1]
    piece, joint = np.nonzero(v0 * (v0 + 2.0 * c[:, 2] * span[:, None]) < 0.0)    # qd changes sign
    turns = b[piece] - v0[piece, joint] / (2.0 * c[piece, 2, joint])
    return np.sort(np.concatenate((b, b[:-1] + 0.5 * span, turns)))


def feasible_start(arm, q, qd, qdd):
    """An extrapolated reference state held within the limits, as the controller's reference is.

    Carried on too far, a constant acceleration crosses a limit; no plan can start from
    such a state and keep the limits. A joint at a position limit stops there; one at
    its velocity limit stops accelerating beyond it; one near a position limit moves
    toward it no faster than it can stop; accelerations are clipped. (The controller's
    lead-in absorbs the small difference from its real reference.)
    """
    vmax = arm.max_velocity
    q1, qd1, qdd1 = trajectory.held_within_limits(q, qd, qdd, arm.lower, arm.upper, vmax, arm.max_acceleration)
    # Speeding up, a joint gains a^2 / 2j more speed before the jerk limit lets its
    # acceleration reach zero: no more than it has left below its speed limit.
    room = np.sqrt(2.0 * _full_jerk(arm) * np.maximum(vmax - np.abs(qd1), 0.0))
    speeding_up = qdd1 * qd1 > 0
    qdd1 = np.where(speeding_up, np.clip(qdd1, -room, room), qdd1)
    # Near a position limit, moving toward it: no faster than a brake at the acceleration limit can
    # stop before it (the planner's quintic brake travels qd^2 / a), and not speeding up toward it.
    amax = np.where(np.isfinite(arm.max_acceleration), arm.max_acceleration, 10.0)
    left = np.maximum(np.where(qd1 > 0, arm.upper - q1, q1 - arm.lower), 0.0)
    stoppable = np.sqrt(left * amax)
    too_fast = np.abs(qd1) > stoppable
    qdd1 = np.where(too_fast & (qdd1 * qd1 > 0), 0.0, qdd1)
    qd1 = np.where(too_fast, np.sign(qd1) * stoppable, qd1)
    return q1, qd1, qdd1


def _read_only(a):
    a.flags.writeable = False
    return a


def _full_jerk(arm):
    """The arm's jerk limits, DEFAULT_JERK_PER_ACCEL times the acceleration limit where none is given."""
    a = np.where(np.isfinite(arm.max_acceleration), arm.max_acceleration, 2.0)
    return np.where(np.isfinite(arm.max_jerk), arm.max_jerk, DEFAULT_JERK_PER_ACCEL * a)


class Limits:
    """The limits part of :class:`~picking_core.planning.Planner` (``self.arm``, ``self.settings``)."""

    # -- limits and durations -----------------------------------------------------
    # The scaled limits, computed once: the settings are frozen and the arm's limits read-only
    # (a pick cycle reads them about 30 times).
    @functools.cached_property
    def _vmax(self):
        v = np.where(np.isfinite(self.arm.max_velocity), self.arm.max_velocity, 1.0)
        return _read_only(v * self.settings.speed_scale * PLAN_MARGIN)

    @functools.cached_property
    def _amax(self):
        a = np.where(np.isfinite(self.arm.max_acceleration), self.arm.max_acceleration, 2.0)
        return _read_only(a * (self.settings.speed_scale ** 2) * PLAN_MARGIN)

    @functools.cached_property
    def _jmax(self):
        return _read_only(_full_jerk(self.arm) * (self.settings.speed_scale ** 3) * PLAN_MARGIN)

    def shortest_duration(self, q0, qf, method):
        """The shortest time in which every joint makes its move within the scaled limits, s."""
        return float(self._shortest_durations(np.array((q0, qf), float), method)[0])

    def _shortest_durations(self, qs, method):
        """:meth:`shortest_duration` of each move between consecutive configurations ``qs``
        (m + 1, n), shape (m,)."""
        h = np.abs(np.diff(qs, axis=0))
        v, a = self._vmax, self._amax
        if method == 'lspb':
            cruise = h > v**2 / a
            t = np.where(cruise, h / v + v / a, 2.0 * np.sqrt(h / a))
        else:
            kv, ka = _PEAKS[method]
            t = np.maximum(kv * h / v, np.sqrt(ka * h / a))
            if self.settings.limit_jerk and method == 'quintic':
                # A quintic from rest to rest jerks hardest at its ends: 60 h / T^3.
                t = np.maximum(t, np.cbrt(60.0 * h / self._jmax))
        return np.maximum(t.max(axis=1), self.settings.sample_period)

    def move_times(self, q_from, q_to):
        """Estimated times of the rest-to-rest moves from every configuration of ``q_from`` (m, n) to
        every one of ``q_to`` (k, n), s, shape (m, k): each joint's trapezoid at the scaled limits,
        plus the time its jerk limit takes to build the acceleration up; the slowest joint's. For
        choosing among many moves (a harvest's order), not for timing one: it plans nothing."""
        h = np.abs(np.asarray(q_to, float)[None, :, :] - np.asarray(q_from, float)[:, None, :])
        v, a = self._vmax, self._amax
        t = np.where(h > v**2 / a, h / v + v / a, 2.0 * np.sqrt(h / a))
        if self.settings.limit_jerk:
            t = np.where(h > 0.0, t + a / self._jmax, 0.0)
        return t.max(axis=2)

    def check_limits(self, traj, label):
        """Raise Unreachable, its message led by ``label``, where ``traj`` (the arm's joints first) breaks a
        position, velocity, acceleration or (with ``limit_jerk``) jerk limit of the arm."""
        self._check(traj, label)

    def _check(self, traj, label):
        t = _check_times(traj)
        q, qd, qdd = traj.sample(t)
        try:
            check_joint_limits(self.arm, t, q, qd, qdd, slack=1e-6)
            if self.settings.limit_jerk:
                self._check_jerk(traj, t)
        except Unreachable as exc:
            raise Unreachable(f'{label}: {exc}') from None

    def _limit_use(self, traj):
        """How far ``traj`` goes into the scaled limits: the largest |qd| / vmax and sqrt(|qdd| / amax)
        (stretched that many times, it reaches them)."""
        t = np.linspace(0.0, traj.duration, max(50, int(traj.duration / 0.0025)))
        _, qd, qdd = traj.sample(t)
        return max(float(np.max(np.abs(qd) / self._vmax)), float(np.sqrt(np.max(np.abs(qdd) / self._amax))))

    def _jerk_ratio(self, traj, t):
        """Largest |jerk| over the scaled jerk limit along ``traj`` at times ``t``."""
        jerk = np.abs(traj.jerk(t))[:, :self.arm.dof]
        return float(np.max(jerk / self._jmax)) if jerk.size else 0.0

    def _check_jerk(self, traj, t):
        over = self._jerk_ratio(traj, t)
        if over > 1.0 / PLAN_MARGIN + 1e-6:
            raise Unreachable(f'jerk limit broken: {over * PLAN_MARGIN:.2f} times the limit; slow the motion down')

    # -- the start ----------------------------------------------------------------------
    def check_start(self, start):
        """``start = (q, qd, qdd)`` as three finite arrays of one value per joint (a velocity or an
        acceleration given as one number holds for every joint), else ValueError."""
        try:
            q, qd, qdd = start
        except (TypeError, ValueError):
            raise ValueError('start must be (q, qd, qdd): positions, velocities, accelerations') from None
        out = []
        for name, x in (('start position', q), ('start velocity', qd), ('start acceleration', qdd)):
            try:
                arr = np.asarray(x, dtype=float)
            except (TypeError, ValueError):
                raise ValueError(f'{name} must be numbers, one per joint') from None
            if arr.ndim == 0 and name != 'start position':
                arr = np.full(self.arm.dof, float(arr))
            if arr.shape != (self.arm.dof,):
                raise ValueError(f'{name} must have {self.arm.dof} values (one per joint), got shape {arr.shape}')
            out.append(self.arm.check_joints(arr, name))
        return tuple(out)

    def come_to_rest(self, start):
        """A braking segment when the start state moves (None at rest), and the rest state."""
        q, qd, qdd = self.check_start(start)
        if np.abs(qd).max() < 1e-4 and np.abs(qdd).max() < 1e-3:
            return None, q
        vmax = np.where(np.isfinite(self.arm.max_velocity), self.arm.max_velocity, np.inf)
        amax = np.where(np.isfinite(self.arm.max_acceleration), self.arm.max_acceleration, np.inf)
        # Ruckig's time-optimal, jerk-limited stop keeps the velocity and acceleration limits
        # whenever any stop can.
        try:
            stop = trajectory.time_optimal_stop(q, qd, qdd, np.minimum(vmax, 1e3), np.minimum(amax, 1e4),
                                                np.minimum(_full_jerk(self.arm), 1e5))
            p, v, a = stop.sample(np.linspace(0.0, stop.duration, 201))
            if (np.abs(v) <= vmax + 1e-9).all() and (np.abs(a) <= amax + 1e-9).all() and \
                    self.arm.within_limits(p).all():
                return stop, stop.end_state()[0]
        except ValueError:
            pass
        # Else the shortest of a few quintic stops that keeps the limits (a start already
        # decelerating hard needs more time than its speed alone says); none does: the first,
        # unless it leaves a position limit (no plan from this start could keep it).
        first = None
        for least in (0.05, 0.1, 0.2, 0.4):
            stop = trajectory.brake(q, qd, qdd, self.arm.max_acceleration, min_duration=least)
            if first is None:
                first = stop
            p, v, a = stop.sample(np.linspace(0.0, stop.duration, 101))
            if (np.abs(v) <= np.maximum(vmax, np.abs(qd)) + 1e-9).all() and \
                    (np.abs(a) <= np.maximum(amax, np.abs(qdd)) + 1e-9).all() and self.arm.within_limits(p).all():
                break
        else:
            stop = first
            self._check_stops_within_position_limits(q, qd, stop)
        return stop, stop.end_state()[0]

    def _check_stops_within_position_limits(self, q, qd, stop):
        """Unreachable, naming the joint, when the stop from the start passes a position limit."""
        p = stop.sample(np.linspace(0.0, stop.duration, 101))[0]
        arm = self.arm
        beyond = (p < arm.lower - 1e-9) | (p > arm.upper + 1e-9)
        if beyond.any():
            j = int(np.flatnonzero(beyond.any(axis=0))[0])
            upper = bool((p[:, j] > arm.upper[j] + 1e-9).any())
            reach = p[:, j].max() if upper else p[:, j].min()
            limit = arm.upper[j] if upper else arm.lower[j]
            raise Unreachable(f'{arm.joint_names[j]} moves at {qd[j]:.3g} rad/s from {q[j]:.4g} rad toward its '
                              f'limit {limit:.4g} rad and cannot stop before it (a stop within the acceleration '
                              f'limit reaches {reach:.4g} rad): no plan from this motion keeps the limit')
