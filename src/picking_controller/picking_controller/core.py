"""The trajectory controller's logic, with no ROS in it.

:class:`ControllerCore` owns the arm's future: the schedule of trajectories it runs
(:mod:`.schedule`), each spliced on at its stamp (:mod:`.splicing`), the reference it commands at
every tick held within the limits (:mod:`.limiting`), the tracking of the measured state against the
command of the same instant (:mod:`.monitoring`), and the goals of the FollowJointTrajectory action
(:mod:`.goals`). The node feeds it messages and the clock and publishes what it returns.

Times: ``now`` is the controller's clock (s). The schedule runs on its own clock, ``now`` less the
delay that stalls of the control loop added to the motion under way: a tick that comes late delays
the schedule by the excess instead of making the reference jump ahead, and stamps name schedule
times. While the arm holds with nothing scheduled the two clocks agree again.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from picking_core.trajectory import brake, hold

from .events import Event, LateTrajectory, Mode, Tolerances
from .goals import ErrorCode, JointTolerances, Outcome
from .gripper import GripperChannel
from .limiting import CommandGuard
from .monitoring import LATE_FEEDBACK, Tracker
from .schedule import Entry, Schedule
from .splicing import Splicer, accepted
from .validation import Limits, Validator

#: s a hold entry lasts (the arm then rests at its end: the schedule is idle).
HOLD = 0.01

__all__ = ['ControllerCore', 'ErrorCode', 'Event', 'JointTolerances', 'LateTrajectory', 'Mode', 'Outcome', 'Points',
           'Prepared',
           'Tolerances']


@dataclass(frozen=True)
class Points:
    """A trajectory as a message gives it: ``names``, ``times`` (s from its stamp), ``positions``,
    ``velocities`` and ``accelerations`` (one row per point; empty: not given), ``start`` (its header stamp,
    schedule time s; 0: now)."""

    names: tuple
    times: np.ndarray
    positions: object
    velocities: object
    accelerations: object
    start: float = 0.0


@dataclass(frozen=True)
class Prepared:
    """A trajectory checked and made into a schedule entry, for :meth:`ControllerCore.commit`."""

    entry: Entry
    version: int
    accepted: Event


class ControllerCore:
    """Reference generation and supervision for one arm.

    Parameters
    ----------
    names : sequence of str
        The arm's joints, in command order.
    lower, upper, max_velocity, max_acceleration : array_like
        Limits per joint (inf where none); ``max_jerk`` likewise (the bridges keep it).
    tolerances : Tolerances
    optional : sequence of str
        Joints a trajectory may leave out (a gripper): they hold their reference.
    stall_limit : float
        s: ticks farther apart than this (a stalled loop) delay the schedule by the excess.
    """

    def __init__(self, names, lower, upper, max_velocity, max_acceleration, tolerances=Tolerances(),
                 optional=(), stall_limit=0.05, max_jerk=None, gripper=None):
        self.limits = Limits.of(names, lower, upper, max_velocity, max_acceleration, max_jerk, optional)
        self.names = list(names)
        # The gripper's own channel (a GripperCommand action drives it), when the arm has one.
        self.gripper = None if gripper is None else GripperChannel(
            self.names.index(gripper), self.limits.lower[self.names.index(gripper)],
            self.limits.upper[self.names.index(gripper)], self.limits.max_velocity[self.names.index(gripper)],
            self.limits.max_acceleration[self.names.index(gripper)])
        self.splicer = Splicer(self.limits, Validator(self.limits))
        self.guard = CommandGuard(self.limits)
        self.schedule = Schedule()
        self.mode = Mode.WAITING         # waiting -> holding <-> moving; fault on a violation
        self.canceling = False           # the running goal was canceled: the reference brakes to rest
        self.version = 0                 # counts changes of the schedule
        self.delay = 0.0                 # s the schedule runs behind the clock (stalls of the motion under way)
        self.delayed = 0.0               # s of stalls in all, for the reports
        self._last_tick = None
        self._stalled_until = -np.inf    # clock time the last stall ended
        self._stall_reported = self._late_reported = -np.inf
        self._pending = []               # events raised while switching entries, sent with the next command
        self._active = None              # the entry that ran at the last look
        self.set_tolerances(tolerances, stall_limit)
        self.tracker = Tracker(self.limits.n, self.stall_limit)

    def set_tolerances(self, tolerances, stall_limit):
        """New default tolerances and stall limit, for the trajectories that start from now on (a running one
        keeps its own; the watchdog's ``state_timeout`` applies at once)."""
        if not stall_limit > 0:
            raise ValueError(f'stall_limit must be > 0 s, got {stall_limit}')
        self.tol = tolerances
        self.default_tolerances = JointTolerances.default(tolerances, self.limits.n)
        self.stall_limit = float(stall_limit)
        if hasattr(self, 'tracker'):
            self.tracker.history.gap = self.stall_limit

    # -- what runs -----------------------------------------------------------------------
    @property
    def goal(self):
        """The action goal whose trajectory runs now (None: none, or a topic's trajectory)."""
        active = self.schedule.active
        return None if active is None or self.mode != Mode.MOVING else active.goal

    @property
    def feedback_ok(self):
        return self.tracker.ok

    @property
    def active_tolerances(self):
        active = self.schedule.active
        return (active.tolerances if active is not None and active.tolerances is not None
                else self.default_tolerances)

    def schedule_time(self, now):
        """The schedule's clock at clock time ``now``, s."""
        return now - self.delay

    def reference(self, now):
        """``(q, qd, qdd)`` of the schedule at clock time ``now``, or None before any feedback."""
        t = now - self.delay
        if len(self.schedule.entries) > 1:
            self._take_over(t)
        return self.schedule.state_at(t)

    def trajectory_time(self, now, goal=None):
        """The ``time_from_start`` of the reference at ``now`` in the running trajectory's own points (its stamp
        and any bridge before them taken off, on the schedule's clock): where a sender's plan is; negative before
        them (a goal's trajectory ``goal`` waiting on the schedule for its start, or its bridge running). None
        while no client's trajectory runs (holding, braking), or ``goal`` has none on the schedule."""
        active = self.schedule.active
        entry = active if goal is None else next((e for e in self.schedule.entries if e.goal == goal), None)
        if entry is None or entry.kind != 'trajectory' or (entry is active and self.mode != Mode.MOVING):
            return None
        return (now - self.delay) - entry.origin

    def feedback(self, now):
        """``(reference (q, qd, qdd), measured q, measured qd or None)`` at ``now``, or None before any
        feedback: what an action goal's feedback reports."""
        if not self.schedule or self.tracker.q is None:
            return None
        return self.schedule.state_at(now - self.delay), self.tracker.q, self.tracker.qd

    def _take_over(self, t):
        """Entries that have reached their start take over; the goals they take over from end as preempted."""
        for entry in self.schedule.advance(t):
            by = self.schedule.active.goal
            self._preempt(entry, by, 'a newer trajectory took over from it'
                          + (f' (goal {by})' if by is not None else ' (from the joint_trajectory topic)'))
        active = self.schedule.active
        if active is self._active:
            return
        self._active = active
        self.canceling = active.kind == 'brake' and self.canceling
        if active.kind != 'hold':
            self.mode = Mode.MOVING
            self.tracker.reset()

    def _preempt(self, entry, by, why):
        if entry.goal is not None and entry.goal != by:
            self._pending.append(Event('WARN', f'goal preempted: {why}', goal=entry.goal, outcome=Outcome(
                'aborted', ErrorCode.INVALID_GOAL, f'preempted: {why}')))

    # -- new trajectories ------------------------------------------------------------------
    def prepare(self, joint_names, times, positions, velocities, accelerations, start, now, splice_delay=0.0,
                goal=None, tolerances=None):
        """Check a trajectory and make it a schedule entry spliced at its stamp ``start`` (schedule time; 0: at
        ``now + splice_delay``). Reads the controller's state but changes nothing, so that a node can run it
        outside the lock its control loop takes; :meth:`commit` then puts it on. Raises ValueError with the
        reason for refusing it (:class:`LateTrajectory` for a start already past)."""
        if self.mode == Mode.WAITING:
            raise ValueError('no joint_states received yet: the controller does not know where the arm is')
        if not self.tracker.ok:
            raise ValueError('feedback lost: no joint_states; refusing to move blind')
        message = Points(tuple(joint_names), np.asarray(times, float), positions, velocities, accelerations,
                         float(start))
        t_now = now - self.delay + splice_delay
        entry, words = self.splicer.entry(self.schedule, message, t_now, goal, tolerances)
        return Prepared(entry, self.version, accepted(entry, message.times.size, words, t_now))

    def commit(self, prepared, now):
        """Put a prepared trajectory on the schedule; returns its Event, or None when the schedule changed
        since it was prepared or its start has passed (prepare it again)."""
        entry = prepared.entry
        if prepared.version != self.version or now - self.delay > (entry.start if entry.cut is None else entry.cut):
            return None
        t = now - self.delay
        for dropped in self.schedule.splice(entry):
            self._preempt(dropped, entry.goal, 'a newer trajectory took over from it' if dropped.start <= t else
                          'a newer trajectory replaced it before it started')
        self.version += 1
        if self.mode == Mode.FAULT:
            self.mode = Mode.HOLDING
        self._take_over(t)
        return prepared.accepted

    def load(self, joint_names, times, positions, velocities, accelerations, start, now, goal=None,
             tolerances=None):
        """:meth:`prepare` then :meth:`commit` at the same time; returns an Event (accepted or rejected)."""
        try:
            prepared = self.prepare(joint_names, times, positions, velocities, accelerations, start, now,
                                    goal=goal, tolerances=tolerances)
        except ValueError as exc:
            return self.rejected(exc, goal=goal)
        return self.commit(prepared, now)

    @staticmethod
    def rejected(exc, goal=None, **values):
        """The ERROR event for a trajectory refused with ``exc``; ``late`` says whether it only came too late
        (code OLD_HEADER_TIMESTAMP), so that its sender can tell a stale plan from a bad one."""
        return Event('ERROR', f'trajectory rejected: {exc}; the arm keeps its current reference',
                     {**values, 'late': isinstance(exc, LateTrajectory)}, goal=goal, outcome=Outcome.refused(exc))

    def cancel(self, goal, now):
        """Cancel action goal ``goal``: ``(accepted, events)``.

        A goal waiting for its start ends at once (with it whatever was spliced after it); a running one
        brakes to rest within the acceleration limits and ends as canceled when the arm is still. A goal
        that already ended cannot be canceled."""
        t = now - self.delay
        waiting = next((e for e in self.schedule.waiting() if e.goal == goal), None) if goal is not None else None
        if waiting is not None:
            keep = [e for e in self.schedule.entries if e.start < waiting.start]
            dropped = self.schedule.entries[len(keep):]
            self.schedule.entries = keep
            self.version += 1
            for e in dropped[1:]:
                self._preempt(e, None, 'the trajectory it was spliced onto was canceled')
            return True, [Event('OK', 'goal canceled before its trajectory started', goal=goal,
                                outcome=Outcome('canceled', ErrorCode.SUCCESSFUL, 'canceled before it started'))]
        if goal is None or self.goal != goal:
            return False, []
        if not self.canceling:
            self._brake(t, goal, 'the goal it was spliced onto was canceled')
            self.canceling = True
        return True, [Event('OK', 'goal canceled: braking to rest within the limits',
                            {'stops_in': self.schedule.active.traj.duration})]

    def _brake(self, t, goal=None, why='the arm braked to rest'):
        """Brake the reference to rest within the acceleration limits, then hold; everything scheduled after is
        dropped (its goals preempted)."""
        state = self.limits.held(*self.schedule.state_at(t))
        entry = Entry(t, brake(*state, self.limits.max_acceleration), t, goal, kind='brake')
        for dropped in self.schedule.replace_all(entry):
            if dropped.goal != goal:
                self._preempt(dropped, None, why)
        self._active = entry
        self.version += 1

    def _hold_at(self, q, t):
        entry = Entry(t, hold(q, HOLD), t, kind='hold')
        for dropped in self.schedule.replace_all(entry):
            self._preempt(dropped, None, 'the arm is held where it was measured')
        self._active = entry
        self.version += 1
        self.guard.forget()

    # -- the clock ---------------------------------------------------------------------------
    def advance(self, now):
        """Start a tick at ``now``, before its feedback and command; returns events.

        A tick that comes more than ``stall_limit`` after the previous one (the loop stalled: no real-time
        guarantee here) delays the schedule by the excess: the reference goes on from where the arm was last
        told to be instead of jumping ahead (a drive extrapolates a late command briefly, then holds: set
        ``stall_limit`` to the drive's command timeout). Reported at most once a second. While the arm holds
        with nothing scheduled, the delay is dropped (the schedule's clock is the clock again)."""
        last, self._last_tick = self._last_tick, now
        if not self.schedule:
            return []
        if self.mode != Mode.MOVING and now - self.delay >= self.schedule.end:
            self.delay = 0.0
        if last is None:
            return []
        excess = now - last - self.stall_limit
        if not excess > 0 or self.mode != Mode.MOVING:
            return []
        self.delay += excess
        self.delayed += excess
        self._stalled_until = now
        if now - self._stall_reported < 1.0:
            return []
        self._stall_reported = now
        return [Event('WARN', f'control loop stalled for {now - last:.3f} s: the schedule goes on {excess:.3f} s '
                              'later instead of jumping ahead', {'stall': now - last, 'delay': excess,
                                                                 'total_delay': self.delay})]

    def tick(self, now):
        """The watchdog; returns events (feedback lost)."""
        if self.mode == Mode.WAITING or not self.tracker.silent(now, self._stalled_until, self.tol.state_timeout):
            return []
        self.tracker.ok = False
        was_moving = self.mode == Mode.MOVING
        goal = self.goal
        self._brake(now - self.delay, None, 'feedback lost')
        self.mode = Mode.HOLDING
        text = (f'feedback lost: no joint_states for {now - self.tracker.received:.2f} s '
                f'(state_timeout {self.tol.state_timeout} s)')
        # No code names this: the path can no longer be checked.
        return [Event('ERROR', text + '; ' + ('trajectory aborted, ' if was_moving else '') + 'holding', goal=goal,
                      outcome=Outcome('aborted', ErrorCode.PATH_TOLERANCE_VIOLATED, text))]

    def command(self, now):
        """What to send at ``now``: ``((q, qd, qdd), events)``, the reference held within the limits (see
        :class:`~.limiting.CommandGuard`), or ``(None, events)`` before any feedback."""
        ref = self.reference(now)
        events, self._pending = self._pending, []
        if ref is None:
            return None, events
        finger = self.gripper.reference(now) if self.gripper is not None else None
        if finger is not None:
            ref = tuple(np.array(x, float) for x in ref)
            for x, value in zip(ref, finger):
                x[self.gripper.index] = value
        out, limited = self.guard.hold(ref, now, self.schedule.active)
        self.tracker.history.record(now, out[0], out[1])
        return out, events + limited

    # -- the gripper on its own action ------------------------------------------------------------
    def command_gripper(self, target, now):
        """A GripperCommand to ``target``: the gripper's reference moves there from where it is commanded now
        (ValueError: beyond its limits, or no gripper)."""
        if self.gripper is None:
            raise ValueError('this arm has no gripper joint')
        finger = self.gripper.reference(now)
        ref = self.reference(now) if finger is None else None
        current = finger[0] if finger is not None else (
            float(ref[0][self.gripper.index]) if ref is not None else float(self.tracker.q[self.gripper.index]))
        self.gripper.command(target, now, current)

    def measured_gripper(self):
        """The gripper's newest measured opening, or None."""
        q = self.tracker.q
        return None if q is None or self.gripper is None else float(q[self.gripper.index])

    # -- the measured state ------------------------------------------------------------------
    def on_state(self, q, qd, stamp, now):
        """A joint_states message (arm order); ``stamp`` is its header time (clock s). Returns events."""
        tracker, t = self.tracker, now - self.delay
        restored = self.mode != Mode.WAITING and not tracker.ok
        tracker.measure(q, qd, stamp, now)
        events = []
        if self.mode == Mode.WAITING or restored:
            # The arm may have been moved, or its driver restarted elsewhere, while the feedback was gone:
            # hold where it is now, never drive it back to the old reference.
            self._hold_at(tracker.q, t)
            words = 'feedback received' if self.mode == Mode.WAITING else 'feedback restored'
            self.mode = Mode.HOLDING
            events.append(Event('OK', f'{words}: holding the measured position {tracker.q.round(4).tolist()}'
                                + ('' if words == 'feedback received' else '; send a new trajectory to move'),
                                {'positions': tracker.q.round(5).tolist()}))
        tracker.ok = True
        if tracker.late > LATE_FEEDBACK and now - self._late_reported > 1.0:
            self._late_reported = now
            events.append(Event('WARN', f'joint_states arrive late: {tracker.late:.3f} s after their stamp (judged '
                                        'against the command of their stamp\'s instant)', {'feedback_age': tracker.late}))
        if self.mode == Mode.MOVING:
            events += self._check_tracking(now)
        return events

    def _check_tracking(self, now):
        tol = self.active_tolerances
        found = self.tracker.path_violation(tol)
        if found is not None:
            return [self._fault(found, ErrorCode.PATH_TOLERANCE_VIOLATED, now)]
        t, schedule = now - self.delay, self.schedule
        if len(schedule.entries) > 1 or t < schedule.end:
            return []
        goal_q = schedule.active.traj.end_state()[0]
        if self.tracker.at_goal(goal_q, tol):
            self.mode = Mode.HOLDING
            values = {'final_error': float(np.abs(self.tracker.q - goal_q).max()),
                      'max_tracking_error': float(self.tracker.max_error.max()),
                      'duration': schedule.active.traj.duration}
            goal, canceling = schedule.active.goal, self.canceling
            self.canceling = False
            self._active = schedule.entries[0] = replace(schedule.active, goal=None)     # it has ended
            if canceling:
                return [Event('OK', 'goal canceled: the arm is at rest', values, goal=goal, outcome=Outcome(
                    'canceled', ErrorCode.SUCCESSFUL, 'braked to rest within the limits'))]
            if schedule.active.kind != 'trajectory':
                return []
            return [Event('OK', 'goal reached', values, goal=goal, outcome=Outcome('succeeded', ErrorCode.SUCCESSFUL, ''))]
        if t > schedule.end + tol.goal_time:
            return [self._fault(self.tracker.goal_violation(goal_q, tol), ErrorCode.GOAL_TOLERANCE_VIOLATED, now)]
        return []

    def _fault(self, found, code, now):
        """Brake, hold, and end the running goal with ``code``: the joint farthest beyond its tolerance."""
        goal = self.goal
        self._brake(now - self.delay, None, f'{found.what} tolerance violated')
        self.mode, self.canceling = Mode.FAULT, False
        unit = 'rad/s' if 'velocity' in found.what else 'rad'
        name = self.names[found.joint]
        text = (f'{found.what} tolerance violated: {name} is {found.off:+.4f} {unit} {found.where} '
                f'(tolerance {found.limit:g} {unit})')
        return Event('ERROR', text + '; holding', {'joint': name, 'error': found.off}, goal=goal,
                     outcome=Outcome('aborted', code, text))
