"""A new trajectory made into an entry of the schedule at its stamp (pure core).

A trajectory stamped ``t_s`` (0: from the current reference, now) takes over the schedule at
``t_s``. Where its first point is the reference at ``t_s`` (position, velocity and acceleration)
it carries on from it exactly. Where it is not:

- a first point given a ``time_from_start`` > 0 is led into from the reference over that time (as
  ros2_controllers' joint trajectory controller interpolates to it), when that lead-in keeps every
  limit;
- otherwise the reference is bridged to the first point by the fastest jerk-limited move within the
  limits (Ruckig), and the points run that much later.

A stamp already past is refused as late (``OLD_HEADER_TIMESTAMP``: its sender may plan again from a
later start); a trajectory the arm cannot run is refused with the reason (``INVALID_GOAL``). The
splicer reads the schedule and changes nothing: :meth:`ControllerCore.commit` puts its entry on.
"""

from __future__ import annotations

import numpy as np

from picking_core.trajectory import concatenate, time_optimal

from .events import Event, LateTrajectory
from .sampler import from_points
from .schedule import Entry

#: s: how well a trajectory's stamp places its first point in time (a float of the epoch's seconds
#: resolves a quarter of a microsecond; the stamp and the point's time_from_start are each rounded).
STAMP_RESOLUTION = 1e-6
#: s: a first point due sooner than this after the splice is bridged, not led into (a lead-in so short
#: takes an acceleration no arm has).
MIN_LEAD = 0.02
#: Jerk used for the bridge of a joint with no jerk limit, as a multiple of its acceleration limit (1/s).
JERK_PER_ACCELERATION = 50.0


class Splicer:
    """Makes trajectory messages into schedule entries for an arm of :class:`~.validation.Limits`."""

    def __init__(self, limits, validator):
        self.limits, self.validator = limits, validator
        jerk = np.where(np.isfinite(limits.max_jerk), limits.max_jerk,
                        JERK_PER_ACCELERATION * np.where(np.isfinite(limits.max_acceleration),
                                                         limits.max_acceleration, 1.0))
        self._bridge_limits = tuple(np.where(np.isfinite(x), x, 1e3) for x in
                                    (limits.max_velocity, limits.max_acceleration, jerk))

    def entry(self, schedule, message, t_now, goal=None, tolerances=None):
        """The :class:`Entry` of ``message`` (a :class:`Points`) spliced at its stamp, ``t_now`` the earliest
        splice (schedule time, s); ``(entry, words)`` with how it joins the reference. Raises
        :class:`LateTrajectory` for a start already past, ValueError for any other refusal."""
        t_s = message.start if message.start > 0 else t_now
        if t_s < t_now - STAMP_RESOLUTION:
            raise LateTrajectory(f'it starts {t_now - t_s:.3f} s in the past (header.stamp {message.start:.6f}); '
                                 'stamp it later, or 0 to start from the current reference now')
        schedule = schedule.until(t_s)          # what was scheduled from t_s on is replaced
        ref = self.limits.held(*schedule.state_at(t_s))
        v = self.validator
        order = v.order(message.names)
        m, k = message.times.size, len(message.names)
        pos = v.block(message.positions, m, k, order, 'positions', held=ref[0])
        vel = v.block(message.velocities, m, k, order, 'velocities', optional=True)
        acc = v.block(message.accelerations, m, k, order, 'accelerations', optional=True)
        times = message.times
        if m and times[0] < 0:
            raise ValueError('time_from_start must be >= 0')
        v.check_points(pos, vel, acc, times + (t_s - t_now))
        if _carries_on(schedule, t_s + times[0], pos[0], vel, acc, self.limits):
            traj = from_points(times - times[0], pos, vel, acc)
            v.check_spline(traj)
            return Entry(t_s + times[0], traj, t_s, goal, tolerances, cut=t_s), 'carries on from the reference'
        if times[0] >= MIN_LEAD:
            led = self._led_in(times, pos, vel, acc, ref)
            if led is not None:
                return Entry(t_s, led, t_s, goal, tolerances, lead=float(times[0])), \
                    f'led in from the reference over {times[0]:.3f} s'
        bridge = self._bridge(ref, pos[0], None if vel is None else vel[0], None if acc is None else acc[0])
        main = from_points(times - times[0], pos, vel, acc)
        v.check_spline(main)
        traj = concatenate([bridge, main])
        origin = t_s + bridge.duration - times[0]
        return Entry(t_s, traj, origin, goal, tolerances, lead=bridge.duration), \
            f'bridged from the reference in {bridge.duration:.3f} s (its points run that much later)'

    def _led_in(self, times, pos, vel, acc, ref):
        """The trajectory led into from ``ref`` over the first point's time, or None where that lead-in would
        break a limit."""
        try:
            traj = from_points(times, pos, vel, acc, start=ref)
            self.validator.check_spline(traj)
        except ValueError:
            return None
        lead = float(times[0])
        t = np.linspace(traj.start_time, traj.start_time + lead, 17)
        qdd = traj.sample(t)[2]
        if (np.abs(qdd) > self.limits.max_acceleration * (1 + 1e-3) + 1e-6).any():
            return None
        return traj

    def _bridge(self, ref, q, qd, qdd):
        """The fastest jerk-limited move from the reference ``ref`` to the state ``(q, qd, qdd)`` (None: 0),
        within every limit; ValueError naming why there is none."""
        vmax, amax, jmax = self._bridge_limits
        try:
            bridge = time_optimal(ref[0], q, vmax, amax, jmax, v0=ref[1], a0=ref[2], vf=qd, af=qdd)
        except ValueError as exc:
            raise ValueError(f'its first point cannot be reached from the current reference within the limits '
                             f'({exc})') from None
        lim = self.limits
        t = np.linspace(0.0, bridge.duration, 64)
        path = bridge.sample(t)[0]
        low, high = path < lim.lower - 1e-6, path > lim.upper + 1e-6
        if (low | high).any():
            i, j = np.argwhere(low | high)[0]
            raise ValueError(f'the bridge from the current reference to its first point takes {lim.names[j]} to '
                             f'{path[i, j]:.4g} rad, beyond [{lim.lower[j]:.4g}, {lim.upper[j]:.4g}]: give the first '
                             'point a state nearer the reference')
        return bridge


def _carries_on(schedule, t, q, vel, acc, limits):
    """True when the state ``(q, vel[0], acc[0])`` is the reference at schedule time ``t`` (within how much the
    reference itself moves over the stamp's resolution): the trajectory then runs from there exactly."""
    qd = np.zeros_like(q) if vel is None else vel[0]
    qdd = np.zeros_like(q) if acc is None else acc[0]
    states = [limits.held(*schedule.state_at(t + dt)) for dt in (-STAMP_RESOLUTION, 0.0, STAMP_RESOLUTION)]
    for k, (x, tol) in enumerate(((q, 1e-6), (qd, 1e-6), (qdd, 1e-6 * (1.0 + np.abs(qdd).max())))):
        at = states[1][k]
        spread = np.maximum(np.abs(states[0][k] - at), np.abs(states[2][k] - at))
        if (np.abs(x - at) > tol + spread).any():
            return False
    return True


def accepted(entry, points, words, t_now):
    """The event of a trajectory spliced: its points, duration, when it takes over and how it joins."""
    return Event('OK', f'trajectory accepted: {words}', {
        'points': points, 'duration': float(entry.traj.duration), 'starts_in': float(max(entry.start - t_now, 0.0)),
        'bridge': float(entry.lead)}, goal=entry.goal)
