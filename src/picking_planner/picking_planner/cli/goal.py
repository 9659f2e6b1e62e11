"""``picking-goal``: send a goal to the planner's action, follow it, report its result.

    picking-goal pose 0.6 0.1 0.4 --rpy 180 0 0 [--method quintic|cubic|lspb|line]
    picking-goal path --pose 0.6 0.1 0.4 --pose 0.5 -0.2 0.5 --rpy 180 0 0 [--method via_lspb|...]
    picking-goal path --arc --pose 0.6 0.1 0.5 --pose 0.6 0.2 0.4 --rpy 180 0 0
    picking-goal pick 0.7 0.15 0.65 --rpy 0 90 0

Positions are metres in base_link; ``--rpy`` is roll, pitch, yaw in degrees (fixed
axes x, y, z), ``--quat`` a quaternion x y z w. ``--method`` sets the planner's
``method`` (pose goals) or ``path_method`` (path goals) parameter for this goal
and after it. Add ``--ros-args -r __ns:=/arm2`` to talk to another arm. Ctrl-C
cancels the goal: the arm brakes to rest within its limits.

Exit codes: 0 the goal succeeded; 1 it was refused (never ran: unreachable, a
bad goal, the controller refused its plan); 2 bad arguments; 3 it ended early
(aborted, superseded by another goal, canceled); 4 timed out.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
import rclpy
from action_msgs.msg import GoalStatus
from geometry_msgs.msg import Pose, PoseArray, PoseStamped
from picking_interfaces.action import FollowPath, MoveToPose, Pick
from rclpy.action import ActionClient
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.utilities import remove_ros_args
from scipy.spatial.transform import Rotation

EXIT_OK, EXIT_REFUSED, EXIT_ARGS, EXIT_FAILED, EXIT_TIMEOUT = 0, 1, 2, 3, 4


def build_parser():
    parser = argparse.ArgumentParser(prog='picking-goal', description=__doc__.split('\n\n')[0],
                                     epilog=__doc__.split('\n\n', 1)[1],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--timeout', type=float, default=30.0, help='s to wait for each answer')
    parser.add_argument('--no-wait', action='store_true', help='return once the planner has taken the goal')
    sub = parser.add_subparsers(dest='kind', required=True)
    for kind in ('pose', 'pick'):
        p = sub.add_parser(kind, help='move the tool to a pose' if kind == 'pose' else
                           'run the Table 1 pick-and-place cycle for a fruit at this pose')
        p.add_argument('xyz', type=float, nargs=3, metavar=('X', 'Y', 'Z'), help='m, base_link')
        _orientation(p)
        if kind == 'pose':
            p.add_argument('--method', help='cubic, quintic, lspb, optimal or line')
    p = sub.add_parser('path', help='pass through several poses')
    p.add_argument('--pose', type=float, nargs=3, action='append', required=True, metavar=('X', 'Y', 'Z'))
    _orientation(p)
    p.add_argument('--method', help='via_lspb, quintic_via, optimal, line or arc')
    p.add_argument('--arc', action='store_true', help='same as --method arc (2 poses: through, end)')
    for p in sub.choices.values():
        p.add_argument('--frame', default='base_link', help='frame of the poses (only base_link)')
    return parser


def _orientation(p):
    g = p.add_mutually_exclusive_group()
    g.add_argument('--rpy', type=float, nargs=3, metavar=('R', 'P', 'Y'), help='degrees')
    g.add_argument('--quat', type=float, nargs=4, metavar=('X', 'Y', 'Z', 'W'))


def quaternion(args):
    """(x, y, z, w) from --rpy (degrees) or --quat; default: the tool pointing down."""
    if args.quat is not None:
        return [float(v) for v in args.quat]
    rpy = args.rpy if args.rpy is not None else (180.0, 0.0, 0.0)
    return Rotation.from_euler('xyz', rpy, degrees=True).as_quat().tolist()


def make_pose(xyz, quat):
    pose = Pose()
    pose.position.x, pose.position.y, pose.position.z = (float(v) for v in xyz)
    pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = quat
    return pose


class GoalClient(Node):
    def spin_until(self, predicate, timeout):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            rclpy.spin_once(self, timeout_sec=0.05)
            result = predicate()
            if result:
                return result
        return None


def set_method(args, node):
    """Set the planner's method parameter for this goal; an exit code on failure, else None."""
    name = 'path_method' if args.kind == 'path' else 'method'
    client = AsyncParameterClient(node, 'picking_planner')
    if not client.wait_for_services(timeout_sec=args.timeout):
        print('picking-goal: no planner answers (is picking-planner running in this namespace?)', file=sys.stderr)
        return EXIT_TIMEOUT
    future = client.set_parameters([Parameter(name, value=args.method)])
    rclpy.spin_until_future_complete(node, future, timeout_sec=args.timeout)
    result = future.result()
    if result is None or not result.results[0].successful:
        reason = result.results[0].reason if result else 'no answer'
        print(f'picking-goal: the planner refused {name}={args.method!r}: {reason}', file=sys.stderr)
        return EXIT_REFUSED
    return None


