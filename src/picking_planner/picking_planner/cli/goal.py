"""``picking-goal``: send a goal to the planner's action, follow it, report its result.

    picking-goal pose 0.6 0.1 0.4 --rpy 180 0 0
    picking-goal pose 0.6 -0.1 0.45 --method line
    picking-goal path --pose 0.55 -0.1 0.45 --pose 0.5 -0.25 0.5 --method via_lspb
    picking-goal path --arc --pose 0.55 -0.1 0.5 --pose 0.5 0.05 0.45
    picking-goal pick 0.7 0.15 0.65 --rpy 0 90 0
    picking-goal stop

Positions are metres in base_link; ``--rpy`` is roll, pitch, yaw in degrees (fixed
axes x, y, z), ``--quat`` a quaternion x y z w. ``--method`` chooses the method
for this goal only (the planner's ``method`` / ``path_method`` parameters are the
default). Add ``--ros-args -r __ns:=/arm2`` to talk to another arm. Ctrl-C
cancels the goal: the arm brakes to rest within its limits; ``stop`` cancels
every goal of the planner.

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
from rclpy.utilities import remove_ros_args
from scipy.spatial.transform import Rotation

from ..planning import PATH_METHODS, POSE_METHODS

EXIT_OK, EXIT_REFUSED, EXIT_ARGS, EXIT_FAILED, EXIT_TIMEOUT = 0, 1, 2, 3, 4
#: s of discovery before picking-goal says what it waits for.
DISCOVERY = 2.0


def build_parser():
    # The options every subcommand takes, before or after it (`picking-goal pose ... --timeout 5`).
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument('--timeout', type=float, default=argparse.SUPPRESS,
                        help='s to wait for the planner to take the goal (default: 30)')
    common.add_argument('--no-wait', action='store_true', default=argparse.SUPPRESS,
                        help='return once the planner has taken the goal')
    parser = argparse.ArgumentParser(prog='picking-goal', description=__doc__.split('\n\n')[0],
                                     epilog=__doc__.split('\n\n', 1)[1], parents=[common],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest='kind', required=True)
    for kind in ('pose', 'pick'):
        p = sub.add_parser(kind, parents=[common], help='move the tool to a pose' if kind == 'pose' else
                           'run the Table 1 pick-and-place cycle for a fruit at this pose')
        # (Three positionals: argparse cannot show one positional with a tuple metavar.)
        for axis in 'xyz':
            p.add_argument(axis, type=float, metavar=axis.upper(), help=f'{axis} of the tool, m in base_link')
        _orientation(p)
        if kind == 'pose':
            p.add_argument('--method', choices=POSE_METHODS, help="for this goal only (default: the planner's)")
    p = sub.add_parser('path', parents=[common], help='pass through several poses')
    p.add_argument('--pose', type=float, nargs=3, action='append', required=True, metavar=('X', 'Y', 'Z'),
                   help='a pose to pass, m in base_link (repeat it)')
    _orientation(p)
    p.add_argument('--method', choices=PATH_METHODS, help="for this goal only (default: the planner's)")
    p.add_argument('--arc', action='store_true', help='same as --method arc (2 poses: through, end)')
    for p in sub.choices.values():
        p.add_argument('--frame', default='base_link', help='frame of the poses (only base_link)')
    sub.add_parser('stop', parents=[common], help='cancel every goal of the planner (the arm brakes to rest)')
    return parser


def _orientation(p):
    g = p.add_mutually_exclusive_group()
    g.add_argument('--rpy', type=float, nargs=3, metavar=('R', 'P', 'Y'),
                   help='roll, pitch, yaw of the tool in degrees (default: 180 0 0, pointing down)')
    g.add_argument('--quat', type=float, nargs=4, metavar=('X', 'Y', 'Z', 'W'), help="the tool's orientation")


def quaternion(args):
    """(x, y, z, w) from --rpy (degrees) or --quat; default: the tool pointing down."""
    if args.quat is not None:
        q = np.asarray(args.quat, float)
        if not (np.all(np.isfinite(q)) and np.linalg.norm(q) > 1e-9):
            raise ValueError('--quat must be finite and not zero')
        return (q / np.linalg.norm(q)).tolist()
    rpy = args.rpy if args.rpy is not None else (180.0, 0.0, 0.0)
    return Rotation.from_euler('xyz', rpy, degrees=True).as_quat().tolist()


def unit_hint(args):
    """A note when --rpy looks like radians (every value within 2 pi, one not a whole degree)."""
    rpy = getattr(args, 'rpy', None)
    if rpy is not None and max(abs(v) for v in rpy) < 7.0 and any(abs(v - round(v)) > 1e-6 for v in rpy):
        return (f'note: --rpy takes degrees; {" ".join(f"{v:g}" for v in rpy)} look like radians '
                f'(in degrees: {" ".join(f"{np.degrees(v):.1f}" for v in rpy)})')
    return None


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


def make_goal(args, node):
    """The action's name, type and goal message."""
    quat = quaternion(args)
    stamp = node.get_clock().now().to_msg()
    if args.kind == 'path':
        msg = PoseArray(poses=[make_pose(p, quat) for p in args.pose])
    else:
        msg = PoseStamped(pose=make_pose((args.x, args.y, args.z), quat))
    msg.header.frame_id, msg.header.stamp = args.frame, stamp
    method = getattr(args, 'method', None) or ''
    if args.kind == 'path':
        return 'follow_path', FollowPath, FollowPath.Goal(path=msg, method=method)
    if args.kind == 'pick':
        return 'pick', Pick, Pick.Goal(target=msg)
    return 'move_to_pose', MoveToPose, MoveToPose.Goal(pose=msg, method=method)


