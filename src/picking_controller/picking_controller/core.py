"""The trajectory controller's logic, with no ROS in it.

:class:`ControllerCore` holds the active trajectory on the controller's clock,
produces the reference at every tick, validates new trajectories, splices them
onto the current reference (no jump), monitors tracking against tolerances,
and runs the feedback watchdog. The node only feeds it messages and the clock
and publishes what it returns.

Times are seconds on one clock (the node's ROS clock).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from picking_planner.trajectory import PiecewisePolynomial, brake, held_within_limits, hold

from .sampler import from_points

#: Shortest lead-in from the current reference to a new trajectory's first point, s.
MIN_LEAD = 0.02
#: Lead-ins tried in turn when a shorter one would break a limit (a trajectory that came late), s.
LEADS = (MIN_LEAD, 0.05, 0.1, 0.2)


class LateTrajectory(ValueError):
    """A trajectory that came too late to run as sent: it ends before it could take over, or the
    points due by then cannot be caught up on (too far from the reference, or only beyond a
    limit), or it was planned from a reference the controller no longer follows (its first point
    is not where the reference will be, and the lead-in from there breaks a limit). Its sender
    may plan it again; a trajectory rejected otherwise is at fault itself."""


@dataclass(frozen=True)
class Prepared:
    """A validated trajectory, ready to take over at ``t_splice`` (see :meth:`ControllerCore.prepare`)."""

    traj: PiecewisePolynomial
    t_splice: float
    version: int
    accepted: Event
    lead_in: float = 0.0                 # s: the lead-in from the reference to the first point


@dataclass(frozen=True)
class Tolerances:
    """Tracking tolerances (rad, s), one value for every joint or one per joint."""

    path: float = 0.1                    # largest |measured - reference| while moving
    goal: float = 0.005                  # at the end
    goal_time: float = 2.0               # s after the end to get within ``goal``
    stopped_velocity: float = 0.02       # rad/s, "at rest" at the goal
    state_timeout: float = 0.5           # s without joint_states before "feedback lost"


@dataclass
class Event:
    """Something the node reports on ``controller_status``."""

    level: str                           # 'OK', 'WARN' or 'ERROR'
    message: str
    values: dict = field(default_factory=dict)


class ControllerCore:
    """Reference generation and supervision for one arm.

    Parameters
    ----------
    names : sequence of str
        The arm's joints, in command order.
    lower, upper, max_velocity, max_acceleration : array_like
        Limits per joint (inf where none).
    tolerances : Tolerances
    optional : sequence of str
        Joints a trajectory may leave out (a gripper): they hold their reference.
    stall_limit : float
        s: ticks farther apart than this (a stalled loop) delay the trajectory by
        the excess instead of making the reference jump ahead (see :meth:`advance`).
    """

    def __init__(self, names, lower, upper, max_velocity, max_acceleration, tolerances=Tolerances(),
                 optional=(), stall_limit=0.05):
        if not stall_limit > 0:
            raise ValueError(f'stall_limit must be > 0 s, got {stall_limit}')
        self.names = list(names)
        self.optional = set(optional)
        self.n = len(self.names)
        self.lower = np.asarray(lower, float)
        self.upper = np.asarray(upper, float)
        self.max_velocity = np.asarray(max_velocity, float)
        self.max_acceleration = np.asarray(max_acceleration, float)
        self.tol = tolerances
        self.mode = 'waiting'            # waiting -> holding <-> moving; fault on a violation
        self.traj: PiecewisePolynomial | None = None
        self.t0 = 0.0                    # clock time of the trajectory's t = 0
        self.lead_in_end = -np.inf       # clock time its lead-in to its first point ends
        self.measured_q = None
        self.measured_qd = None
        self.measured_time = None
        self.feedback_ok = False
        self.max_error = np.zeros(self.n)
        self.version = 0                 # counts changes of the active trajectory
        self.next = None                 # a Prepared trajectory waiting for its splice time
        self._last_command = None        # (q, time) of the last command sent
        self.limited = 0                 # ticks whose command had to be limited
        self._limited_version = -1
        self.stall_limit = float(stall_limit)
        self.delayed = 0.0               # s the trajectories were delayed by stalled ticks, in all
        self._last_tick = None
        self._stalled_until = -np.inf    # when the last stall ended (its delay was applied)
        self._stall_reported = -np.inf

    # -- feedback -------------------------------------------------------------
    def on_state(self, q, qd, stamp, now):
        """A joint_states message (in arm order); ``stamp`` is its header time."""
        events = []
        self.measured_q = np.asarray(q, float)
        self.measured_qd = None if qd is None else np.asarray(qd, float)
        self.measured_time = now
        if self.mode == 'waiting':
            self._hold_at(self.measured_q, now)
            self.mode = 'holding'
            events.append(Event('OK', 'feedback received: holding the measured position '
                                      f'{self.measured_q.round(4).tolist()}',
                                {'positions': self.measured_q.round(5).tolist()}))
        elif not self.feedback_ok:
            # The arm may have been moved, or its driver restarted elsewhere, while the feedback
            # was gone: hold where it is now, never drive it back to the old reference.
            self._hold_at(self.measured_q, now)
            self._last_command = None
            self.mode = 'holding'
            events.append(Event('OK', 'feedback restored: holding the measured position '
                                      f'{self.measured_q.round(4).tolist()}; send a new trajectory to move'))
        self.feedback_ok = True
        if self.mode == 'moving':
            events += self._check_tracking(stamp if stamp > 0 else now, now)
        return events

    def _check_tracking(self, t_meas, now):
        if t_meas < self._stalled_until:
            # Measured while this loop stood still (a process stalled as a whole catches up with states
            # stamped in the past): the reference of that time was rewritten by the stall's delay, so
            # there is nothing to compare with. The next measurement is checked.
            return []
        ref_q = self.traj.sample(t_meas - self.t0)[0][0]
        err = self.measured_q - ref_q
        np.maximum(self.max_error, np.abs(err), out=self.max_error)
        bad = np.abs(err) > self.tol.path
        if bad.any():
            j = int(np.argmax(np.abs(err)))
            self._stop(now)
            self.mode = 'fault'
            return [Event('ERROR', f'path tolerance violated: {self.names[j]} is {err[j]:+.4f} rad from the '
                                   f'reference (tolerance {self.tol.path}); holding',
                          {'joint': self.names[j], 'error': float(err[j])})]
        end = self.t0 + self.traj.duration
        if now >= end:
            goal_q = self.traj.end_state()[0]
            off = np.abs(self.measured_q - goal_q)
            still = self.measured_qd is None or np.all(np.abs(self.measured_qd) <= self.tol.stopped_velocity)
            if np.all(off <= self.tol.goal) and still:
                self.mode = 'holding'
                return [Event('OK', 'goal reached', {
                    'final_error': float(off.max()), 'max_tracking_error': float(self.max_error.max()),
                    'duration': self.traj.duration})]
            if now > end + self.tol.goal_time:
                j = int(np.argmax(off))
                self._stop(now)
                self.mode = 'fault'
                return [Event('ERROR', f'goal tolerance violated: {self.names[j]} is {off[j]:.4f} rad from the '
                                       f'goal {self.tol.goal_time} s after the end (tolerance {self.tol.goal}); '
                                       'holding', {'joint': self.names[j], 'error': float(off[j])})]
        return []

    # -- the reference ------------------------------------------------------------
    def advance(self, now):
        """Start a tick at ``now``, before its feedback and command; returns events.

        A tick that comes more than ``stall_limit`` after the previous one (the
        loop was stalled: no real-time guarantee here) delays the active and any
        scheduled trajectory by the excess. The reference then goes on from where
        the arm was last told to be, instead of jumping ahead by the stall (a
        drive extrapolates a late command for a short time, then holds: set
        ``stall_limit`` to the drive's command timeout). Reported at most once a second.
        """
        last, self._last_tick = self._last_tick, now
        if last is None or self.traj is None:
            return []
        excess = now - last - self.stall_limit
        if not excess > 0:
            return []
        self.t0 += excess
        self._stalled_until = now
        if self.next is not None:
            self.next = replace(self.next, t_splice=self.next.t_splice + excess)
        self.version += 1                # a trajectory prepared before the stall is prepared again
        if self.mode != 'moving':
            return []
        self.delayed += excess
        if now - self._stall_reported < 1.0:
            return []
        self._stall_reported = now
        return [Event('WARN', f'control loop stalled for {now - last:.3f} s: the trajectory goes on '
                              f'{excess:.3f} s later instead of jumping ahead',
                      {'stall': now - last, 'delay': excess, 'total_delay': self.delayed})]

    def reference(self, now):
        """``(q, qd, qdd)`` to command at ``now``, or None while waiting for feedback."""
        if self.next is not None and now >= self.next.t_splice:
            self._set(self.next.traj, self.next.t_splice, self.next.lead_in)
            self.mode = 'moving'
            self.max_error[:] = 0.0
        if self.traj is None:
            return None
        # A tick that read the clock just before a new trajectory was loaded gets the
        # trajectory's start state (with its velocity), not the "before the start" hold.
        return self.traj.state_at(max(now - self.t0, self.traj.start_time))

    def command(self, now):
        """What to send at ``now``: the reference held to the joint limits, and events.

        Positions stay within [lower, upper], velocities and accelerations within
        their limits, and the position within ``max_velocity`` times the time since
        the last command of that command (no step). The reference is built to keep
        them; should it not (a bug, a limit changed), the command is limited and
        reported once per trajectory. Returns ``(q, qd, qdd), events`` or ``None, []``
        while waiting for feedback.
        """
        ref = self.reference(now)
        if ref is None:
            return None, []
        q, qd, qdd = ref
        # (The ufuncs themselves: np.clip and np.array_equal cost several times as much per call
        # on arrays this small, at every tick.)
        out_q = np.minimum(np.maximum(q, self.lower), self.upper)
        last = self._last_command
        if last is not None and now > last[1]:
            reach = self.max_velocity * (now - last[1]) * 1.01 + 1e-9
            np.minimum(np.maximum(out_q, last[0] - reach, out=out_q), last[0] + reach, out=out_q)
        out_qd = np.minimum(np.maximum(qd, -self.max_velocity), self.max_velocity)
        out_qdd = np.minimum(np.maximum(qdd, -self.max_acceleration), self.max_acceleration)
        self._last_command = (out_q, now)
        events = []
        if not ((out_q == q).all() and (out_qd == qd).all() and (out_qdd == qdd).all()):
            self.limited += 1
            if self._limited_version != self.version:
                self._limited_version = self.version
                events.append(self._limited_event(q, qd, qdd, out_q, out_qd, out_qdd, now))
        return (out_q, out_qd, out_qdd), events

    def _limited_event(self, q, qd, qdd, out_q, out_qd, out_qdd, now):
        """The WARN for a limited command: which joint, which limit, and the likely cause."""
        j = int(np.argmax(np.abs(out_q - q) + np.abs(out_qd - qd) + np.abs(out_qdd - qdd)))
        name = self.names[j]
        if out_q[j] != q[j] and self.lower[j] <= q[j] <= self.upper[j]:
            what = (f'its position {q[j]:.4g} jumps from the last command faster than the velocity limit '
                    f'{self.max_velocity[j]:.4g} allows')
        elif out_q[j] != q[j]:
            what = f'its position {q[j]:.4g} is beyond [{self.lower[j]:.4g}, {self.upper[j]:.4g}]'
        elif out_qd[j] != qd[j]:
            what = f'its velocity {qd[j]:.4g} is beyond the limit {self.max_velocity[j]:.4g}'
        elif now < self.lead_in_end:
            what = (f'its acceleration {qdd[j]:.4g} is beyond the limit {self.max_acceleration[j]:.4g} '
                    f'(in the {self.lead_in_end - self.t0:.3f} s lead-in from the reference to the trajectory\'s '
                    'first point run: give that point more time from the reference, with a later time_from_start or '
                    f'header.stamp; points due within {MIN_LEAD * 1e3:.0f} ms are replaced by the lead-in)')
        else:
            # Accelerations are checked at the points, not between them: a quintic through points
            # whose acceleration steps between them (cubic and LSPB plans) overshoots there.
            what = (f'its acceleration {qdd[j]:.4g} is beyond the limit {self.max_acceleration[j]:.4g} '
                    '(between the points: the spline through them overshoots where the planned acceleration '
                    'steps, as in cubic and LSPB moves, or turns sharply within a sample period; jerk-limited '
                    'plans sampled finely enough do not)')
        return Event('WARN', f'command limited: the reference of {name}: {what}; sent within the limits '
                             '(reported once per trajectory)',
                     {'joint': name, 'position': float(q[j]), 'velocity': float(qd[j]),
                      'acceleration': float(qdd[j]), 'limited_ticks': self.limited})

    def tick(self, now):
        """The watchdog; returns events (feedback lost)."""
        if self.mode == 'waiting' or not self.feedback_ok:
            return []
        if now - self.measured_time > self.tol.state_timeout:
            self.feedback_ok = False
            was_moving = self.mode == 'moving'
            self._stop(now)
            self.mode = 'holding'
            return [Event('ERROR', f'feedback lost: no joint_states for {now - self.measured_time:.2f} s '
                                   f'(state_timeout {self.tol.state_timeout} s); '
                                   + ('trajectory aborted, ' if was_moving else '') + 'holding')]
        return []

    def _set(self, traj, t0, lead_in=0.0):
        """Make ``traj`` (its t = 0 at clock time ``t0``, its first ``lead_in`` s a lead-in
        from the reference) the active trajectory."""
        self.traj, self.t0 = traj, t0
        self.lead_in_end = t0 + lead_in
        self.next = None
        self.version += 1

    def _hold_at(self, q, now):
        self._set(hold(q, 1.0), now)

    def _stop(self, now):
        """Brake the reference to rest, within the acceleration limits, then hold."""
        self._set(brake(*self.reference(now), self.max_acceleration), now)

    # -- new trajectories -------------------------------------------------------------
    def load(self, joint_names, times, positions, velocities, accelerations, start, now):
        """Validate and start a trajectory now; returns an Event (accepted or rejected).

        :meth:`prepare` then :meth:`commit` at the same time: what a node does in
        two steps, so that its control loop never waits for the validation.
        """
        try:
            prepared = self.prepare(joint_names, times, positions, velocities, accelerations, start, now)
        except ValueError as exc:
            return self.rejected(exc)
        return self.commit(prepared, now)

    @staticmethod
    def rejected(exc, **values):
        """The ERROR event for a trajectory refused with ``exc``; ``late`` says whether it only came
        too late (a :class:`LateTrajectory`), so that its sender can tell a stale plan from a bad one."""
        return Event('ERROR', f'trajectory rejected: {exc}; the arm keeps its current reference',
                     {**values, 'late': isinstance(exc, LateTrajectory)})

    def commit(self, prepared, now):
        """Schedule a prepared trajectory to take over at its splice time.

        Returns its Event, or None when the active trajectory changed since it was
        prepared (a fault braked, feedback came) or its splice time has passed:
        prepare it again.
        """
        if prepared.version != self.version or now > prepared.t_splice:
            return None
        if now == prepared.t_splice:
            self._set(prepared.traj, prepared.t_splice, prepared.lead_in)
            self.mode = 'moving'
            self.max_error[:] = 0.0
        else:
            self.next = prepared
            self.version += 1
        return prepared.accepted

    def prepare(self, joint_names, times, positions, velocities, accelerations, start, now, splice_delay=0.0):
        """Validate a trajectory and splice it onto the reference at ``now + splice_delay``.

        Reads the controller's state but changes nothing, so a node can run it
        outside the lock its control loop takes; :meth:`commit` then schedules
        the result. Raises ValueError with the reason for refusing it.

        Parameters
        ----------
        joint_names : sequence of str
            The message's joint order.
        times : array_like, shape (m,)
            ``time_from_start`` of the points, s.
        positions, velocities, accelerations : array_like, shape (m, k)
            Empty velocities/accelerations mean "not given".
        start : float
            Clock time of the trajectory's start (header.stamp; 0 means the splice time).
        now : float
        splice_delay : float
            The new trajectory takes over this long after ``now``, s: time for the
            caller to finish before the switch (the old one runs until then).
        """
        version = self.version
        now = now + splice_delay                 # everything below happens at the splice time
        if self.mode == 'waiting':
            raise ValueError('no joint_states received yet: the controller does not know where the arm is')
        if not self.feedback_ok:
            raise ValueError('feedback lost: no joint_states; refusing to move blind')
        order = self._order(joint_names)
        ref = self._commanded(*self._reference_at(now))
        held = ref[0]
        times = np.asarray(times, float)
        m = times.size
        pos = self._block(positions, m, len(joint_names), order, 'positions', held=held)
        vel = self._block(velocities, m, len(joint_names), order, 'velocities', optional=True)
        acc = self._block(accelerations, m, len(joint_names), order, 'accelerations', optional=True)
        offset = (start - now) if start > 0 else 0.0
        rel = times + offset
        if m and rel[-1] <= MIN_LEAD:
            raise LateTrajectory('the trajectory ends in the past (or within 20 ms)')
        self._check_limits(pos, vel, acc, times=rel)
        # Points due within the lead are dropped and replaced by a lead-in from the current
        # reference: MIN_LEAD at first; a late trajectory whose lead-in would break a limit
        # catches up over a longer one (as long as the plan expects the arm near its reference).
        traj = error = None
        for lead in LEADS:
            if rel[-1] <= lead:
                break
            keep = rel > lead
            if not keep.all():
                # The last dropped point is where the plan expects the arm at the end of the lead.
                due = rel[~keep][-1]
                gap = np.abs(pos[~keep][-1] - held).max()
                if gap > self.tol.path:
                    error = error or LateTrajectory(
                        f'its point due at {due:+.3f} s lies {gap:.4f} rad from the current '
                        f'reference (it runs from {rel[0]:+.3f} s to {rel[-1]:+.3f} s from now); give the first '
                        'point a later time_from_start to move there smoothly')
                    break
            checking = False
            try:
                traj = from_points(rel[keep], pos[keep], None if vel is None else vel[keep],
                                   None if acc is None else acc[keep], start=ref)
                checking = True
                self._check_spline(traj)
                break
            except ValueError as exc:
                traj = None
                if keep.all():
                    # Not late. Planned from another reference (the sender's view of a plan this
                    # controller did not run, say), it may only be the lead-in that breaks a limit:
                    # stale, its sender may plan it again; else the trajectory itself is at fault.
                    error = exc
                    if checking and self._starts_elsewhere(now + rel[0], pos[0], None if vel is None else vel[0]):
                        error = LateTrajectory(f'{exc} (its first point is not where the current reference '
                                               'will be: planned from another reference?)')
                    break
                error = LateTrajectory(str(exc))
        if traj is None:
            raise error
        return Prepared(traj, now, version, Event('OK', 'trajectory accepted', {
            'points': m, 'duration': float(traj.duration), 'starts_in': float(max(offset, 0.0))}),
            lead_in=float(rel[keep][0]))

    def _starts_elsewhere(self, t, q, qd, tol=1e-6):
        """True when the reference at clock time ``t`` is not at ``q`` (moving at ``qd``, if given)."""
        ref_q, ref_qd, _ = self._commanded(*self._reference_at(t))
        return bool(np.abs(ref_q - q).max() > tol or (qd is not None and np.abs(ref_qd - qd).max() > tol))

    def _commanded(self, q, qd, qdd):
        """A reference state held within the limits, as :meth:`command` sends it: what a new
        trajectory is spliced onto. (A reference beyond a limit, led in too hard before, would
        make every lead-in from it break the limit at once: the arm could take no new trajectory.)
        A joint at a position limit stops there; one at its speed limit stops accelerating past it."""
        return held_within_limits(q, qd, qdd, self.lower, self.upper, self.max_velocity, self.max_acceleration)

    def _reference_at(self, t):
        """The reference at clock time ``t`` as things stand (a scheduled trajectory
        included), without switching to it."""
        traj, t0 = (self.next.traj, self.next.t_splice) if self.next and t >= self.next.t_splice \
            else (self.traj, self.t0)
        return traj.state_at(max(t - t0, traj.start_time))

    def _order(self, joint_names):
        names = list(joint_names)
        if len(set(names)) != len(names):
            raise ValueError(f'joint names repeat: {names}')
        unknown = [n for n in names if n not in self.names]
        missing = [n for n in self.names if n not in names and n not in self.optional]
        if unknown:
            raise ValueError(f'unknown joints {unknown} (this arm has {self.names})')
        if missing:
            raise ValueError(f'missing joints {missing}')
        return [names.index(n) if n in names else -1 for n in self.names]

    def _block(self, values, m, k, order, what, optional=False, held=None):
        if isinstance(values, np.ndarray) and values.ndim == 2:      # one row per point, already
            if optional and values.size == 0:
                return None
            if m == 0:
                raise ValueError('no points')
            if values.shape != (m, k):
                raise ValueError(f'every point needs {k} {what} (one per joint name)')
            given = values.astype(float)
        else:
            rows = [np.asarray(v, float) for v in values]
            if optional and all(r.size == 0 for r in rows):
                return None
            if m == 0:
                raise ValueError('no points')
            if len(rows) != m or any(r.shape != (k,) for r in rows):
                raise ValueError(f'every point needs {k} {what} (one per joint name)')
            given = np.array(rows)
        if not np.all(np.isfinite(given)):
            raise ValueError(f'{what} must be finite')
        arr = given[:, np.maximum(order, 0)]
        left_out = np.array(order) < 0
        if left_out.any():
            # Joints the trajectory leaves out hold where their reference is.
            arr[:, left_out] = held[left_out] if what == 'positions' else 0.0
        return arr

    def _check_limits(self, pos, vel, acc, slack=1e-6, times=None, spline=False):
        """ValueError naming the first point (or, ``spline``, the time on the spline) beyond a limit."""
        for what, arr, lo, hi in (('position', pos, self.lower, self.upper),
                                  ('velocity', vel, -self.max_velocity, self.max_velocity),
                                  ('acceleration', acc, -self.max_acceleration, self.max_acceleration)):
            if arr is None:
                continue
            bad = (arr < lo - slack) | (arr > hi + slack)
            if bad.any():
                i, j = np.argwhere(bad)[0]
                where = (f'between the points, {times[i]:+.3f} s after the splice (the spline from the current '
                         'reference through them)' if spline else f'point {i}')
                raise ValueError(f'{where}: {self.names[j]} {what} {arr[i, j]:.4g} is beyond its limit '
                                 f'[{lo[j]:.4g}, {hi[j]:.4g}]'
                                 + (f' at {times[i]:+.3f} s from now' if times is not None and not spline else ''))

    def _check_spline(self, traj):
        """The spline between the points must respect the position and velocity limits too."""
        t = np.union1d(np.linspace(0.0, traj.duration, max(50, 4 * len(traj.breaks))), traj.breaks - traj.start_time)
        q, qd, _ = traj.sample(t)
        self._check_limits(q, qd, None, slack=1e-3, times=t, spline=True)
