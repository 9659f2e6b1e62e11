"""New trajectories: validated, led into from the current reference without a jump, and scheduled
to take over (part of :class:`~picking_controller.core.ControllerCore`)."""

from __future__ import annotations

import numpy as np

from picking_core.trajectory import brake, held_within_limits, hold

from .events import LEADS, MIN_LEAD, Event, LateTrajectory, Mode, Prepared
from .goals import ErrorCode, Outcome
from .sampler import from_points

#: s: how well a trajectory's stamp places its first point in time (a float of the epoch's seconds
#: resolves a quarter of a microsecond; the stamp and the point's time_from_start are each rounded).
STAMP_RESOLUTION = 1e-6


class Splicing:
    """The active trajectory, the one waiting for its splice time, and how a new one takes over."""

    def reference(self, now):
        """``(q, qd, qdd)`` to command at ``now``, or None while waiting for feedback."""
        if self.next is not None and now >= self.next.t_splice:
            self._take_over(self.next)
        if self.traj is None:
            return None
        # A tick that read the clock just before a new trajectory was loaded gets the
        # trajectory's start state (with its velocity), not the "before the start" hold.
        return self.traj.state_at(max(now - self.t0, self.traj.start_time))

    def _set(self, traj, t0, lead_in=0.0, origin=None):
        """Make ``traj`` (its t = 0 at clock time ``t0``, its first ``lead_in`` s a lead-in
        from the reference, its message's time_from_start 0 at ``origin``, default ``t0``)
        the active trajectory."""
        self.traj, self.t0 = traj, t0
        self.origin = t0 if origin is None else origin
        self.lead_in_end = t0 + lead_in
        self.next = None
        self.version += 1

    def _take_over(self, prepared):
        """Run a prepared trajectory from its splice time; the goal it replaces ends as preempted."""
        self._preempt(self.goal, prepared.goal)
        self._set(prepared.traj, prepared.t_splice, prepared.lead_in, prepared.origin)
        self.goal, self.canceling = prepared.goal, False
        self.active_tolerances = prepared.tolerances or self.default_tolerances
        self.mode = Mode.MOVING
        self.max_error[:] = 0.0

    def _preempt(self, goal, by):
        if goal is not None and goal != by:
            self._pending.append(Event('WARN', 'goal preempted by a newer trajectory', goal=goal, outcome=Outcome(
                'aborted', ErrorCode.INVALID_GOAL, 'preempted: a newer trajectory took over from this one'
                + (f' (goal {by})' if by is not None else ' (from the joint_trajectory topic)'))))

    def end_goal(self, level, message, outcome, values=None):
        """The event that ends the running goal (if any) with ``outcome``."""
        event = Event(level, message, values or {}, goal=self.goal, outcome=outcome)
        self.goal, self.canceling = None, False
        return event

    def cancel(self, goal, now):
        """Cancel action goal ``goal``: ``(accepted, events)``.

        A goal whose trajectory is still waiting for its splice time ends at once; a running one
        brakes to rest within the acceleration limits and ends as canceled when the arm is
        still (see the monitoring part). A goal that already ended cannot be canceled.
        """
        if self.next is not None and self.next.goal == goal:
            self.next = None
            self.version += 1
            return True, [Event('OK', 'goal canceled before its trajectory started', goal=goal,
                                outcome=Outcome('canceled', ErrorCode.SUCCESSFUL, 'canceled before it started'))]
        if goal is None or self.goal != goal or self.mode != Mode.MOVING:
            return False, []
        if not self.canceling:
            self._stop(now)
            self.canceling = True
        return True, [Event('OK', 'goal canceled: braking to rest within the limits', {'stops_in': self.traj.duration})]

    def _hold_at(self, q, now):
        self._set(hold(q, 1.0), now)

    def _stop(self, now):
        """Brake the reference to rest, within the acceleration limits, then hold."""
        self._set(brake(*self.reference(now), self.max_acceleration), now)

    # -- new trajectories -------------------------------------------------------------
    def load(self, joint_names, times, positions, velocities, accelerations, start, now, goal=None,
             tolerances=None):
        """Validate and start a trajectory now; returns an Event (accepted or rejected).

        :meth:`prepare` then :meth:`commit` at the same time: what a node does in
        two steps, so that its control loop never waits for the validation.
        """
        try:
            prepared = self.prepare(joint_names, times, positions, velocities, accelerations, start, now,
                                    goal=goal, tolerances=tolerances)
        except ValueError as exc:
            return self.rejected(exc, goal=goal)
        return self.commit(prepared, now)

    @staticmethod
    def rejected(exc, goal=None, **values):
        """The ERROR event for a trajectory refused with ``exc``; ``late`` says whether it only came
        too late (a :class:`LateTrajectory`, code OLD_HEADER_TIMESTAMP), so that its sender can tell
        a stale plan from a bad one."""
        return Event('ERROR', f'trajectory rejected: {exc}; the arm keeps its current reference',
                     {**values, 'late': isinstance(exc, LateTrajectory)}, goal=goal, outcome=Outcome.refused(exc))

    def commit(self, prepared, now):
        """Schedule a prepared trajectory to take over at its splice time.

        Returns its Event, or None when the active trajectory changed since it was
        prepared (a fault braked, feedback came) or its splice time has passed:
        prepare it again.
        """
        if prepared.version != self.version or now > prepared.t_splice:
            return None
        if now == prepared.t_splice:
            self._take_over(prepared)
        else:
            if self.next is not None:
                self._preempt(self.next.goal, prepared.goal)
            self.next = prepared
            self.version += 1
        return prepared.accepted

    def prepare(self, joint_names, times, positions, velocities, accelerations, start, now, splice_delay=0.0,
                goal=None, tolerances=None):
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
        goal : hashable, optional
            The action goal it runs for: the events that end it carry it.
        tolerances : goals.JointTolerances, optional
            The goal's tolerances (default: the controller's).
        """
        version = self.version
        now = now + splice_delay                 # everything below happens at the splice time
        if self.mode == Mode.WAITING:
            raise ValueError('no joint_states received yet: the controller does not know where the arm is')
        if not self.feedback_ok:
            raise ValueError('feedback lost: no joint_states; refusing to move blind')
        order = self._order(joint_names)
        ref = self._commanded(*self._reference_at(now, scheduled=False))
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
        if self._carries_on(now, rel, pos, vel, acc):
            # It begins where the reference will be at its first point: the reference runs on
            # until then and the trajectory takes over there, exactly as planned (no lead-in).
            traj = from_points(rel - rel[0], pos, vel, acc)
            self._check_spline(traj)
            return Prepared(traj, now + float(rel[0]), version, Event('OK', 'trajectory accepted', {
                'points': m, 'duration': float(traj.duration), 'starts_in': float(rel[0]), 'caught_up': 0.0}),
                goal=goal, tolerances=tolerances, origin=now + offset)
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
                gaps = np.abs(pos[~keep][-1] - held)
                gap = gaps.max()
                if (gaps > (tolerances or self.default_tolerances).path).any():
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
                self._check_lead_in(traj, float(rel[keep][0]), ref)
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
            'points': m, 'duration': float(traj.duration), 'starts_in': float(max(offset, 0.0)),
            # How much of the trajectory a catch-up lead-in replaced (it came late), s.
            'caught_up': float(times[keep][0] - times[0])}),
            lead_in=float(rel[keep][0]), goal=goal, tolerances=tolerances, origin=now + offset)

    def _carries_on(self, now, rel, pos, vel, acc):
        """True when a trajectory's first point, due later than the shortest lead-in, is the state
        (position, velocity and acceleration) the active trajectory's reference will have then: at
        an instant within STAMP_RESOLUTION of its time (a ROS stamp in float seconds of the epoch
        knows it no better, and right after a break the reference's acceleration already moves at
        the jerk of the phase that begins there)."""
        if vel is None or acc is None or rel[0] <= MIN_LEAD:
            return False
        t = now + float(rel[0])
        states = [self._commanded(*self._reference_at(t + dt, scheduled=False))
                  for dt in (-STAMP_RESOLUTION, 0.0, STAMP_RESOLUTION)]
        for k, (x, tol) in enumerate(((pos[0], 1e-6), (vel[0], 1e-6),
                                      (acc[0], 1e-6 * (1.0 + np.abs(acc[0]).max())))):
            # Within how much the reference itself moves over that instant.
            at = states[1][k]
            spread = np.maximum(np.abs(states[0][k] - at), np.abs(states[2][k] - at))
            if (np.abs(x - at) > tol + spread).any():
                return False
        return True

    def _check_lead_in(self, traj, lead, ref):
        """The lead-in from the reference to the first point must keep the acceleration limits too:
        a lead-in that cannot is refused (a late one is tried longer, then refused as late), never
        limited after the fact."""
        t = np.linspace(traj.start_time, traj.start_time + lead, 17)
        qdd = traj.sample(t)[2]
        over = np.abs(qdd) > self.max_acceleration * (1 + 1e-3) + 1e-6
        if over.any():
            i, j = np.argwhere(over)[0]
            first = traj.state_at(traj.start_time + lead)
            raise ValueError(f'the {lead:.3f} s lead-in from the current reference to the first point needs '
                             f'{self.names[j]} acceleration {qdd[i, j]:.4g}, beyond its limit '
                             f'{self.max_acceleration[j]:.4g} (from {ref[0][j]:.4f} rad at {ref[1][j]:.4g} rad/s, '
                             f'{ref[2][j]:.4g} rad/s² to {first[0][j]:.4f} rad at {first[1][j]:.4g} rad/s, '
                             f'{first[2][j]:.4g} rad/s²): give the first point a later time_from_start')

    def _starts_elsewhere(self, t, q, qd, tol=1e-6):
        """True when the reference at clock time ``t`` is not at ``q`` (moving at ``qd``, if given)."""
        ref_q, ref_qd, _ = self._commanded(*self._reference_at(t, scheduled=False))
        return bool(np.abs(ref_q - q).max() > tol or (qd is not None and np.abs(ref_qd - qd).max() > tol))

    def _commanded(self, q, qd, qdd):
        """A reference state held within the limits, as :meth:`command` sends it: what a new
        trajectory is spliced onto. (A reference beyond a limit, led in too hard before, would
        make every lead-in from it break the limit at once: the arm could take no new trajectory.)
        A joint at a position limit stops there; one at its speed limit stops accelerating past it."""
        return held_within_limits(q, qd, qdd, self.lower, self.upper, self.max_velocity, self.max_acceleration)

    def trajectory_time(self, t):
        """The time_from_start, in the running trajectory's own points, of the reference at clock
        time ``t``: ``t`` less its header stamp and the delays stalls added since (see
        :meth:`advance`); a sender learns from it how late its plan runs. None while no
        trajectory's points run (holding, or braking after a fault or a cancel)."""
        if self.next and t >= self.next.t_splice:
            return t - self.next.origin
        return t - self.origin if self.mode == Mode.MOVING and not self.canceling else None

    def _reference_at(self, t, scheduled=True):
        """The reference at clock time ``t`` as things stand, without switching: with the trajectory
        scheduled to take over (``scheduled``), or of the active one alone. A new trajectory is spliced
        onto the active one: committed, it replaces the scheduled one, which then never runs (spliced
        onto that one, it took over with a jump from where the active one really was)."""
        traj, t0 = (self.next.traj, self.next.t_splice) if scheduled and self.next and t >= self.next.t_splice \
            else (self.traj, self.t0)
        return traj.state_at(max(t - t0, traj.start_time))
