"""The planner driving a UR5e through standard ros2_control interfaces, as it would a real one: a joint
trajectory controller's FollowJointTrajectory action and controller_state, and a gripper action controller's
GripperCommand (fakes written from ros2_controllers' documentation: fake_controllers.py). A pose goal, a
pick and a harvest; the arm's trajectories name its six joints only, and the gripper is commanded on its
own action, its answers awaited."""

import threading

import numpy as np
import pytest
import yaml
from action_msgs.msg import GoalStatus
from fake_controllers import GripperActionController, JointTrajectoryController
from geometry_msgs.msg import PoseArray, PoseStamped
from picking_interfaces.action import MoveToPose, Pick
from rclpy.executors import MultiThreadedExecutor
from rosstack import BURST, Client, ensure_rclpy, goal_result, make_pose, send_goal, stop_all
from scipy.spatial.transform import Rotation

from picking_bringup.shipped import config_dir
from picking_bringup.stack import NodeProcess
from picking_common.actions import ActionClient
from picking_common.status import stamp_key, status_values
from picking_core.kinematics import ArmModel
from picking_description import urdf_path

NS = '/std'
UR5E = ArmModel.from_urdf(urdf_path('ur5e'))
HOME = yaml.safe_load((config_dir() / 'arms' / 'ur5e.yaml').read_text())['/**/picking_planner'][
    'ros__parameters']['home_positions']
FACING = Rotation.from_euler('y', 90, degrees=True).as_quat()
CONTROLLER, GRIPPER = 'scaled_joint_trajectory_controller', 'gripper_controller'


@pytest.fixture(scope='module')
def arm(tmp_path_factory):
    import rclpy
    ensure_rclpy()
    node = rclpy.create_node('fake_ur5e', namespace=NS)
    gripper = GripperActionController(node, GRIPPER, 'robotiq_finger_joint', 0.09)
    jtc = JointTrajectoryController(node, CONTROLLER, UR5E.joint_names, HOME, gripper=gripper)
    executor = MultiThreadedExecutor(num_threads=2)
    executor.add_node(node)
    spinning = threading.Thread(target=executor.spin, daemon=True)
    spinning.start()
    log_dir = tmp_path_factory.mktemp('logs')
    config = config_dir()
    files = [f for name in ('planner.yaml', 'pick_cycle.yaml', 'arms/ur5e.yaml')
             for f in ('--params-file', str(config / name))]
    planner = NodeProcess('picking-planner', [
        '--ros-args', '-r', f'__ns:={NS}', *files, '-p', f'urdf_path:={urdf_path("ur5e")}',
        '-p', f'controller_action:={CONTROLLER}/follow_joint_trajectory',
        '-p', f'controller_state:={CONTROLLER}/controller_state', '-p', f'gripper_action:={GRIPPER}/gripper_cmd',
        '-p', 'speed_scale:=0.5'], log_dir / 'planner.log')
    client = Client(NS)
    try:
        actions = {n: ActionClient(client, kind, n) for n, kind in (('pick', Pick), ('move_to_pose', MoveToPose))}
        for n, action in actions.items():
            assert action.wait_for_server(timeout_sec=60.0), f'no {n} server'
        client.wait_for(lambda: client.states, 20.0, 'joint_states')
        client.pub_harvest = client.create_publisher(PoseArray, 'harvest_targets', BURST)
        yield client, actions, jtc, gripper, planner
        for action in actions.values():
            client.retire(action)
    finally:
        client.close()
        codes = stop_all([planner])
        executor.shutdown()
        node.destroy_node()
    assert codes == [0], planner.output()[-3000:]


def stamped(xyz, quat):
    msg = PoseStamped()
    msg.header.frame_id = 'base_link'
    msg.pose = make_pose(xyz, quat)
    return msg


def arm_only(jtc, since):
    """Every goal the controller accepted since ``since`` named the arm's six joints only."""
    return all(list(h.request.trajectory.joint_names) == list(UR5E.joint_names) for h in jtc.accepted[since:])


def test_a_pose_goal_goes_to_the_arm_controller_with_the_arms_joints_only(arm):
    client, actions, jtc, gripper, planner = arm
    since = len(jtc.accepted)
    target = [0.5, 0.2, 0.4]
    down = Rotation.from_euler('x', 180, degrees=True).as_quat()
    handle, _ = send_goal(client, actions['move_to_pose'], MoveToPose.Goal(pose=stamped(target, down)))
    done = goal_result(client, handle, timeout=30.0)
    assert done.status == GoalStatus.STATUS_SUCCEEDED, done.result.message
    assert len(jtc.accepted) > since and arm_only(jtc, since)
    assert np.linalg.norm(UR5E.fk(jtc.q)[:3, 3] - target) < 1e-3


