"""The plans a planner has sent, on the controller's clock: which one runs when, and what a
new plan must carry of them. Pure functions (no ROS), for :mod:`picking_planner.node`."""

from __future__ import annotations

import numpy as np


def plan_active(sent, t):
    """The entry of ``sent`` (``(trajectory, start time, joint names)``, oldest first) that
    runs at time ``t``: the newest one started by then, or None."""
    for plan in reversed(sent):
        if plan[1] <= t:
            return plan
    return None


def carried_points(sent, t_from, t_until, period, names):
    """The motion of the plans ``sent`` from ``t_from`` to just before ``t_until``, every
    ``period`` s: ``(t - t_from, q, qd, qdd)`` for the joints ``names``, or None when a
    plan running then lacks one of them (or there is less than half a period to carry).

    A plan is carried on from the state of the plan sent before it at its start time.
    The controller takes only the newest of the trajectories waiting for it: when a plan
    reaches it while the one it carries on from still waits, that one is never run, and
    the new plan would start from a state the arm never reaches. So each trajectory sent
    carries the plans it carries on from, from the start of the first one the controller
    is not yet seen to run: taken or not, the controller then runs the same motion.
    """
    # (The last point at least half a period before ``t_until``: no sliver of a segment.)
    times = t_from + np.arange(max(int(np.ceil((t_until - t_from) / period - 0.5)), 0)) * period
    rows = []
    for t in times:
        traj, t0, plan_names = plan_active(sent, t)
        try:
            cols = [plan_names.index(n) for n in names]
        except ValueError:
            return None
        rows.append([x[cols] for x in traj.state_at(t - t0)])
    if not rows:
        return None
    q, qd, qdd = (np.array(x) for x in zip(*rows))
    return times - t_from, q, qd, qdd
