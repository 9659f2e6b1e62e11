"""Action goals in the controller's logic, without ROS: every goal ends in one outcome, with the
code and the reason a FollowJointTrajectory client expects; tolerances per goal; cancel brakes."""

import numpy as np
import pytest

from picking_controller.core import ControllerCore, ErrorCode, JointTolerances, Tolerances

NAMES = ['a', 'b', 'gripper']


def core(**tol):
    c = ControllerCore(NAMES, [-3, -3, 0], [3, 3, 0.1], [2, 2, 0.3], [10, 10, 3], Tolerances(**tol),
                       optional=['gripper'])
    c.on_state([0.0, 0.0, 0.05], [0.0, 0.0, 0.0], 0.0, now=0.0)
    return c


def run(c, start, end, follow=True, dt=1e-3):
    """Command and feed back (a perfect servo when ``follow``) from ``start`` to ``end``; the events
    that end goals."""
    ended = []
    for now in np.arange(start, end, dt):
        ref, events = c.command(now)
        q = ref[0] if follow else c.tracker.q
        events += c.on_state(q, ref[1] if follow else np.zeros(3), now, now=now)
        events += c.tick(now)
        ended += [e for e in events if e.outcome is not None]
    return ended


def test_a_goal_that_arrives_succeeds_once():
    c = core()
    assert c.load(['a', 'b'], [1.0], [[0.5, 0.2]], [], [], 0.0, now=0.0, goal='g1').level == 'OK'
    ended = run(c, 0.0, 1.5)
    assert [(e.goal, e.outcome.status, e.outcome.code) for e in ended] == [('g1', 'succeeded', ErrorCode.SUCCESSFUL)]
    assert c.goal is None


def test_a_new_trajectory_preempts_the_running_goal_and_says_so():
    c = core()
    c.load(['a', 'b'], [2.0], [[1.0, 0.0]], [], [], 0.0, now=0.0, goal='g1')
    run(c, 0.0, 0.5)
    c.load(['a', 'b'], [1.0], [[0.5, 0.0]], [], [], 0.0, now=0.5, goal='g2')
    ended = run(c, 0.5, 2.0)
    assert [(e.goal, e.outcome.status) for e in ended] == [('g1', 'aborted'), ('g2', 'succeeded')]
    assert ended[0].outcome.code == ErrorCode.INVALID_GOAL and 'preempted' in ended[0].outcome.text
    # One from the topic (no goal) preempts as well, and says where it came from.
    c.load(['a', 'b'], [2.0], [[1.0, 0.0]], [], [], 0.0, now=2.0, goal='g3')
    c.load(['a', 'b'], [1.0], [[0.0, 0.0]], [], [], 0.0, now=2.1)
    ended = run(c, 2.1, 2.2)
    assert [e.goal for e in ended] == ['g3'] and 'joint_trajectory topic' in ended[0].outcome.text


def test_refusals_carry_the_code_of_their_reason():
    c = core()
    assert c.load(['a', 'x'], [1.0], [[0.5, 0.5]], [], [], 0.0, now=0.0, goal='j').outcome.code == \
        ErrorCode.INVALID_JOINTS
    assert c.load(['a', 'b'], [1.0], [[9.0, 0.0]], [], [], 0.0, now=0.0, goal='p').outcome.code == \
        ErrorCode.INVALID_GOAL
    old = c.load(['a', 'b'], [0.5], [[0.1, 0.0]], [], [], start=1.0, now=2.0, goal='o')
    assert old.goal == 'o' and old.outcome.code == ErrorCode.OLD_HEADER_TIMESTAMP
    assert old.outcome.status == 'aborted' and 'in the past' in old.outcome.text


