"""Supervision of the arm: the measured state, tracking against the tolerances at the measurement's own
instant, the feedback's age, and the feedback watchdog (pure core)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .history import CommandHistory

#: s after its stamp that a joint state is late: said so (once a second), not judged as a tracking error.
LATE_FEEDBACK = 0.1


@dataclass(frozen=True)
class Violation:
    """A tolerance broken: ``what`` ('path', 'path velocity', 'goal', 'goal velocity'), the joint's index, how
    far off (rad or rad/s), its tolerance and where the measurement was judged from."""

    what: str
    joint: int
    off: float
    limit: float
    where: str


class Tracker:
    """The newest measurement of ``n`` joints and what it says about the command that ran.

    ``history`` keeps the commands of the last seconds: a joint state is compared with the command of its
    stamp's instant (:class:`~.history.CommandHistory`). ``stall_limit``: s between two ticks beyond which
    the command between them is unknown (not judged).
    """

    def __init__(self, n, stall_limit):
        self.history = CommandHistory(n, gap=stall_limit)
        self.q = self.qd = None
        self.stamp = None            # the newest state's stamp, clock s
        self.received = None         # when it came, clock s
        self.ok = False              # states are coming
        self.max_error = np.zeros(n)
        self.late = 0.0              # s the newest state came after its stamp

    def measure(self, q, qd, stamp, now):
        """A joint state (arm order); ``stamp`` its header time (0: unknown, taken as ``now``)."""
        self.q = np.asarray(q, float)
        self.qd = None if qd is None else np.asarray(qd, float)
        self.stamp = stamp if stamp > 0 else now
        self.received = now
        self.late = max(now - self.stamp, 0.0)

    def reset(self):
        """A new motion: its largest tracking error counts from here."""
        self.max_error[:] = 0.0

    def path_violation(self, tol):
        """The newest state against the command of its instant: a :class:`Violation`, or None when within the
        tolerances ``tol`` (goals.JointTolerances) or when the command of that instant is not known (the loop
        stood still over it, or the state is older than the record)."""
        commanded = self.history.at(self.stamp)
        if commanded is None:
            return None
        ref_q, ref_qd = commanded
        err = self.q - ref_q
        np.maximum(self.max_error, np.abs(err), out=self.max_error)
        found = _beyond('path', err, tol.path, 'from the reference')
        if found is None and tol.checks_path_velocity and self.qd is not None:
            found = _beyond('path velocity', self.qd - ref_qd, tol.path_velocity, 'from the reference')
        return found

    def at_goal(self, goal_q, tol):
        """True when the newest state is within the goal tolerance of ``goal_q`` and at rest."""
        off = self.q - goal_q
        return bool((np.abs(off) <= tol.goal).all() and (self.qd is None or (np.abs(self.qd) <= tol.goal_velocity).all()))

    def goal_violation(self, goal_q, tol):
        """Why the newest state is not at the goal: off it, or near it but still moving."""
        off = self.q - goal_q
        if self.qd is not None and (np.abs(off) <= tol.goal).all():
            return _beyond('goal velocity', self.qd, tol.goal_velocity, f'from the goal {tol.goal_time} s after the end')
        return _beyond('goal', off, tol.goal, f'from the goal {tol.goal_time} s after the end')

    def silent(self, now, since, timeout):
        """True when no state came for ``timeout`` s, counted from ``since`` at the earliest (a loop that stood
        still could read none meanwhile)."""
        return self.ok and now - max(self.received, since) > timeout


def _beyond(what, off, limit, where):
    bad = np.abs(off) > limit
    if not bad.any():
        return None
    j = int(np.argmax(np.abs(off) - limit))
    return Violation(what, j, float(off[j]), float(limit[j]), where)
