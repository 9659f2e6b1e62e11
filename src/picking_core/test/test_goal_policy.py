"""The planner's goal policy without ROS: resends, waiting goals, late replans, where plans start."""

import numpy as np
import pytest

from picking_core import trajectory
from picking_core.approaches import Blocked, BrakeBlocked
from picking_core.goal_policy import (DELIVERY, FIRST_PLANNING, LATE_REPLANS, REPEAT_WINDOW, WAIT_LIMIT, Goal,
                                         GoalPolicy, Start, Unsettled)

HOME = np.array([0.0, 0.2, 1.6, 0.0, 1.3, 0.0])


@pytest.fixture
def policy(arm):
    return GoalPolicy(arm, start_delay=0.1)


def goal(kind='pose', key='12.000000000', came=0.0):
    return Goal(kind, key, lambda start, gripper: None, came)


def test_a_goal_sent_again_is_answered_again_not_planned_twice(policy):
    assert policy.repeat('5.000000001', b'goal', 100.0) == (False, None)
    assert policy.repeat('5.000000001', b'goal', 101.0) == (True, None)          # still being planned
    policy.answered('5.000000001', 'accepted')
    assert policy.repeat('5.000000001', b'goal', 102.0) == (True, 'accepted')
    # Another content under the same stamp, the same one long after, or no stamp at all: new goals.
    assert policy.repeat('5.000000001', b'other', 103.0) == (False, None)
    assert policy.repeat('5.000000001', b'other', 103.0 + REPEAT_WINDOW + 1) == (False, None)
    assert policy.repeat('0.000000000', b'x', 0.0) == (False, None)
    assert policy.repeat('0.000000000', b'x', 0.0) == (False, None)


def test_only_the_newest_goal_waits_and_a_goal_waiting_too_long_is_refused(policy):
    first, second = goal(key='1.000000000', came=10.0), goal(key='2.000000000', came=10.5)
    assert policy.wait(first) is None
    assert policy.wait(second) is first                    # superseded
    assert policy.waited(False, 10.5 + WAIT_LIMIT / 2) == (None, None)
    assert policy.waited(False, 10.5 + WAIT_LIMIT + 0.1) == (None, second)
    assert policy.waiting is None
    policy.wait(first)
    assert policy.waited(True, 1e9) == (first, None)


def test_a_plan_starts_later_for_a_kind_that_took_longer_and_twice_as_far_at_each_replan(policy):
    g = goal('pick')
    assert policy.delay(g) == pytest.approx(0.1 + 1.5 * FIRST_PLANNING['pick'])
    policy.planned(g, 0.2)
    assert policy.delay(g) == pytest.approx(0.1 + 0.3)
    g.attempt = 2
    assert policy.delay(g) == pytest.approx(0.4 + 0.3)


def test_without_a_reference_the_plan_starts_at_rest_from_the_measurement(policy):
    start = policy.start_state(50.0, None, HOME)
    assert start.source == 'measured' and start.time == 50.0 and start.carry_from is None
    assert np.array_equal(start.state[0], HOME) and not start.state[1].any() and not start.state[2].any()
    with pytest.raises(ValueError, match='no joint_states'):
        policy.start_state(50.0, None, None)


