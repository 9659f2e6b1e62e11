"""The controller's follow_joint_trajectory action, driven as MoveIt or `ros2 action send_goal`
would: an rclpy ActionClient of control_msgs/action/FollowJointTrajectory."""

import time

import numpy as np
import pytest
from action_msgs.msg import GoalStatus
from builtin_interfaces.msg import Duration
from control_msgs.action import FollowJointTrajectory
from control_msgs.msg import JointTolerance
from rclpy.duration import Duration as Span
from rosstack import ARM_JOINTS, HOME, goal_result, largest_step, running_stack
from rosstack import send_goal as send
from trajectory_msgs.msg import JointTrajectoryPoint

from picking_common.actions import ActionClient

Result = FollowJointTrajectory.Result


@pytest.fixture(scope='module')
def arm(tmp_path_factory):
    with running_stack('/fjt', tmp_path_factory.mktemp('logs')) as (stack, client):
        action = ActionClient(client, FollowJointTrajectory, 'follow_joint_trajectory')
        assert action.wait_for_server(timeout_sec=20.0), 'no follow_joint_trajectory server'
        yield client, action
        client.retire(action)


def goal(offsets, seconds, names=ARM_JOINTS, **extra):
    """From HOME to HOME + ``offsets`` (rad) in ``seconds``, at rest at both ends."""
    g = FollowJointTrajectory.Goal(**extra)
    g.trajectory.joint_names = list(names)
    end = JointTrajectoryPoint(positions=[float(h + o) for h, o in zip(HOME, offsets)],
                               velocities=[0.0] * len(names), time_from_start=Duration(
                                   sec=int(seconds), nanosec=int(seconds % 1 * 1e9)))
    g.trajectory.points = [end]
    return g


def result(client, handle, timeout=20.0):
    done = goal_result(client, handle, timeout)
    return done.status, done.result


def moved(client, angle):
    """Until the waist has turned ``angle`` rad from HOME."""
    end = time.monotonic() + 10.0
    while abs(client.last_positions()[0] - HOME[0]) < angle:
        assert time.monotonic() < end, f'the waist did not turn {angle} rad'
        time.sleep(0.01)


@pytest.fixture(autouse=True)
def from_home(arm):
    """Every test starts with the arm at rest at HOME, whatever the one before it left."""
    client, action = arm
    if np.abs(np.subtract(client.last_positions()[:6], HOME)).max() > 1e-3:
        handle, _ = send(client, action, goal([0.0] * 6, 1.5))
        assert result(client, handle)[0] == GoalStatus.STATUS_SUCCEEDED


