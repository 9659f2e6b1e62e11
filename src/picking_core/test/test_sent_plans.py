"""The planner's sent plans: which one runs when, and what a new plan carries (sent_plans.py)."""

from collections import deque

import numpy as np
import pytest
from hypothesis import given, strategies as st

from picking_core import trajectory
from picking_core.sent_plans import (SentPlan, carried_points, carry_start, forget_before, plan_active,
                                        predict_reference)

ARM = ['a', 'b']


def sent_plans():
    """Three plans as the node keeps them: A from t = 10 s, B from 10.3 s, C (with a gripper) from 10.35 s."""
    def carry_on(plan, t, goal):
        q, qd, qdd = plan.state_at(t)
        return trajectory.quintic(q, goal, 1.0, v0=qd, a0=qdd)
    a = trajectory.quintic([0.0, 0.0], [1.0, -1.0], 2.0)
    b = carry_on(a, 0.3, [0.5, 0.5])
    c = trajectory.stack([carry_on(b, 0.05, [0.2, 0.2]), trajectory.hold([0.09], 1.0)])
    return [SentPlan(a, 10.0, ARM), SentPlan(b, 10.3, ARM), SentPlan(c, 10.35, ARM + ['gripper'])]


def test_the_plan_active_at_a_time_is_the_newest_started_by_then():
    sent = sent_plans()
    assert plan_active(sent, 9.0) is None
    assert plan_active(sent, 10.2)[1] == 10.0
    assert plan_active(sent, 10.3)[1] == 10.3
    assert plan_active(sent, 12.0)[1] == 10.35
    # A plan sent later but starting earlier wins from its start on.
    late = SentPlan(sent[0].trajectory, 10.1, ARM)
    assert plan_active(sent + [late], 10.4)[1] == 10.1


def test_a_new_plan_carries_the_plans_the_controller_may_not_have_run():
    sent = sent_plans()
    t, q, qd, qdd = carried_points(sent, 10.3, 10.42, 0.01, ARM)
    # Every 10 ms from B's start, at least half a period before the new plan's start.
    assert t == pytest.approx(np.arange(12) * 0.01)
    assert t[-1] <= 0.12 - 0.005
    for k, tk in enumerate(t + 10.3):
        traj, t0, names = plan_active(sent, tk)[:3]
        cols = [names.index(n) for n in ARM]
        for got, want in zip((q[k], qd[k], qdd[k]), traj.state_at(tk - t0)):
            assert got == pytest.approx(want[cols], abs=1e-12)
    # B until 10.35 s, then the plan with the gripper (its arm joints).
    assert q[4] == pytest.approx(sent[1].trajectory.state_at(0.04)[0])
    assert q[6] == pytest.approx(sent[2].trajectory.state_at(0.01)[0][:2])
    # Joints in the new plan's order; one a running plan lacks: nothing to carry.
    assert carried_points(sent, 10.3, 10.42, 0.01, ['b', 'a'])[1] == pytest.approx(q[:, ::-1])
    assert carried_points(sent, 10.3, 10.42, 0.01, ARM + ['gripper']) is None
    assert carried_points(sent, 10.36, 10.42, 0.01, ARM + ['gripper'])[1].shape == (6, 3)
    assert carried_points(sent, 10.3, 10.304, 0.01, ARM) is None     # less than half a period


def test_the_carry_starts_at_the_first_unseen_plan_or_afresh_at_one_that_did_not_carry_on():
    sent = sent_plans()
    assert carry_start(sent, 10.2, 10.5) == 10.3          # B and C are not seen to run yet
    assert carry_start(sent, 10.31, 10.5) == 10.35
    assert carry_start(sent, 10.36, 10.5) is None         # C runs: nothing to carry
    assert carry_start(sent, 10.2, 10.32) == 10.3          # C starts after the new plan
    # D started from an extrapolated reference, 0.05 rad from where B is then: carrying B
    # into D would jump; the carry starts afresh at D's start.
    d = trajectory.quintic(sent[1].trajectory.state_at(0.05)[0] + 0.05, [0.2, 0.2], 1.0)
    afresh = sent[:2] + [SentPlan(d, 10.35, ARM, carries_on=False)]
    assert carry_start(afresh, 10.2, 10.5) == 10.35
    # Carried from B all the same, the points start afresh at D rather than jump from B to D between two points.
    across = carried_points(afresh, 10.3, 10.5, 0.01, ARM)
    assert across[0][0] == pytest.approx(0.05) and np.abs(np.diff(across[1], axis=0)).max() < 0.01
    assert np.abs(np.diff(carried_points(afresh, 10.35, 10.5, 0.01, ARM)[1], axis=0)).max() < 0.01
    # ... unless a plan sent after D, starting before it, runs instead of it.
    replaced = afresh + [SentPlan(sent[1].trajectory, 10.32, ARM)]
    assert carry_start(replaced, 10.2, 10.5) == 10.3


@given(st.lists(st.tuples(st.integers(0, 12), st.booleans()), max_size=12), st.integers(-1, 12), st.integers(0, 13))
def test_the_carry_start_is_the_first_unseen_start_or_the_last_running_plan_that_did_not_carry_on(plans, seen, until):
    """Against the definition, by plan_active at every start: whatever the order plans were sent in."""
    sent = [SentPlan(None, float(s), ARM, carries_on) for s, carries_on in plans]
    starts = sorted({p.start for p in sent if seen < p.start < until})
    fresh = [t for t in starts[1:] if plan_active(sent, t).start == t and not plan_active(sent, t).carries_on]
    want = (fresh[-1] if fresh else starts[0]) if starts else None
    assert carry_start(sent, seen, until) == want