def test_a_pick_closes_and_opens_the_gripper_on_its_action(arm):
    client, actions, jtc, gripper, planner = arm
    since, commands = len(jtc.accepted), len(gripper.commands)
    handle, feedback = send_goal(client, actions['pick'], Pick.Goal(target=stamped([0.6, 0.15, 0.6], FACING)))
    done = goal_result(client, handle, timeout=60.0)
    assert done.status == GoalStatus.STATUS_SUCCEEDED, done.result.message
    assert arm_only(jtc, since)
    # Closed on the apple (the fake's stall is an abort, as gripper_action_controller's without allow_stalling),
    # then opened over the box; and the arm back home.
    sent = gripper.commands[commands:]
    assert len(sent) >= 2 and sent[-2] < 0.07 < sent[-1], sent
    assert np.abs(jtc.q - HOME).max() < 1e-3


def test_a_harvest_picks_every_apple_counted_by_the_gripper(arm):
    client, actions, jtc, gripper, planner = arm
    since, commands = len(jtc.accepted), len(gripper.commands)
    apples = [[0.6, 0.1 * k - 0.05, 0.55] for k in range(3)]
    tree = PoseArray(poses=[make_pose(a, FACING) for a in apples])
    tree.header.frame_id, tree.header.stamp = 'base_link', client.get_clock().now().to_msg()
    key = stamp_key(tree.header.stamp)
    mark = client.mark()
    client.send(client.pub_harvest, tree)
    client.planner_answer(mark, timeout=30.0)   # (sent again while unanswered: see planner_answer)

    def statuses():
        return [status_values(m) | {'message': m.message} for _, m in client.planner_status
                if status_values(m).get('goal') == key]
    end = client.wait_for(lambda: next((s for s in statuses() if s.get('state') in (
        'succeeded', 'refused', 'aborted', 'superseded', 'canceled')), None), 120.0, 'the end of the harvest')
    assert end['state'] == 'succeeded', end['message']
    picked = [s for s in statuses() if s.get('apple_state') == 'picked']
    # (A goal sent again has its statuses said again: each apple counts once.)
    assert {s['apple'] for s in picked} == {'0', '1', '2'}, picked
    assert all(s['verified'] == 'True' for s in picked), picked
    assert arm_only(jtc, since)
    assert len(gripper.commands) - commands >= 6          # a close and an open for each apple


def test_picking_controller_serves_the_gripper_action_too(tmp_path):
    """The project's own stack as one configuration of the standard route: the planner sends the arm's joints to
    picking-controller's follow_joint_trajectory and closes the fingers on its gripper_cmd; a harvest of a tree
    hanging in the simulator puts every apple in the box (the fingers stall on each apple, the planner takes the
    stall as the grasp and judges each apple by the gripper's word)."""
    from diagnostic_msgs.msg import DiagnosticStatus
    from rosstack import running_stack
    from trajectory_msgs.msg import JointTrajectory

    from picking_core.harvest import synthetic_tree
    n, seed = 3, 0
    with running_stack('/ownstd', tmp_path, sim_args=('-p', f'tree:=synthetic {n} {seed}'),
                       planner_args=('-p', 'gripper_action:=gripper_cmd')) as (stack, client):
        events, sent = [], []
        client.create_subscription(DiagnosticStatus, 'fruit_events', events.append, BURST)
        client.create_subscription(JointTrajectory, 'planned_trajectory', sent.append, BURST)
        pub = client.create_publisher(PoseArray, 'harvest_targets', BURST)
        tree = PoseArray(poses=[make_pose(T[:3, 3], Rotation.from_matrix(T[:3, :3]).as_quat())
                                for T in synthetic_tree(n, seed)])
        tree.header.frame_id, tree.header.stamp = 'base_link', client.get_clock().now().to_msg()
        key = stamp_key(tree.header.stamp)
        since = client.mark()
        client.send(pub, tree)
        client.planner_answer(since, timeout=30.0)   # (sent again while unanswered)
        said = lambda: [status_values(m) for _, m in client.planner_status if status_values(m).get('goal') == key]  # noqa: E731
        end = client.wait_for(lambda: next((v for v in said() if v.get('state') in (
            'succeeded', 'aborted', 'refused', 'superseded', 'canceled')), None), 120.0, 'the end of the harvest')
        assert end['state'] == 'succeeded', end
        client.wait_for(lambda: events and int(status_values(events[-1])['in_the_box']) == n, 5.0,
                        f'{n} apples in the box by the simulator\'s count')
        picked = [v for v in said() if v.get('apple_state') == 'picked']
        # (A goal sent again has its statuses said again: each apple counts once.)
        assert {v['apple'] for v in picked} == {str(k) for k in range(n)}, picked
        assert all(v['verified'] == 'True' for v in picked), picked
        # Every trajectory sent named the arm's joints only; the gripper took every command.
        assert sent and all('gripper_joint' not in m.joint_names for m in sent), [m.joint_names for m in sent]
        assert 'gripper command refused' not in stack.controller.output()
