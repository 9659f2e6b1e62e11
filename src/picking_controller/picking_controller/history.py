"""What the controller commanded, tick by tick: the reference a measurement is judged against (pure core).

A joint state is compared with the reference of its own instant (its stamp), as ros2_controllers
compares the state with the desired state of the same update: a simulator or driver whose states
arrive late is then late, not off its path. The reference of an instant is what was commanded then,
read back from this record, so that a stall's delay of the schedule (which moves later references,
not earlier ones) never rewrites it.
"""

from __future__ import annotations

import numpy as np


class CommandHistory:
    """The commands of the last ``capacity`` ticks: their clock times, positions and velocities.

    ``gap``: s between two ticks beyond which the reference between them is not known (the loop
    stalled: what a drive did meanwhile is its own).
    """

    def __init__(self, n, capacity=4096, gap=0.05):
        self.capacity, self.gap = int(capacity), float(gap)
        # Twice the capacity: appends run on until the end, then the newer half moves to the front.
        self._t = np.empty(2 * self.capacity)
        self._q = np.empty((2 * self.capacity, n))
        self._qd = np.empty((2 * self.capacity, n))
        self._size = 0

    def __len__(self):
        return self._size

    def record(self, t, q, qd):
        """The command sent at clock time ``t`` (s)."""
        i = self._size
        if i == 2 * self.capacity:
            keep = self.capacity
            self._t[:keep] = self._t[i - keep:i]
            self._q[:keep] = self._q[i - keep:i]
            self._qd[:keep] = self._qd[i - keep:i]
            i = keep
        self._t[i], self._q[i], self._qd[i] = t, q, qd
        self._size = i + 1

    def clear(self):
        self._size = 0

    def at(self, t):
        """``(q, qd)`` commanded at clock time ``t``, or None where it is not known: before the record, in a
        gap of more than ``gap`` between two ticks, or more than ``gap`` after the newest tick."""
        n = self._size
        if n == 0:
            return None
        times = self._t[:n]
        j = int(np.searchsorted(times, t, side='right'))
        if j == 0:
            return None
        if j == n:                              # after the newest command: it extrapolated briefly
            dt = t - times[-1]
            if dt > self.gap:
                return None
            return self._q[n - 1] + self._qd[n - 1] * dt, self._qd[n - 1]
        t0, t1 = times[j - 1], times[j]
        if t1 - t0 > self.gap:
            return None
        w = (t - t0) / (t1 - t0)
        return ((1.0 - w) * self._q[j - 1] + w * self._q[j], (1.0 - w) * self._qd[j - 1] + w * self._qd[j])
