"""The plans a planner has sent, on the controller's clock: which one runs when, and what a
new plan must carry of them. Pure functions (no ROS), for :mod:`picking_core.node`."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .trajectory.waypoints import one_sided, waypoints


class SentPlan(NamedTuple):
    """A plan as sent: its trajectory, its start on the controller's clock, its joint names,
    and whether it carries on from the plans sent before it (starts from the state of the one
    running at ``start``) or from elsewhere (an extrapolated reference, the measured state).
    ``key``: the trajectory as the controller names it; ``stamp``: the time of its points'
    time_from_start 0 (before ``start`` when it carries older plans' points); ``delay``: how
    much later than sent the controller runs it (stalls of its loop: see
    :meth:`GoalPolicy.runs_late`), already in ``start``."""

    trajectory: object
    start: float
    names: list
    carries_on: bool = True
    key: str = ''
    stamp: float = 0.0
    delay: float = 0.0


def plan_active(sent, t):
    """The entry of ``sent`` (:class:`SentPlan`, oldest first) that runs at time ``t``: the
    newest one started by then, or None."""
    for plan in reversed(sent):
        if plan.start <= t:
            return plan
    return None


def forget_before(sent, t):
    """Drop from the deque ``sent`` the plans that cannot run at ``t`` or later: those sent
    before the plan active at ``t`` (a later time runs that one or a newer plan). Returns
    the plan active at ``t``, or None (then nothing is dropped)."""
    active = plan_active(sent, t)
    if active is not None:
        while sent[0] is not active:
            sent.popleft()
    return active


def carry_start(sent, seen, t_start):
    """Where a new plan starting at ``t_start`` must carry the sent plans from: the start of
    the first plan the controller is not seen to run by ``seen`` (its reference's stamp),
    or None when there is none.

    The carried motion must be one motion: each plan in it starts from the state of the
    plan before it. A plan that started elsewhere (from an extrapolated reference, which
    the controller led into its own way) begins the carry afresh at its start; carrying
    the motion before it too would put a jump into the points at that start.
    """
    first = afresh = None
    later = np.inf                   # the earliest start among the plans sent after this one
    for plan in reversed(sent):
        if seen < plan.start < t_start:
            first = plan.start if first is None else min(first, plan.start)
            # It runs from its start unless a plan sent after it starts by then.
            if plan.start < later and not plan.carries_on:
                afresh = plan.start if afresh is None else max(afresh, plan.start)
        later = min(later, plan.start)
    return afresh if afresh is not None else first


def carried_points(sent, t_from, t_until, period, names):
    """The motion of the plans ``sent`` from ``t_from`` to just before ``t_until``, as the points
    :func:`~picking_core.trajectory.waypoints` makes of each (every ``period`` s, its breaks and
    acceleration steps): ``(t - t_from, q, qd, qdd)`` for the joints ``names``, or None when a
    plan running then lacks one of them (or there is less than half a period to carry).

    A plan is carried on from the state of the plan sent before it at its start time.
    The controller takes only the newest of the trajectories waiting for it: when a plan
    reaches it while the one it carries on from still waits, that one is never run, and
    the new plan would start from a state the arm never reaches. So each trajectory sent
    carries the plans it carries on from, from the start of the first one the controller
    is not yet seen to run: taken or not, the controller then runs the same motion.
    """
    # (The last point at least half a period before ``t_until``: no sliver of a segment.)
    if t_until - t_from < period / 2:
        return None
    starts = sorted({p.start for p in sent if t_from < p.start < t_until} | {t_from})
    parts, before, previous = [], None, None
    for lo, hi in zip(starts, starts[1:] + [t_until]):
        active = plan_active(sent, lo)
        traj, t0, plan_names = active.trajectory, active.start, active.names
        try:
            cols = [plan_names.index(n) for n in names]
        except ValueError:
            return None
        if previous is not None and _apart(previous[0].state_at(lo - previous[1]), previous[2],
                                           traj.state_at(lo - t0), cols):
            # This plan does not start where the one before it is then (that one was refused, and the plan it
            # carried on from is gone): carry from here; joining the two would put a jump between two points.
            parts, before = [], None
        previous = (traj, t0, cols)
        if before is not None:           # the acceleration the plan before ended with, for the joints carried
            before, given = one_sided(traj, np.array([lo - t0]), after=True)[2][0], before
            before[cols] = given
        t, q, qd, qdd = waypoints(traj, period, lo - t0, hi - t0, before=before, end=False)
        parts.append((t + (lo - t_from), q[:, cols], qd[:, cols], qdd[:, cols]))
        before = traj.state_at(hi - t0)[2][cols]
    if not parts:
        return None
    return tuple(np.concatenate(x) for x in zip(*parts))


def _apart(state, cols, other, other_cols, tol=1e-6):
    """True when two plans' states (columns ``cols`` and ``other_cols``: the joints carried) differ in q or qd."""
    return any(np.abs(a[cols] - b[other_cols]).max() > tol for a, b in zip(state[:2], other[:2]))


def predict_reference(q, qd, qdd, dt):
    """Where a reference that is not on the plans sent is expected ``dt`` s later: its
    acceleration brought linearly to zero over ``dt``. Returns ``(q, qd, qdd)``, the last zero.

    Held constant instead (the Taylor expansion), the acceleration went on for ever under a
    flood of goals while the reference was off the plans (after the controller stalled): each
    plan started ``dt`` ahead with the reference's acceleration, the controller's lead-in to it
    (a spline between the two states) kept that acceleration exactly, and the next goal, a
    millisecond later, found it again. The arm sped up toward its limits until goals were
    refused. Ended over ``dt``, the acceleration the lead-ins keep shrinks with each goal (by a
    factor ``1 - 1 ms / dt`` at a goal a millisecond), and the speed it adds stays below
    ``|qdd| dt``.
    """
    q, qd, qdd = (np.asarray(x, dtype=float) for x in (q, qd, qdd))
    return q + qd * dt + qdd * (dt * dt / 3.0), qd + qdd * (0.5 * dt), np.zeros_like(qdd)