def test_plans_that_can_no_longer_run_are_forgotten():
    sent = deque(sent_plans())
    assert forget_before(sent, 9.0) is None and len(sent) == 3         # before any plan: all kept
    assert forget_before(sent, 10.32).start == 10.3                     # A can no longer run
    assert [p.start for p in sent] == [10.3, 10.35]
    # A plan sent last that starts earliest runs from then on: all before it go.
    sent.append(SentPlan(sent[0].trajectory, 10.31, ARM))
    assert forget_before(sent, 10.4).start == 10.31 and len(sent) == 1


def test_a_reference_off_the_plans_is_predicted_with_its_acceleration_ended_by_then():
    """The state ``dt`` later of an acceleration brought linearly to zero: a cubic in time."""
    q, qd, qdd = np.array([0.5, -1.0]), np.array([1.0, 0.0]), np.array([-3.0, 6.0])
    dt = 0.1
    got = predict_reference(q, qd, qdd, dt)
    ramp = trajectory.PiecewisePolynomial([0.0, dt], [[q, qd, qdd / 2, -qdd / (6 * dt)]])
    for x, want in zip(got, ramp.state_at(dt)):
        assert x == pytest.approx(want, abs=1e-15)
    assert np.all(got[2] == 0.0)
    assert predict_reference(q, qd, qdd, 0.0)[0] == pytest.approx(q)


@pytest.mark.parametrize('accel', [5.0, -12.0])
def test_a_flood_of_goals_on_a_predicted_reference_does_not_run_away(accel):
    """A goal every millisecond, each plan starting 0.1 s ahead at the state predicted there, and
    the controller leading in from its reference to it (a quintic between the two states): the
    speed the reference gains stays below |qdd| x 0.1 s and its acceleration dies out. (Predicted
    with the acceleration held, the lead-in kept it, and after 2 s the reference moved at
    |qdd| x 2 s.)"""
    q, qd, qdd = np.zeros(1), np.zeros(1), np.array([accel])
    for _ in range(2000):
        start = predict_reference(q, qd, qdd, 0.1)
        lead_in = trajectory.quintic(q, start[0], 0.1, qd, start[1], qdd, start[2])
        q, qd, qdd = lead_in.state_at(0.001)
    assert abs(qd[0]) <= abs(accel) * 0.1
    assert abs(qdd[0]) < 1e-6 * abs(accel)


def test_carried_points_keep_every_break_and_acceleration_step_of_the_plans_they_carry():
    """LSPB plans (their acceleration steps at the blends): between two carried points no break of the
    plan running then, and where the acceleration steps, two points STEP apart, before and after it."""
    a = trajectory.lspb(np.array([0.0, 0.0]), np.array([1.0, -1.0]), 1.0, np.array([8.0, 8.0]))
    q, qd, qdd = a.state_at(0.3)
    b = trajectory.concatenate([trajectory.quintic(q, q + 0.1, 0.2, v0=qd, a0=qdd),
                                trajectory.lspb(q + 0.1, np.array([0.2, 0.2]), 0.6, np.array([8.0, 8.0]))])
    sent = [SentPlan(a, 10.0, ARM), SentPlan(b, 10.3, ARM)]
    t, q, qd, qdd = carried_points(sent, 10.0, 10.9, 0.01, ARM)
    steps = trajectory.step_pairs(t)
    starts = t[np.flatnonzero(~steps)] + 10.0
    for lo, hi in zip(starts[:-1], starts[1:]):
        plan = plan_active(sent, lo)
        breaks = plan.trajectory.breaks + plan.start
        assert not ((breaks > lo + 1e-9) & (breaks < hi - 1e-9)).any(), (lo, hi)
    # Each step pair: the acceleration before the step, then the state a microsecond after it.
    first = np.flatnonzero(steps) - 1
    assert first.size >= 4
    assert q[first + 1] == pytest.approx(q[first] + qd[first] * trajectory.STEP, abs=1e-11)
    for k in first:
        plan = plan_active(sent, 10.0 + t[k] + 1e-7)
        local = 10.0 + t[k] - plan.start
        assert qdd[k] == pytest.approx(plan.trajectory.sample([local - 1e-9])[2][0], abs=1e-5)
        assert qdd[k + 1] == pytest.approx(plan.trajectory.sample([local + 1e-9])[2][0], abs=1e-5)


def test_carried_points_hold_a_plan_that_ended_before_the_next_began():
    """A plan from rest may start after the one before it has ended (planned late, then started later as it
    is): the points carried across the gap hold the first plan's end, as the controller holds its last point
    (its last polynomial, extrapolated, reached 5.6 rad on a wrist: a flood goal refused for a limit)."""
    a = trajectory.quintic(np.array([0.0, 0.0]), np.array([0.5, -0.5]), 0.5)
    b = trajectory.quintic(np.array([0.5, -0.5]), np.array([0.0, 0.0]), 0.5)
    sent = [SentPlan(a, 10.0, ARM), SentPlan(b, 11.0, ARM, carries_on=False)]
    t, q, qd, qdd = carried_points(sent, 10.0, 11.2, 0.01, ARM)
    gap = (t > 0.5) & (t < 1.0)
    assert gap.sum() >= 40
    assert q[gap] == pytest.approx(np.tile([0.5, -0.5], (gap.sum(), 1)))
    assert not qd[gap].any() and not qdd[gap].any()
    assert np.abs(q).max() <= 0.5 + 1e-12
