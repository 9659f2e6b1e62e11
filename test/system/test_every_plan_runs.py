"""Every plan runs as planned, on the shipped configuration: picks, pose goals and path goals with every
method, through the actions, and the controller's commanded reference (``joint_commands``) against the
planned trajectory (``planned_trajectory``) at every tick recorded, and never a "command limited".

The planned trajectory is read here independently of the project's code: scipy's Bernstein polynomial
through each point's position, velocity and acceleration, joint by joint (the quintics a controller
builds between points). Where a plan's acceleration steps, its two points a microsecond apart are the
step: the instant itself is left out (it has two accelerations)."""

import numpy as np
import pytest
from action_msgs.msg import GoalStatus
from geometry_msgs.msg import PoseStamped
from picking_interfaces.action import FollowPath, MoveToPose, Pick
from rosstack import RELIABLE, Client, ensure_rclpy, goal_result, make_pose, send_goal
from scipy.interpolate import BPoly
from scipy.spatial.transform import Rotation
from trajectory_msgs.msg import JointTrajectory

from picking_bringup.stack import Stack
from picking_common.actions import ActionClient
from picking_common.status import stamp_key, status_values
from picking_core.analysis import REFERENCE_BOUND
from picking_core.planning import PATH_METHODS, POSE_METHODS

#: The methods whose acceleration steps: run with the shipped configuration's ``limit_jerk`` off.
STEPPING = {'cubic', 'lspb', 'via_lspb'}
SIDEWAYS = Rotation.from_euler('xyz', [0, 90, 0], degrees=True).as_quat()
DOWN = Rotation.from_euler('xyz', [180, 0, 0], degrees=True).as_quat()


def stamped(xyz, quat=DOWN):
    msg = PoseStamped()
    msg.header.frame_id = 'base_link'
    msg.pose = make_pose(xyz, quat)
    return msg


def since(stamp, origin):
    """Seconds from stamp ``origin`` to ``stamp``, to the nanosecond."""
    return (stamp.sec - origin.sec) + (stamp.nanosec - origin.nanosec) * 1e-9


def deviations(trajectory, commands, until, caught_up=0.0):
    """Largest |commanded - planned| (q, qd, qdd) over the commands stamped while ``trajectory`` ran
    (from its first point, or ``caught_up`` s later, to its last, or to ``until``, the next
    trajectory's stamp), and how many."""
    names = list(trajectory.joint_names)
    t = np.array([p.time_from_start.sec + p.time_from_start.nanosec * 1e-9 for p in trajectory.points])
    rows = {k: np.array([getattr(p, k) for p in trajectory.points])
            for k in ('positions', 'velocities', 'accelerations')}
    plans = [BPoly.from_derivatives(t, np.stack([rows[k][:, j] for k in rows], axis=1)) for j in range(len(names))]
    # Where the acceleration steps (two points a microsecond apart), and the plan's ends (a cubic or LSPB
    # plan starts and ends at full acceleration, the hold before and after at none): two-valued there.
    steps = np.r_[t[0], t[1:][np.diff(t) < 2e-6], t[-1]]
    worst, count = np.zeros(3), 0
    for msg in commands:
        tau = since(msg.header.stamp, trajectory.header.stamp)
        if not (t[0] + caught_up <= tau <= t[-1] and tau < until) or (np.abs(steps - tau) < 2e-6).any():
            continue
        cols = [list(msg.name).index(n) for n in names]
        got = np.array([[msg.position[c] for c in cols], [msg.velocity[c] for c in cols],
                        [msg.effort[c] for c in cols]])
        want = np.array([[p(tau, nu=k) for p in plans] for k in range(3)])
        worst = np.maximum(worst, np.abs(got - want).max(axis=1))
        count += 1
    return worst, count


