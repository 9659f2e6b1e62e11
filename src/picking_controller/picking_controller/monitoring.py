"""Supervision of a running trajectory: feedback, tracking against the tolerances, stalls of the
control loop, and the feedback watchdog (part of :class:`~picking_controller.core.ControllerCore`)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .events import Event, Mode
from .goals import ErrorCode, Outcome


class Monitoring:
    """Feedback and tolerances; braking on a fault is the splicing part's."""

    def on_state(self, q, qd, stamp, now):
        """A joint_states message (in arm order); ``stamp`` is its header time."""
        events = []
        self.measured_q = np.asarray(q, float)
        self.measured_qd = None if qd is None else np.asarray(qd, float)
        self.measured_time = now
        if self.mode == Mode.WAITING:
            self._hold_at(self.measured_q, now)
            self.mode = Mode.HOLDING
            events.append(Event('OK', 'feedback received: holding the measured position '
                                      f'{self.measured_q.round(4).tolist()}',
                                {'positions': self.measured_q.round(5).tolist()}))
        elif not self.feedback_ok:
            # The arm may have been moved, or its driver restarted elsewhere, while the feedback
            # was gone: hold where it is now, never drive it back to the old reference.
            self._hold_at(self.measured_q, now)
            self._last_command = None
            self.mode = Mode.HOLDING
            events.append(Event('OK', 'feedback restored: holding the measured position '
                                      f'{self.measured_q.round(4).tolist()}; send a new trajectory to move'))
        self.feedback_ok = True
        if self.mode == Mode.MOVING:
            events += self._check_tracking(stamp if stamp > 0 else now, now)
        return events

    def _check_tracking(self, t_meas, now):
        if t_meas < self._stalled_until:
            # Measured while this loop stood still (a process stalled as a whole catches up with states
            # stamped in the past): the reference of that time was rewritten by the stall's delay, so
            # there is nothing to compare with. The next measurement is checked.
            return []
        tol = self.active_tolerances
        ref_q, ref_qd, _ = (a[0] for a in self.traj.sample(t_meas - self.t0))
        err = self.measured_q - ref_q
        np.maximum(self.max_error, np.abs(err), out=self.max_error)
        if (np.abs(err) > tol.path).any():
            return [self._fault('path', err, tol.path, 'from the reference', ErrorCode.PATH_TOLERANCE_VIOLATED, now)]
        if tol.checks_path_velocity and self.measured_qd is not None:
            verr = self.measured_qd - ref_qd
            if (np.abs(verr) > tol.path_velocity).any():
                return [self._fault('path velocity', verr, tol.path_velocity, 'from the reference',
                                    ErrorCode.PATH_TOLERANCE_VIOLATED, now)]
        end = self.t0 + self.traj.duration
        if now >= end:
            goal_q = self.traj.end_state()[0]
            off = self.measured_q - goal_q
            moving = None if self.measured_qd is None else self.measured_qd
            if (np.abs(off) <= tol.goal).all() and (moving is None or (np.abs(moving) <= tol.goal_velocity).all()):
                self.mode = Mode.HOLDING
                values = {'final_error': float(np.abs(off).max()),
                          'max_tracking_error': float(self.max_error.max()), 'duration': self.traj.duration}
                if self.canceling:
                    return [self.end_goal('OK', 'goal canceled: the arm is at rest', Outcome(
                        'canceled', ErrorCode.SUCCESSFUL, 'canceled: braked to rest within the limits'), values)]
                return [self.end_goal('OK', 'goal reached', Outcome('succeeded', ErrorCode.SUCCESSFUL, ''), values)]
            if now > end + tol.goal_time:
                unsettled = moving is not None and (np.abs(moving) > tol.goal_velocity).any() \
                    and (np.abs(off) <= tol.goal).all()
                what, off, limit = ('goal velocity', moving, tol.goal_velocity) if unsettled else ('goal', off, tol.goal)
                return [self._fault(what, off, limit, f'from the goal {tol.goal_time} s after the end',
                                    ErrorCode.GOAL_TOLERANCE_VIOLATED, now)]
        return []

    def _fault(self, what, off, limit, where, code, now):
        """Brake, hold, and end the running goal with ``code``: the joint farthest beyond its tolerance."""
        j = int(np.argmax(np.abs(off) - limit))
        self._stop(now)
        self.mode = Mode.FAULT
        unit = 'rad/s' if 'velocity' in what else 'rad'
        text = (f'{what} tolerance violated: {self.names[j]} is {off[j]:+.4f} {unit} {where} '
                f'(tolerance {limit[j]:g} {unit})')
        return self.end_goal('ERROR', text + '; holding', Outcome('aborted', code, text),
                             {'joint': self.names[j], 'error': float(off[j])})

    def feedback(self, now):
        """``(reference (q, qd, qdd), measured q, measured qd or None)`` at ``now``, or None while
        waiting for feedback: what an action goal's feedback reports."""
        if self.traj is None or self.measured_q is None:
            return None
        return self._reference_at(now), self.measured_q, self.measured_qd

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
        self.origin += excess
        self._stalled_until = now
        if self.next is not None:
            self.next = replace(self.next, t_splice=self.next.t_splice + excess, origin=self.next.origin + excess)
        self.version += 1                # a trajectory prepared before the stall is prepared again
        if self.mode != Mode.MOVING:
            return []
        self.delayed += excess
        if now - self._stall_reported < 1.0:
            return []
        self._stall_reported = now
        return [Event('WARN', f'control loop stalled for {now - last:.3f} s: the trajectory goes on '
                              f'{excess:.3f} s later instead of jumping ahead',
                      {'stall': now - last, 'delay': excess, 'total_delay': self.delayed})]

    def tick(self, now):
        """The watchdog; returns events (feedback lost)."""
        if self.mode == Mode.WAITING or not self.feedback_ok:
            return []
        # Counted while this loop runs: a loop that stalled itself could read no states meanwhile.
        if now - max(self.measured_time, self._stalled_until) > self.tol.state_timeout:
            self.feedback_ok = False
            was_moving = self.mode == Mode.MOVING
            self._stop(now)
            self.mode = Mode.HOLDING
            text = (f'feedback lost: no joint_states for {now - self.measured_time:.2f} s '
                    f'(state_timeout {self.tol.state_timeout} s)')
            # No code names this: the path can no longer be checked.
            return [self.end_goal('ERROR', text + '; ' + ('trajectory aborted, ' if was_moving else '') + 'holding',
                                  Outcome('aborted', ErrorCode.PATH_TOLERANCE_VIOLATED, text))]
        return []