def test_a_plan_carries_on_from_the_plan_the_reference_follows(policy):
    """The reference lies on the plan sent: the next plan starts on that plan's exact state at its
    start time, and carries the sent plan's points from where the controller may not have it."""
    move = trajectory.quintic(HOME, HOME + 0.3, 2.0)
    first = policy.start_state(10.0, None, HOME)
    policy.sent_plan(goal(), move, first, list('abcdef'), '10.000000000', 10.0, 0.1)
    q, qd, qdd = move.state_at(0.5)
    start = policy.start_state(11.0, (q, qd, qdd, 10.5), HOME)
    assert start.carries_on and start.source == 'reference'
    assert np.allclose(start.state[0], move.state_at(1.0)[0]) and np.allclose(start.state[1], move.state_at(1.0)[1])
    assert start.carry_from is None                         # the controller runs the sent plan already
    own = (np.array([0.0, 0.01]), *(np.zeros((2, 6)) for _ in range(3)))
    assert policy.points(own, start, 0.01, list('abcdef')) == (own, 11.0)
    # A second plan, sent to start at 11 s: a third starting at 11.5 s, the reference seen at 10.5 s
    # (before the second's start), carries the second from its start.
    second = trajectory.quintic(start.state[0], HOME, 1.0, v0=start.state[1], a0=start.state[2])
    policy.sent_plan(goal(), second, start, list('abcdef'), '11.000000000', 10.5, 0.1)
    third = policy.start_state(11.5, (q, qd, qdd, 10.5), HOME)
    assert third.carries_on and third.carry_from == 11.0
    points, stamp = policy.points(own, third, 0.01, list('abcdef'))
    assert stamp == 11.0 and len(points[0]) == 50 + 2
    assert np.allclose(points[1][0], second.state_at(0.0)[0])


def test_a_plan_the_controller_runs_late_is_moved_so_that_starts_far_ahead_stay_on_it(policy):
    """A controller that stalled runs the plan later than its stamp (its feedback says where in the
    plan's points its reference is): the plan is moved by that delay, and a start predicted seconds
    ahead (a replacing harvest's) is the plan's state then, not the reference extrapolated."""
    names = list('abcdef')
    move = trajectory.quintic(HOME, HOME + 0.5, 4.0)
    policy.sent_plan(goal(), move, policy.start_state(10.0, None, HOME), names, '10.000000000', 10.0, 0.1)
    q, qd, qdd = move.state_at(1.0)
    # Without the feedback, the reference at 11.3 s is not on the plan: extrapolated a little way
    # ahead, never 2 s (the goal waits for the feedback).
    assert not policy.start_state(11.6, (q, qd, qdd, 11.3), HOME).carries_on
    with pytest.raises(Unsettled, match='off the plan it runs'):
        policy.start_state(13.3, (q, qd, qdd, 11.3), HOME)
    # Feedback at 11.3 s: 1.0 s into the plan's points, which are there: it runs 0.3 s late.
    assert policy.runs_late('10.000000000', 11.3, 1.0, names + ['gripper_joint'], [*q, 0.09]) == pytest.approx(0.3)
    assert policy.sent[0].start == pytest.approx(10.3) and policy.sent[0].delay == pytest.approx(0.3)
    found = policy.start_state(13.3, (q, qd, qdd, 11.3), HOME)
    assert found.carries_on and np.allclose(found.state[0], move.state_at(3.0)[0])
    # Known already, a feedback that does not match, one for another plan, one without a time: no move.
    assert policy.runs_late('10.000000000', 11.4, 1.1, names, move.state_at(1.1)[0]) == 0.0
    assert policy.runs_late('10.000000000', 11.6, 1.1, names, move.state_at(1.1)[0] + 0.01) == 0.0
    assert policy.runs_late('12.000000000', 12.6, 0.3, names, HOME) == 0.0
    assert policy.runs_late('10.000000000', 11.6, 0.0, names, HOME) == 0.0
    assert policy.sent[0].start == pytest.approx(10.3)


