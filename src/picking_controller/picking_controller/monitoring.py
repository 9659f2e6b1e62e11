"""Supervision of a running trajectory: feedback, tracking against the tolerances, stalls of the
control loop, and the feedback watchdog (part of :class:`~picking_controller.core.ControllerCore`)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .events import Event, Mode


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
        ref_q = self.traj.sample(t_meas - self.t0)[0][0]
        err = self.measured_q - ref_q
        np.maximum(self.max_error, np.abs(err), out=self.max_error)
        bad = np.abs(err) > self.tol.path
        if bad.any():
            j = int(np.argmax(np.abs(err)))
            self._stop(now)
            self.mode = Mode.FAULT
            return [Event('ERROR', f'path tolerance violated: {self.names[j]} is {err[j]:+.4f} rad from the '
                                   f'reference (tolerance {self.tol.path}); holding',
                          {'joint': self.names[j], 'error': float(err[j])})]
        end = self.t0 + self.traj.duration
        if now >= end:
            goal_q = self.traj.end_state()[0]
            off = np.abs(self.measured_q - goal_q)
            still = self.measured_qd is None or np.all(np.abs(self.measured_qd) <= self.tol.stopped_velocity)
            if np.all(off <= self.tol.goal) and still:
                self.mode = Mode.HOLDING
                return [Event('OK', 'goal reached', {
                    'final_error': float(off.max()), 'max_tracking_error': float(self.max_error.max()),
                    'duration': self.traj.duration})]
            if now > end + self.tol.goal_time:
                j = int(np.argmax(off))
                self._stop(now)
                self.mode = Mode.FAULT
                return [Event('ERROR', f'goal tolerance violated: {self.names[j]} is {off[j]:.4f} rad from the '
                                       f'goal {self.tol.goal_time} s after the end (tolerance {self.tol.goal}); '
                                       'holding', {'joint': self.names[j], 'error': float(off[j])})]
        return []

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
        if now - self.measured_time > self.tol.state_timeout:
            self.feedback_ok = False
            was_moving = self.mode == Mode.MOVING
            self._stop(now)
            self.mode = Mode.HOLDING
            return [Event('ERROR', f'feedback lost: no joint_states for {now - self.measured_time:.2f} s '
                                   f'(state_timeout {self.tol.state_timeout} s); '
                                   + ('trajectory aborted, ' if was_moving else '') + 'holding')]
        return []
