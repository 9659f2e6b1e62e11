"""The shipped UR5e and FR3 brought up as a user would (``picking-stack --arm``), a random tree of 12 apples
hanging in the simulator: a pose goal and a pick through the planner's actions, checked on the arm's own
joint_states with its own kinematics, and the tree harvested, counted by the simulator's fruit world."""

import numpy as np
import pytest
from action_msgs.msg import GoalStatus
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseArray, PoseStamped
from picking_interfaces.action import MoveToPose, Pick
from rosstack import BURST, Client, ensure_rclpy, goal_result, make_pose, send_goal, stop_all
from scipy.spatial.transform import Rotation

from picking_bringup import stack as launcher
from picking_common.actions import ActionClient
from picking_common.status import stamp_key, status_values
from picking_core.harvest import synthetic_tree
from picking_core.kinematics import ArmModel
from picking_description import urdf_path

TREE = (12, 1)                                                   # apples, seed

FACING = Rotation.from_euler('y', 90, degrees=True).as_quat()     # the tool's z along +x


def stamped(xyz, quat):
    msg = PoseStamped()
    msg.header.frame_id = 'base_link'
    msg.pose = make_pose(xyz, quat)
    return msg


@pytest.fixture(scope='module', params=['ur5e', 'fr3'])
def arm(request, tmp_path_factory):
    name = request.param
    ensure_rclpy()
    stack = launcher.Stack(f'/{name}', tmp_path_factory.mktemp(name), arm=name,
                           args={'picking-sim': ['-p', f'tree:=synthetic {TREE[0]} {TREE[1]}']})
    client = Client(f'/{name}')
    client.fruit_events = []
    client.create_subscription(DiagnosticStatus, 'fruit_events', client.fruit_events.append, BURST)
    client.pub_harvest = client.create_publisher(PoseArray, 'harvest_targets', BURST)
    try:
        client.wait_ready(60.0)
        actions = {n: ActionClient(client, kind, n) for n, kind in (('pick', Pick), ('move_to_pose', MoveToPose))}
        for n, action in actions.items():
            assert action.wait_for_server(timeout_sec=20.0), f'no {n} server'
        yield name, ArmModel.from_urdf(urdf_path(name)), client, actions
        for action in actions.values():
            client.retire(action)
    finally:
        client.close()
        codes = stop_all(stack.processes)
    assert set(codes) == {0}, codes


def tool_pose(model, client):
    state = client.states[-1][1]
    q = [state.position[list(state.name).index(n)] for n in model.joint_names]
    return model.fk(q)


def test_joint_states_name_the_arms_own_joints(arm):
    _, model, client, _ = arm
    client.wait_for(lambda: client.states, 10.0, 'joint_states')
    assert tuple(client.states[-1][1].name) == model.all_joint_names


def test_the_tree_is_harvested_into_the_box_by_the_simulators_count(arm):
    _, _, client, _ = arm
    n, seed = TREE
    tree = PoseArray(poses=[make_pose(T[:3, 3], Rotation.from_matrix(T[:3, :3]).as_quat())
                            for T in synthetic_tree(n, seed)])
    tree.header.frame_id, tree.header.stamp = 'base_link', client.get_clock().now().to_msg()
    key = stamp_key(tree.header.stamp)
    since = client.mark()
    client.send(client.pub_harvest, tree)
    client.planner_answer(since, timeout=30.0)   # (sent again while unanswered: see planner_answer)
    said = lambda: [status_values(m) for _, m in client.planner_status if status_values(m).get('goal') == key]  # noqa: E731
    end = client.wait_for(lambda: next((v for v in said() if v.get('state') in (
        'succeeded', 'aborted', 'refused', 'superseded', 'canceled')), None), 180.0, 'the end of the harvest')
    assert end['state'] == 'succeeded', end
    picked = [v for v in said() if v.get('apple_state') == 'picked']
    # (A goal sent again has its statuses said again: each apple counts once.) Every apple but at most one picked:
    # on a loaded host a neighbour knocked on the way can swing into the fingers' path, and that closing is missed.
    apples = {v['apple'] for v in picked}
    assert apples <= {str(k) for k in range(n)} and len(apples) >= n - 1, end
    assert all(v['verified'] == 'True' for v in picked), picked
    # The planner's claims are the simulator's count.
    client.wait_for(lambda: client.fruit_events and
                    int(status_values(client.fruit_events[-1])['in_the_box']) == len(apples),
                    5.0, f'{len(apples)} apples in the box by the simulator\'s count, as the planner says')


def test_a_pose_goal_reaches_its_pose(arm):
    _, model, client, actions = arm
    target = [0.5, 0.2, 0.4]
    down = Rotation.from_euler('x', 180, degrees=True).as_quat()
    handle, _ = send_goal(client, actions['move_to_pose'], MoveToPose.Goal(pose=stamped(target, down)))
    done = goal_result(client, handle)
    assert done.status == GoalStatus.STATUS_SUCCEEDED, done.result.message
    client.wait_for(lambda: np.linalg.norm(tool_pose(model, client)[:3, 3] - target) < 2e-3, 5.0,
                    'the tool within 2 mm of the target')
    assert np.allclose(tool_pose(model, client)[:3, :3], Rotation.from_quat(down).as_matrix(), atol=1e-2)


def test_a_pick_runs_its_cycle_and_comes_home(arm):
    """A pick where no apple hangs (the simulator has a tree; its nearest apple hangs 19 cm away, out of reach of
    the fingers even if one left on it swings): the whole cycle runs and comes home, and the pick ends aborted, as
    the measured fingers closed on air say."""
    name, model, client, actions = arm
    apple = [0.55, 0.05, 0.45]
    assert min(np.linalg.norm(T[:3, 3] - apple) for T in synthetic_tree(*TREE)) > 0.15
    handle, feedback = send_goal(client, actions['pick'], Pick.Goal(target=stamped(apple, FACING)))
    done = goal_result(client, handle, timeout=40.0)
    assert done.status == GoalStatus.STATUS_ABORTED and 'not in the fingers' in done.result.message, \
        done.result.message
    phases = {f.phase for f in feedback}
    assert any('grasp' in p for p in phases) and any('P0 back home' in p for p in phases), phases
    # The controller's tracking error, as it saw it: reported, and bounded. (A host that stalls the simulator's
    # servo loop for 0.13 s delays joint_states while this arm's joints move at up to 1.6 rad/s: its path tolerance
    # of 0.1 rad is excused then, and the feedback shows up to about 0.2 rad.)
    assert 0.0 < max(f.tracking_error for f in feedback) < 0.3
