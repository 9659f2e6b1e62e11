"""The controller's schedule: every trajectory it will run, each from the time it takes over (pure core).

A trajectory stamped ``t_s`` is spliced onto the schedule at ``t_s``: what was scheduled before
``t_s`` is kept and runs until then, what was scheduled from ``t_s`` on is dropped, and the new
trajectory runs from there. The reference at any time is the state of the entry active then (the
newest one started by then). Times are on the schedule's clock: the controller's clock less the delay
that stalls of its loop added to the motion under way (see :class:`~picking_controller.core.ControllerCore`).
"""

from __future__ import annotations

from dataclasses import dataclass

from picking_core.trajectory import PiecewisePolynomial


@dataclass(frozen=True)
class Entry:
    """One trajectory of the schedule.

    Attributes
    ----------
    start : float
        Schedule time it takes over, s (its trajectory's time 0).
    traj : PiecewisePolynomial
        From the reference at ``start`` (a bridge or lead-in first where its first point was elsewhere).
    origin : float
        Schedule time of its message's ``time_from_start`` 0, s: ``start`` plus any bridge before its points.
    goal : hashable or None
        The action goal it runs for (None: a topic's trajectory, a hold or a brake).
    tolerances : goals.JointTolerances or None
        Its goal's tolerances (None: the controller's defaults).
    lead : float
        s of its trajectory before its first point (a bridge or lead-in from the reference).
    kind : str
        ``'trajectory'`` (points a client sent), ``'hold'`` or ``'brake'`` (the controller's own).
    cut : float or None
        Schedule time it was spliced at, where what was scheduled is dropped (None: ``start``). A trajectory whose
        first point, due after its stamp, is the reference then takes over there; the schedule runs until then.
    """

    start: float
    traj: PiecewisePolynomial
    origin: float
    goal: object = None
    tolerances: object = None
    lead: float = 0.0
    kind: str = 'trajectory'
    cut: float | None = None

    @property
    def end(self):
        """Schedule time its trajectory ends, s."""
        return self.start + self.traj.duration

    def state_at(self, t):
        """``(q, qd, qdd)`` at schedule time ``t`` (its first state before its start, its end at rest after)."""
        return self.traj.state_at(max(t - self.start, self.traj.start_time))


class Schedule:
    """The entries, oldest first: the one running and those waiting for their start."""

    def __init__(self):
        self.entries = []

    def __bool__(self):
        return bool(self.entries)

    @property
    def active(self):
        """The entry running (the oldest one kept), or None before the first."""
        return self.entries[0] if self.entries else None

    @property
    def last(self):
        return self.entries[-1] if self.entries else None

    @property
    def end(self):
        """Schedule time the last entry ends, s (-inf when empty)."""
        return self.entries[-1].end if self.entries else float('-inf')

    def at(self, t):
        """The entry that runs at schedule time ``t``: the newest started by then (the first before any)."""
        found = self.entries[0] if self.entries else None
        for entry in self.entries[1:]:
            if entry.start > t:
                break
            found = entry
        return found

    def state_at(self, t):
        """The reference ``(q, qd, qdd)`` at schedule time ``t``; None when nothing is scheduled."""
        entry = self.at(t)
        return None if entry is None else entry.state_at(t)

    def until(self, t):
        """The schedule as a trajectory spliced at schedule time ``t`` keeps it: the entries that start before ``t``
        (the first entry at least, which runs before any other)."""
        kept = Schedule()
        kept.entries = [e for e in self.entries if e.start < t] or self.entries[:1]
        return kept

    def splice(self, entry):
        """Put ``entry`` on the schedule at its start; returns the entries it replaced (those that would
        have taken over at or after its start: they never run)."""
        cut = entry.start if entry.cut is None else entry.cut
        keep = [e for e in self.entries if e.start < cut]
        dropped = [e for e in self.entries if e.start >= cut]
        self.entries = keep + [entry]
        return dropped

    def replace_all(self, entry):
        """``entry`` alone (a brake, a hold): returns every entry it replaced."""
        dropped, self.entries = self.entries, [entry]
        return dropped

    def advance(self, t):
        """Drop the entries a newer one has taken over from by schedule time ``t``; returns them."""
        k = 0
        while k + 1 < len(self.entries) and self.entries[k + 1].start <= t:
            k += 1
        done, self.entries = self.entries[:k], self.entries[k:]
        return done

    def waiting(self):
        """The entries that have not taken over yet."""
        return self.entries[1:]