def make_goal(args, node):
    """The action's name, type and goal message."""
    quat = quaternion(args)
    stamp = node.get_clock().now().to_msg()
    if args.kind == 'path':
        msg = PoseArray(poses=[make_pose(p, quat) for p in args.pose])
    else:
        msg = PoseStamped(pose=make_pose(args.xyz, quat))
    msg.header.frame_id, msg.header.stamp = args.frame, stamp
    if args.kind == 'path':
        return 'follow_path', FollowPath, FollowPath.Goal(path=msg)
    if args.kind == 'pick':
        return 'pick', Pick, Pick.Goal(target=msg)
    return 'move_to_pose', MoveToPose, MoveToPose.Goal(pose=msg)


def run(args, node):
    if args.kind == 'path' and args.arc:
        args.method = 'arc'
    if getattr(args, 'method', None):
        failed = set_method(args, node)
        if failed is not None:
            return failed
    name, action_type, goal = make_goal(args, node)
    action = ActionClient(node, action_type, name)
    if not action.wait_for_server(timeout_sec=args.timeout):
        print(f'picking-goal: no {node.get_namespace().rstrip("/")}/{name} action server '
              '(is picking-planner running in this namespace?)', file=sys.stderr)
        return EXIT_TIMEOUT
    t_sent = time.monotonic()
    progress = {'error': 0.0, 'phase': None}

    def on_feedback(msg):
        fb = msg.feedback
        progress['error'] = max(progress['error'], fb.tracking_error)
        if fb.phase != progress['phase']:
            progress['phase'] = fb.phase
            print(f'  {time.monotonic() - t_sent:6.2f} s  {fb.phase:<22} {fb.time_left:6.2f} s left', flush=True)

    sent = action.send_goal_async(goal, feedback_callback=on_feedback)
    handle = node.spin_until(lambda: sent.done() and sent.result(), args.timeout)
    if handle is None or not handle.accepted:
        print(f'picking-goal: the planner did not take the goal within {args.timeout:g} s', file=sys.stderr)
        return EXIT_TIMEOUT
    print(f'sent: {name} goal {bytes(handle.goal_id.uuid).hex()} taken by the planner '
          f'({1e3 * (time.monotonic() - t_sent):.0f} ms; planner_status names it so)')
    if args.no_wait:
        return EXIT_OK
    result = handle.get_result_async()
    try:
        # The planner ends every goal (its controller's result, or a reason); the bound is a guard only.
        done = node.spin_until(lambda: result.done() and result.result(), 3600.0)
    except KeyboardInterrupt:
        print('canceling: the arm brakes to rest', flush=True)
        cancel = handle.cancel_goal_async()
        node.spin_until(cancel.done, args.timeout)
        done = node.spin_until(lambda: result.done() and result.result(), args.timeout)
        if done is None:
            return EXIT_TIMEOUT
    if done is None:
        print('picking-goal: no result', file=sys.stderr)
        return EXIT_TIMEOUT
    res, took = done.result, time.monotonic() - t_sent
    outcome = {0: 'succeeded', 1: 'refused', 2: 'aborted', 3: 'superseded', 4: 'canceled'}.get(res.outcome, '?')
    print(f'{outcome}: {res.message} ({took:.2f} s after sending; plan {res.duration:.3f} s; '
          f'largest tracking error {progress["error"]:.5f} rad)')
    if done.status == GoalStatus.STATUS_SUCCEEDED:
        return EXIT_OK
    return EXIT_REFUSED if res.outcome == action_type.Result.REFUSED else EXIT_FAILED


def main(argv=None):
    argv = sys.argv if argv is None else argv
    parser = build_parser()
    args = parser.parse_args(remove_ros_args(argv)[1:])
    if not (np.isfinite(args.timeout) and args.timeout > 0):
        parser.error('--timeout must be > 0 s')
    rclpy.init(args=argv)
    node = GoalClient(f'picking_goal_{os.getpid()}')
    try:
        return run(args, node)
    except KeyboardInterrupt:
        return EXIT_TIMEOUT
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
