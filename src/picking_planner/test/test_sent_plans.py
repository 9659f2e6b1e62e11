"""The planner's sent plans: which one runs when, and what a new plan carries (sent_plans.py)."""

import numpy as np
import pytest

from picking_planner import trajectory
from picking_planner.sent_plans import carried_points, plan_active

ARM = ['a', 'b']


def sent_plans():
    """Three plans as the node keeps them: A from t = 10 s, B from 10.3 s, C (with a gripper) from 10.35 s."""
    def carry_on(plan, t, goal):
        q, qd, qdd = plan.state_at(t)
        return trajectory.quintic(q, goal, 1.0, v0=qd, a0=qdd)
    a = trajectory.quintic([0.0, 0.0], [1.0, -1.0], 2.0)
    b = carry_on(a, 0.3, [0.5, 0.5])
    c = trajectory.stack([carry_on(b, 0.05, [0.2, 0.2]), trajectory.hold([0.09], 1.0)])
    return [(a, 10.0, ARM), (b, 10.3, ARM), (c, 10.35, ARM + ['gripper'])]


def test_the_plan_active_at_a_time_is_the_newest_started_by_then():
    sent = sent_plans()
    assert plan_active(sent, 9.0) is None
    assert plan_active(sent, 10.2)[1] == 10.0
    assert plan_active(sent, 10.3)[1] == 10.3
    assert plan_active(sent, 12.0)[1] == 10.35
    # A plan sent later but starting earlier wins from its start on.
    late = (sent[0][0], 10.1, ARM)
    assert plan_active(sent + [late], 10.4)[1] == 10.1


def test_a_new_plan_carries_the_plans_the_controller_may_not_have_run():
    sent = sent_plans()
    t, q, qd, qdd = carried_points(sent, 10.3, 10.42, 0.01, ARM)
    # Every 10 ms from B's start, at least half a period before the new plan's start.
    assert t == pytest.approx(np.arange(12) * 0.01)
    assert t[-1] <= 0.12 - 0.005
    for k, tk in enumerate(t + 10.3):
        traj, t0, names = plan_active(sent, tk)
        cols = [names.index(n) for n in ARM]
        for got, want in zip((q[k], qd[k], qdd[k]), traj.state_at(tk - t0)):
            assert got == pytest.approx(want[cols], abs=1e-12)
    # B until 10.35 s, then the plan with the gripper (its arm joints).
    assert q[4] == pytest.approx(sent[1][0].state_at(0.04)[0])
    assert q[6] == pytest.approx(sent[2][0].state_at(0.01)[0][:2])
    # Joints in the new plan's order; one a running plan lacks: nothing to carry.
    assert carried_points(sent, 10.3, 10.42, 0.01, ['b', 'a'])[1] == pytest.approx(q[:, ::-1])
    assert carried_points(sent, 10.3, 10.42, 0.01, ARM + ['gripper']) is None
    assert carried_points(sent, 10.36, 10.42, 0.01, ARM + ['gripper'])[1].shape == (6, 3)
    assert carried_points(sent, 10.3, 10.304, 0.01, ARM) is None     # less than half a period