def test_a_goal_succeeds_with_feedback_of_desired_actual_and_error(arm):
    client, action = arm
    handle, feedback = send(client, action, goal([0.3, -0.2, 0.2, 0.0, 0.1, 0.0], 1.5))
    status, res = result(client, handle)
    assert status == GoalStatus.STATUS_SUCCEEDED and res.error_code == Result.SUCCESSFUL, res.error_string
    assert len(feedback) >= 5                                   # 20 Hz over 1.5 s
    fb = feedback[len(feedback) // 2]
    assert ARM_JOINTS == list(fb.joint_names)[:6]
    n = len(fb.joint_names)
    assert len(fb.desired.positions) == len(fb.actual.positions) == len(fb.error.positions) == n
    assert np.allclose(np.subtract(fb.desired.positions, fb.actual.positions), fb.error.positions)
    assert max(abs(e) for e in fb.error.positions) < 0.05       # the servo tracks


@pytest.mark.parametrize('make, code, words', [
    (lambda: goal([0.0, 0.0, 9.0, 0.0, 0.0, 0.0], 1.0), Result.INVALID_GOAL, 'beyond its limit'),
    (lambda: goal([0.1] * 6, 1.0, path_tolerance=[JointTolerance(name='nope', position=0.1)]), Result.INVALID_GOAL,
     'unknown joint'),
])
def test_an_invalid_goal_ends_aborted_with_its_code_and_reason(arm, make, code, words):
    client, action = arm
    handle, _ = send(client, action, make())
    status, res = result(client, handle)
    assert status == GoalStatus.STATUS_ABORTED and res.error_code == code and words in res.error_string


def test_a_goal_naming_an_unknown_joint_is_rejected_when_sent(arm):
    # As a joint trajectory controller does; controller_status says why (a rejection carries no reason).
    client, action = arm
    since = time.monotonic()
    future = action.send_goal_async(goal([0.1] * 6, 1.0, names=ARM_JOINTS[:5] + ['nope']))
    handle = client.wait_for(lambda: future.done() and future.result(), 10.0, 'the goal response')
    assert not handle.accepted
    client.wait_for(lambda: any('unknown joints' in m.message for t, m in client.controller_status if t >= since),
                    10.0, 'controller_status to say why')


def test_controller_state_gives_the_reference_the_measurement_and_their_difference(arm):
    from control_msgs.msg import JointTrajectoryControllerState
    client, action = arm
    states = []
    sub = client.create_subscription(JointTrajectoryControllerState, 'controller_state', states.append, 10)
    try:
        handle, _ = send(client, action, goal([0.3, 0.0, 0.0, 0.0, 0.0, 0.0], 1.0))
        assert result(client, handle)[0] == GoalStatus.STATUS_SUCCEEDED
        client.wait_for(lambda: len(states) > 20, 10.0, 'controller_state')
    finally:
        client.retire(sub)
    s = states[-1]
    assert list(s.joint_names)[:6] == ARM_JOINTS
    n = len(s.joint_names)
    assert len(s.reference.positions) == len(s.reference.velocities) == len(s.reference.accelerations) == n
    assert np.allclose(np.subtract(s.reference.positions, s.feedback.positions), s.error.positions)
    assert abs(s.reference.positions[0] - (HOME[0] + 0.3)) < 1e-6


def test_an_old_goal_ends_with_old_header_timestamp(arm):
    client, action = arm
    g = goal([0.1] * 6, 0.5)
    g.trajectory.header.stamp = (client.get_clock().now() - Span(seconds=5)).to_msg()
    handle, _ = send(client, action, g)
    status, res = result(client, handle)
    assert status == GoalStatus.STATUS_ABORTED and res.error_code == Result.OLD_HEADER_TIMESTAMP, res.error_string


def test_a_new_goal_preempts_the_running_one_without_a_jump(arm):
    client, action = arm
    mark = client.mark()
    first, _ = send(client, action, goal([0.6, 0.0, 0.0, 0.0, 0.0, 0.0], 3.0))
    moved(client, 0.1)
    second, _ = send(client, action, goal([-0.3, 0.0, 0.0, 0.0, 0.0, 0.0], 2.0))
    status, res = result(client, first)
    assert status == GoalStatus.STATUS_ABORTED and 'preempted' in res.error_string
    status, res = result(client, second)
    assert status == GoalStatus.STATUS_SUCCEEDED, res.error_string
    assert largest_step(client, mark) < 0.01                    # rad per joint_states period: no jump


def test_cancel_brakes_to_rest_and_ends_canceled(arm):
    client, action = arm
    mark = client.mark()
    handle, _ = send(client, action, goal([0.8, 0.0, 0.0, 0.0, 0.0, 0.0], 2.0))
    moved(client, 0.2)
    cancel = handle.cancel_goal_async()
    client.wait_for(cancel.done, 10.0, 'the cancel response')
    assert len(cancel.result().goals_canceling) == 1
    status, res = result(client, handle)
    assert status == GoalStatus.STATUS_CANCELED, res.error_string
    stopped = client.last_positions()[0]
    assert HOME[0] < stopped < HOME[0] + 0.8                    # stopped on the way
    assert largest_step(client, mark) < 0.01