def test_a_brake_into_something_from_a_guessed_start_waits_and_from_a_known_one_is_refused(policy):
    def blocked(why):
        def plan(state, gripper):
            raise why
        return Goal('pose', '12.000000000', plan, 0.0)
    moving = (HOME, 0 * HOME + 0.5, 0 * HOME)
    guessed = Start(moving, 'reference', 10.0)
    with pytest.raises(Unsettled, match="while it brakes: .*extrapolated"):
        policy.plan(blocked(BrakeBlocked('the plan would hit an obstacle while it brakes: x')), guessed, 0.09)
    # From a plan of ours the controller follows, or from the arm measured: refused as it is.
    for known in (guessed._replace(carries_on=True), Start(moving, 'measured', 10.0)):
        with pytest.raises(BrakeBlocked):
            policy.plan(blocked(BrakeBlocked('while it brakes')), known, 0.09)
    # Any other obstacle (the way to the goal, the goal itself) is refused from a guess too.
    with pytest.raises(Blocked):
        policy.plan(blocked(Blocked('the plan would hit an obstacle: y')), guessed, 0.09)
    assert policy.plan(Goal('pose', '1.000000000', lambda state, gripper: (state, gripper), 0.0), guessed,
                       0.09) == (moving, 0.09)


def test_a_late_plan_is_planned_again_up_to_the_limit_then_answered_as_not_run(policy):
    g = goal()
    start = Start((HOME, 0 * HOME, 0 * HOME), 'measured', 10.0)
    move = trajectory.quintic(HOME, HOME + 0.1, 1.0)
    assert policy.late('10.000000000') is None               # nothing sent yet
    for attempt in range(LATE_REPLANS):
        policy.sent_plan(g, move, start, list('abcdef'), f'{10 + attempt}.000000000', 10.0, 0.1)
        assert policy.late('99.000000000') is None            # another trajectory: not ours
        late = policy.late(f'{10 + attempt}.000000000')
        assert late.again and late.goal is g and g.attempt == attempt + 1
        assert len(policy.sent) == 0                          # never run: nothing carries on from it
    policy.sent_plan(g, move, start, list('abcdef'), '20.000000000', 10.0, 0.1)
    late = policy.late('20.000000000')
    assert not late.again and g.attempt == LATE_REPLANS


def test_a_plan_is_on_time_only_with_room_to_deliver_it():
    start = Start((HOME,) * 3, 'measured', 100.0)
    assert GoalPolicy.on_time(100.0 - DELIVERY - 1e-3, start)
    assert not GoalPolicy.on_time(100.0 - DELIVERY + 1e-3, start)


def test_a_plan_from_rest_that_took_too_long_to_make_starts_later_as_it_is(policy):
    """From rest with no sent plan running after its start (a harvest of many apples, long to plan):
    the arm is still there later, so the plan is moved, not planned again; from a motion it is not."""
    z = 0 * HOME
    rest = Start((HOME, z, z), 'measured', 10.0)
    assert policy.postponed(rest, 12.0) == rest._replace(time=12.0)
    assert policy.postponed(Start((HOME, z + 0.1, z), 'reference', 10.0), 12.0) is None
    assert policy.postponed(rest._replace(carry_from=9.5), 12.0) is None
    move = trajectory.quintic(HOME - 0.2, HOME, 1.0)
    policy.sent_plan(goal(), move, Start((HOME - 0.2, z, z), 'measured', 9.5), list('abcdef'), '9.500000000',
                     9.5, 0.1)
    assert policy.postponed(rest, 12.0) is None                  # the sent plan still runs at 10 s
    assert policy.postponed(rest._replace(time=10.6), 12.0).time == 12.0


def test_the_gripper_is_read_from_the_plan_running_then(policy):
    z = 0 * HOME
    grip = trajectory.stack([trajectory.hold(HOME, 1.0), trajectory.quintic(np.array([0.09]), np.array([0.05]), 1.0)])
    policy.sent_plan(goal(), grip, Start((HOME, z, z), 'measured', 10.0), [*'abcdef', 'gripper_joint'],
                     '10.000000000', 10.0, 0.1)
    assert policy.planned_joint(10.0, 'gripper_joint') == pytest.approx(0.09)
    assert policy.planned_joint(11.0, 'gripper_joint') == pytest.approx(0.05)
    assert policy.planned_joint(9.0, 'gripper_joint') is None and policy.planned_joint(10.5, 'thumb') is None