def wait_for_server(node, action, name, timeout):
    """Wait for the planner's action server; after a couple of seconds of discovery, say what is awaited."""
    where = f'{node.get_namespace().rstrip("/")}/{name}'
    if action.wait_for_server(timeout_sec=min(DISCOVERY, timeout)):
        return True
    print(f'picking-goal: no {where} action server yet (is picking-planner running in this namespace, with this '
          f'ROS_DOMAIN_ID?); waiting up to {timeout:g} s', file=sys.stderr, flush=True)
    if timeout > DISCOVERY and action.wait_for_server(timeout_sec=timeout - DISCOVERY):
        return True
    print(f'picking-goal: no {where} action server', file=sys.stderr)
    return False


def stop(node, timeout):
    """Cancel every goal of the planner's three actions (a cancel request naming no goal cancels all)."""
    from action_msgs.srv import CancelGoal
    canceled = 0
    for name in ('move_to_pose', 'follow_path', 'pick'):
        client = node.create_client(CancelGoal, f'{name}/_action/cancel_goal')
        if not client.wait_for_service(timeout_sec=min(DISCOVERY, timeout)):
            print(f'picking-goal: no {name} action server to stop', file=sys.stderr)
            return EXIT_TIMEOUT
        future = client.call_async(CancelGoal.Request())
        answer = node.spin_until(lambda: future.done() and future.result(), timeout)
        canceled += len(answer.goals_canceling) if answer else 0
    print(f'stop: {canceled} goal{"s" if canceled != 1 else ""} canceling (the arm brakes to rest)')
    return EXIT_OK


def run(args, node):
    if args.kind == 'stop':
        return stop(node, args.timeout)
    if args.kind == 'path' and args.arc:
        args.method = 'arc'
    hint = unit_hint(args)
    if hint:
        print(hint, file=sys.stderr)
    name, action_type, goal = make_goal(args, node)
    action = ActionClient(node, action_type, name)
    if not wait_for_server(node, action, name, args.timeout):
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
    args.timeout = getattr(args, 'timeout', 30.0)
    args.no_wait = getattr(args, 'no_wait', False)
    if not (np.isfinite(args.timeout) and args.timeout > 0):
        parser.error('--timeout must be > 0 s')
    if args.kind != 'stop':
        try:
            quaternion(args)
        except ValueError as exc:
            parser.error(str(exc))
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
