"""The last guard before a command leaves: the reference held to the joint limits, and the reason said
once per trajectory when it had to be (pure core)."""

from __future__ import annotations

import numpy as np

from .events import Event


class CommandGuard:
    """Holds each command within the :class:`~.validation.Limits`; counts and names what it had to change."""

    def __init__(self, limits):
        self.limits = limits
        self.last = None             # (q, clock time) of the last command sent
        self.limited = 0             # ticks whose command had to be limited
        self._said_for = None        # the entry whose limiting was reported

    def forget(self):
        """The next command follows no earlier one (the arm was held where it was measured)."""
        self.last = None

    def hold(self, ref, now, entry):
        """``((q, qd, qdd), events)``: ``ref`` held within the limits at clock time ``now``, for the schedule
        ``entry`` that produced it (a limited command is reported once per entry).

        Positions stay within [lower, upper], velocities and accelerations within their limits, and the
        position within ``max_velocity`` times the time since the last command of that command (no step).
        The schedule keeps them; should it not (a bug, a limit changed), the command is limited and said."""
        lim = self.limits
        q, qd, qdd = ref
        # (The ufuncs themselves: np.clip costs several times as much per call on arrays this small.)
        out_q = np.minimum(np.maximum(q, lim.lower), lim.upper)
        last = self.last
        if last is not None and now > last[1]:
            reach = lim.max_velocity * (now - last[1]) * 1.01 + 1e-9
            np.minimum(np.maximum(out_q, last[0] - reach, out=out_q), last[0] + reach, out=out_q)
        out_qd = np.minimum(np.maximum(qd, -lim.max_velocity), lim.max_velocity)
        out_qdd = np.minimum(np.maximum(qdd, -lim.max_acceleration), lim.max_acceleration)
        self.last = (out_q, now)
        events = []
        if not ((out_q == q).all() and (out_qd == qd).all() and (out_qdd == qdd).all()) and _beyond(
                ref, (out_q, out_qd, out_qdd)):
            self.limited += 1
            if self._said_for is not entry:
                self._said_for = entry
                events.append(self._event(ref, (out_q, out_qd, out_qdd)))
        return (out_q, out_qd, out_qdd), events

    def _event(self, ref, out):
        """The WARN for a limited command: which joint, which limit, and the likely cause."""
        lim = self.limits
        (q, qd, qdd), (out_q, out_qd, out_qdd) = ref, out
        j = int(np.argmax(np.abs(out_q - q) + np.abs(out_qd - qd) + np.abs(out_qdd - qdd)))
        if out_q[j] != q[j] and lim.lower[j] <= q[j] <= lim.upper[j]:
            what = (f'its position {q[j]:.4g} jumps from the last command faster than the velocity limit '
                    f'{lim.max_velocity[j]:.4g} allows')
        elif out_q[j] != q[j]:
            what = f'its position {q[j]:.4g} is beyond [{lim.lower[j]:.4g}, {lim.upper[j]:.4g}]'
        elif out_qd[j] != qd[j]:
            what = f'its velocity {qd[j]:.4g} is beyond the limit {lim.max_velocity[j]:.4g}'
        else:
            # Accelerations are checked at the points, not between them: a spline through points whose
            # acceleration steps between them (cubic and LSPB plans) overshoots there.
            what = (f'its acceleration {qdd[j]:.4g} is beyond the limit {lim.max_acceleration[j]:.4g} '
                    '(between the points: the spline through them overshoots where the planned acceleration '
                    'steps, as in cubic and LSPB moves, or turns sharply within a sample period; jerk-limited '
                    'plans sampled finely enough do not)')
        return Event('WARN', f'command limited: the reference of {lim.names[j]}: {what}; sent within the limits '
                             '(reported once per trajectory)',
                     {'joint': lim.names[j], 'position': float(q[j]), 'velocity': float(qd[j]),
                      'acceleration': float(qdd[j]), 'limited_ticks': self.limited})


def _beyond(ref, out, rel=1e-9):
    """True when the limiting changed the reference by more than rounding (a plan at a limit exactly may come
    out a few ulps beyond it; that is not worth a warning)."""
    return any((np.abs(o - i) > rel * (1.0 + np.abs(i))).any() for i, o in zip(ref, out))
