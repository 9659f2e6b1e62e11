"""The planner's actions (pick, move_to_pose) driven by an rclpy ActionClient, as
`ros2 action send_goal` would: each goal ends in a result that comes from the controller's."""

import pytest
from action_msgs.msg import GoalStatus
from geometry_msgs.msg import PoseStamped
from picking_interfaces.action import MoveToPose, Pick
from rosstack import goal_result as result
from rosstack import make_pose, running_stack, settles_at
from rosstack import send_goal as send

from picking_common.actions import ActionClient
from picking_common.status import status_values

APPLE = [0.55, 0.15, 0.35]


@pytest.fixture(scope='module')
def arm(tmp_path_factory):
    with running_stack('/acts', tmp_path_factory.mktemp('logs')) as (stack, client):
        actions = {name: ActionClient(client, kind, name) for name, kind in (('pick', Pick), ('move_to_pose', MoveToPose))}
        for name, action in actions.items():
            assert action.wait_for_server(timeout_sec=20.0), f'no {name} server'
        yield client, actions
        for action in actions.values():
            client.retire(action)


def stamped(xyz):
    msg = PoseStamped()
    msg.header.frame_id = 'base_link'
    msg.pose = make_pose(xyz)
    return msg


@pytest.mark.load
def test_a_pick_succeeds_through_its_phases(arm):
    client, actions = arm
    since = client.mark()
    handle, feedback = send(client, actions['pick'], Pick.Goal(target=stamped(APPLE)))
    done = result(client, handle)
    assert done.status == GoalStatus.STATUS_SUCCEEDED, done.result.message
    assert done.result.outcome == Pick.Result.SUCCEEDED and done.result.duration > 3.0
    phases = [f.phase for f in feedback]
    for phase in ('P1 approach', 'grasp', 'P0 back home'):
        assert any(phase in p for p in phases), (sorted(set(phases)), len(feedback), feedback[-1].time_left)
    lefts = [f.time_left for f in feedback if f.time_left > 0]
    assert lefts == sorted(lefts, reverse=True)
    # The feedback reports a tracking error: the reference now against the newest measured state, which a stalled
    # simulator leaves behind (seen at 0.13 rad on a loaded machine). The controller's own, each measured state against
    # the command of its instant, stayed within its path tolerance (0.1 rad), or the pick had failed.
    assert max(f.tracking_error for f in feedback) > 0.0
    reached = status_values(client.controller_event(since, 'goal reached'))
    assert 0.0 < float(reached['max_tracking_error']) < 0.1, reached


def test_an_unreachable_goal_is_refused_with_the_reason(arm):
    client, actions = arm
    handle, _ = send(client, actions['move_to_pose'], MoveToPose.Goal(pose=stamped([3.0, 0.0, 0.4])))
    done = result(client, handle)
    assert done.status == GoalStatus.STATUS_ABORTED and done.result.outcome == MoveToPose.Result.REFUSED
    assert 'reach' in done.result.message or 'unreachable' in done.result.message.lower(), done.result.message


@pytest.mark.load
def test_a_newer_goal_supersedes_the_running_one(arm):
    client, actions = arm
    first, _ = send(client, actions['move_to_pose'], MoveToPose.Goal(pose=stamped([0.6, -0.2, 0.45])))
    second, _ = send(client, actions['move_to_pose'], MoveToPose.Goal(pose=stamped([0.6, 0.1, 0.4])))
    assert result(client, first).result.outcome == MoveToPose.Result.SUPERSEDED
    done = result(client, second)
    assert done.result.outcome == MoveToPose.Result.SUCCEEDED, done.result.message
    settles_at(client, [0.6, 0.1, 0.4])


def test_a_canceled_goal_brakes_and_ends_canceled(arm):
    client, actions = arm
    handle, feedback = send(client, actions['move_to_pose'], MoveToPose.Goal(pose=stamped([0.5, -0.3, 0.5])))
    client.wait_for(lambda: any(f.phase not in ('sent', 'accepted') for f in feedback), 10.0, 'the motion')
    cancel = handle.cancel_goal_async()
    client.wait_for(cancel.done, 10.0, 'the cancel response')
    done = result(client, handle)
    assert done.status == GoalStatus.STATUS_CANCELED and done.result.outcome == MoveToPose.Result.CANCELED
