"""The last guard before a command leaves: the reference held to the joint limits, and the reason
said once per trajectory when it had to be (part of :class:`~picking_controller.core.ControllerCore`)."""

from __future__ import annotations

import numpy as np

from .events import MIN_LEAD, Event


class CommandLimits:
    """The reference as it is commanded."""

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
        events, self._pending = self._pending, []
        if ref is None:
            return None, events
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
        if not ((out_q == q).all() and (out_qd == qd).all() and (out_qdd == qdd).all()) and self._beyond(
                q, qd, qdd, out_q, out_qd, out_qdd):
            self.limited += 1
            if self._limited_version != self.version:
                self._limited_version = self.version
                events.append(self._limited_event(q, qd, qdd, out_q, out_qd, out_qdd, now))
        return (out_q, out_qd, out_qdd), events

    @staticmethod
    def _beyond(q, qd, qdd, out_q, out_qd, out_qdd, rel=1e-9):
        """True when the limiting changed the reference by more than rounding: a plan at a limit
        exactly may come out a few ulps beyond it; sent within the limits, that is not worth a warning."""
        return any((np.abs(o - i) > rel * (1.0 + np.abs(i))).any()
                   for i, o in ((q, out_q), (qd, out_qd), (qdd, out_qdd)))

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