def test_cancel_brakes_to_rest_within_the_limits_then_ends_as_canceled():
    c = core()
    c.load(['a', 'b'], [1.0], [[1.0, 0.0]], [], [], 0.0, now=0.0, goal='g')
    run(c, 0.0, 0.5)
    moving = c.reference(0.5)[1][0]
    assert moving > 1.0
    accepted, events = c.cancel('g', 0.5)
    assert accepted and 'braking' in events[0].message and events[0].outcome is None
    sent = [c.command(0.5 + k * 1e-3)[0] for k in range(400)]
    qdd = np.array([s[2][0] for s in sent])
    assert np.abs(qdd).max() <= 10.0 + 1e-9                       # no snap
    assert abs(sent[-1][1][0]) < 1e-9                              # at rest
    ended = run(c, 0.9, 1.0)
    assert [(e.goal, e.outcome.status) for e in ended] == [('g', 'canceled')]
    assert c.cancel('g', 1.0) == (False, [])                      # ended: nothing to cancel


def test_a_goal_waiting_for_its_start_is_canceled_at_once():
    c = core()
    c.load(['a', 'b'], [1.0], [[0.5, 0.0]], [], [], start=5.0, now=0.0, goal='later')
    prepared = c.prepare(['a', 'b'], [1.0], [[0.5, 0.0]], [], [], 5.0, now=0.0, splice_delay=0.1, goal='next')
    c.commit(prepared, now=0.0)
    accepted, events = c.cancel('next', 0.05)
    assert accepted and events[0].outcome.status == 'canceled'
    assert [e.goal for e in c.schedule.entries] == [None]


def test_goal_tolerances_override_the_defaults_joint_by_joint():
    base = JointTolerances.default(Tolerances(path=0.1, goal=0.005), 3)
    tol = base.overridden(NAMES, path=[('a', 0.5, 0.0, 0.0), ('b', -1.0, 0.2, 0.0)],
                          goal=[('gripper', 0.01, 0.0, 0.0)], goal_time=0.5)
    assert tol.path.tolist() == [0.5, np.inf, 0.1]
    assert tol.path_velocity.tolist() == [np.inf, 0.2, np.inf] and tol.checks_path_velocity
    assert tol.goal.tolist() == [0.005, 0.005, 0.01] and tol.goal_time == 0.5
    assert base.overridden(NAMES, goal_time=0.0).goal_time == base.goal_time
    for bad, words in (({'path': [('x', 0.1, 0, 0)]}, 'unknown joint'), ({'goal': [('a', -2.0, 0, 0)]}, '-1 for no'),
                       ({'path': [('a', 0.1, 0, 1.0)]}, 'no acceleration'), ({'goal_time': -1.0}, 'goal_time')):
        with pytest.raises(ValueError, match=words):
            base.overridden(NAMES, **bad)


def test_a_goal_runs_under_its_own_tolerances():
    c = core()
    tight = c.default_tolerances.overridden(NAMES, path=[('a', 0.001, 0.0, 0.0)])
    c.load(['a', 'b'], [1.0], [[0.5, 0.0]], [], [], 0.0, now=0.0, goal='tight', tolerances=tight)
    ended = run(c, 0.0, 0.5, follow=False)                          # the arm does not move
    assert ended[0].outcome.code == ErrorCode.PATH_TOLERANCE_VIOLATED and 'tolerance 0.001' in ended[0].outcome.text
    # A loose goal tolerance and time: an arm stuck 0.04 rad short still fails, 0.2 s after the end.
    c = core()
    loose = c.default_tolerances.overridden(NAMES, path=[('a', -1, 0, 0)], goal=[('a', 0.03, 0, 0)], goal_time=0.2)
    c.load(['a', 'b'], [0.5], [[0.04, 0.0]], [], [], 0.0, now=0.0, goal='loose', tolerances=loose)
    ended = run(c, 0.0, 1.0, follow=False)
    assert ended[0].outcome.code == ErrorCode.GOAL_TOLERANCE_VIOLATED
    assert 'tolerance 0.03' in ended[0].outcome.text and '0.2 s after the end' in ended[0].outcome.text


def test_lost_feedback_aborts_the_running_goal():
    c = core()
    c.load(['a', 'b'], [2.0], [[1.0, 0.0]], [], [], 0.0, now=0.0, goal='g')
    c.command(0.1)
    events = c.tick(1.0)                                            # no joint_states for 1 s
    assert events[0].goal == 'g' and events[0].outcome.status == 'aborted'
    assert 'feedback lost' in events[0].outcome.text