@pytest.fixture(scope='module')
def shipped(tmp_path_factory):
    """The arm started as the README says (every shipped parameter file), a client and the actions."""
    ensure_rclpy()
    stack = Stack('/as_planned', tmp_path_factory.mktemp('logs'), args={
        'picking-sim': ['-p', 'initial_positions:=[0.0, 0.2, 1.6, 0.0, -0.23, 0.0, 0.09]']})
    client = Client('/as_planned')
    try:
        stack.wait_ready()
        client.wait_ready()
        client.watch_commands()
        trajectories = []
        client.create_subscription(JointTrajectory, 'planned_trajectory', trajectories.append, RELIABLE)
        actions = {name: ActionClient(client, kind, name)
                   for name, kind in (('pick', Pick), ('move_to_pose', MoveToPose), ('follow_path', FollowPath))}
        for name, action in actions.items():
            assert action.wait_for_server(timeout_sec=20.0), f'no {name} server'
        yield client, actions, trajectories
    finally:
        codes = stack.stop()
        client.close()
    assert set(codes.values()) == {0}, codes


def run(client, action, goal):
    handle, _ = send_goal(client, action, goal)
    done = goal_result(client, handle, timeout=60.0)
    assert done.status == GoalStatus.STATUS_SUCCEEDED, done.result.message


def test_every_method_runs_as_planned_and_no_command_is_limited(shipped):
    client, actions, trajectories = shipped
    rng = np.random.default_rng(7)
    picked = 0
    while picked < 3:
        # Apples in the canopy in front of the arm, grasped horizontally.
        apple = stamped(rng.uniform([0.6, -0.2, 0.45], [0.78, 0.3, 0.8]), SIDEWAYS)
        handle, _ = send_goal(client, actions['pick'], Pick.Goal(target=apple))
        done = goal_result(client, handle, timeout=60.0)
        if done.result.outcome == Pick.Result.REFUSED:
            continue                          # out of reach: another apple
        assert done.status == GoalStatus.STATUS_SUCCEEDED, done.result.message
        picked += 1
    poses = ([0.6, 0.1, 0.4], [0.55, -0.15, 0.45])
    for k, method in enumerate(POSE_METHODS):
        client.set_planner_parameters({'limit_jerk': method not in STEPPING, 'method': method,
                                       'path_method': 'optimal'})
        run(client, actions['move_to_pose'], MoveToPose.Goal(pose=stamped(poses[k % 2])))
    path = [make_pose(p, DOWN) for p in ([0.6, 0.1, 0.4], [0.55, -0.1, 0.45], [0.6, -0.2, 0.35])]
    for method in PATH_METHODS:
        client.set_planner_parameters({'limit_jerk': method not in STEPPING, 'path_method': method,
                                       'method': 'optimal'})
        goal = FollowPath.Goal()
        goal.path.header.frame_id = 'base_link'
        goal.path.poses = path[::-1] if method in ('line', 'arc') else path
        run(client, actions['follow_path'], goal)
    with client.lock:
        statuses = [(m.message, status_values(m)) for _, m in client.controller_status]
        commands = [m for _, m in client.commands]
    assert not [text for text, _ in statuses if 'command limited' in text]
    stalled = [text for text, _ in statuses if 'control loop stalled' in text]
    # The trajectories the controller ran: every one carried on from the reference (none bridged).
    accepted = {values['trajectory']: float(values['bridge']) for text, values in statuses
                if text.startswith('trajectory accepted')}
    assert not [text for text, _ in statuses if text.startswith('trajectory accepted') and 'carries on' not in text]
    ran = [(tr, accepted[stamp_key(tr.header.stamp)]) for tr in trajectories if stamp_key(tr.header.stamp) in accepted]
    assert len(ran) >= 3 + len(POSE_METHODS) + len(PATH_METHODS)
    compared = 0
    for (trajectory, caught_up), following in zip(ran, [tr for tr, _ in ran[1:]] + [None]):
        until = np.inf if following is None else since(following.header.stamp, trajectory.header.stamp)
        worst, count = deviations(trajectory, commands, until, caught_up)
        if stalled and (worst > REFERENCE_BOUND).any():
            continue        # a stalled loop delays its trajectory on purpose (the controller said so)
        assert (worst <= REFERENCE_BOUND).all(), (worst, trajectory.joint_names)
        compared += count > 0
    assert compared >= len(ran) // 2
