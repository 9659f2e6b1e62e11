"""``picking-goal``: send a goal to the planner's action, follow it, report its result.

    picking-goal pose 0.6 0.1 0.4 --rpy 180 0 0
    picking-goal pose 0.6 -0.1 0.45 --method line
    picking-goal path --pose 0.55 -0.1 0.45 --pose 0.5 -0.25 0.5 --method via_lspb
    picking-goal path --arc --pose 0.55 -0.1 0.5 --pose 0.5 0.05 0.45
    picking-goal pick 0.7 0.15 0.65 --rpy 0 90 0
    picking-goal harvest --tree 6 --seed 1
    picking-goal tree --tree 40 --seed 1
    picking-goal stop

Positions are metres in base_link; ``--rpy`` is roll, pitch, yaw in degrees (fixed
axes x, y, z), ``--quat`` a quaternion x y z w. ``--method`` chooses the method
for this goal only (the planner's ``method`` / ``path_method`` parameters are the
default). ``harvest`` sends a tree's apples on ``harvest_targets``: a seeded
synthetic tree (``--tree N``) or a file (``--file apples.yaml``: a YAML list of
``[x, y, z]`` positions, m, grasped along ``--rpy``, or of ``{position: [x, y, z],
rpy: [r, p, y]}`` in degrees), or, with ``--seen``, asks the planner on ``harvest_seen`` to harvest the apples
its fruit map has confirmed from the camera; it prints each apple as it is picked or skipped. ``tree`` sends the same,
in the ``platform`` frame, to picking-harvester on ``tree_targets`` (several arms share it; ``--tree N``
spans the canopy of every arm of ``--platform``/``--layout``). Add ``--ros-args -r __ns:=/arm2``
to talk to another arm. Ctrl-C cancels the goal: the arm brakes to rest within its
limits; ``stop`` cancels every goal of the planner and its controller.

Exit codes: 0 the goal succeeded; 1 it was refused (never ran: unreachable, a
bad goal, the controller refused its plan); 2 bad arguments; 3 it ended early
(aborted, superseded by another goal, canceled); 4 timed out.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np
from action_msgs.msg import GoalStatus
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import Pose, PoseArray, PoseStamped
from picking_interfaces.action import FollowPath, MoveToPose, Pick
from rclpy._rclpy_pybind11 import RCLInvalidROSArgsError, UnknownROSArgsError
from rclpy.node import Node
from rclpy.utilities import remove_ros_args
from std_msgs.msg import Header

from picking_common.actions import ActionClient
from picking_common.status import stamp_key, status_values
from picking_common.topics import BURST
from picking_core.methods import PATH_METHODS, POSE_METHODS

from .stop import DISCOVERY, EXIT_FAILED, EXIT_OK, EXIT_REFUSED, EXIT_TIMEOUT, in_a_node, spin_until, stop


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
    for kind in ('pose', 'pick', 'path'):
        sub.choices[kind].add_argument('--frame', default='base_link', help='frame of the poses: any frame /tf knows (default: %(default)s)')
    for kind, frame, words in (('harvest', 'base_link', "harvest a tree's apples with this arm (harvest_targets)"),
                               ('tree', 'platform', "harvest a tree with every arm of the platform (picking-harvester's "
                                                    'tree_targets)')):
        p = sub.add_parser(kind, parents=[common], help=words)
        tree = p.add_mutually_exclusive_group(required=True)
        tree.add_argument('--file', help='a YAML list of apples: [x, y, z] (m) or {position: [...], rpy: [...] (deg)}')
        tree.add_argument('--tree', type=int, metavar='N', help='a synthetic tree of N apples in the canopy')
        if kind == 'harvest':
            tree.add_argument('--seen', action='store_true', help="the apples the planner's fruit map has confirmed "
                              "from the camera's detections (harvest_seen)")
        p.add_argument('--seed', type=int, default=0, help='of the synthetic tree (default 0)')
        p.add_argument('--rpy', type=float, nargs=3, default=[0.0, 90.0, 0.0], metavar=('R', 'P', 'Y'),
                       help='grasp orientation of apples given without one, degrees (default 0 90 0: along +x)')
        p.add_argument('--frame', default=frame, help='frame of the poses: any frame /tf knows (default: %(default)s)')
    p.add_argument('--platform', help='the platform file whose canopy --tree spans (default: picking_description/platforms/platform.yaml)')
    p.add_argument('--layout', help='its layout (default: its default)')
    sub.add_parser('stop', parents=[common], help='cancel every goal of the planner and its controller (the arm '
                   'brakes to rest)')
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
    from scipy.spatial.transform import Rotation
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
        return spin_until(self, predicate, timeout)


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


def harvest_poses(args):
    """The apples of a harvest as 4x4 poses: a synthetic ``--tree`` or the ``--file``'s; ValueError
    saying what is wrong with them."""
    import yaml
    from scipy.spatial.transform import Rotation
    if getattr(args, 'seen', False):
        return []                             # the planner knows them
    if args.tree is not None:
        if args.tree < 1:
            raise ValueError('--tree needs at least one apple')
        if args.kind == 'tree':
            from picking_core.platform import Platform
            from picking_description import platform_path
            platform = Platform.from_yaml(args.platform or platform_path(), args.layout)
            return platform.tree(args.tree, seed=args.seed)
        from picking_core.harvest import synthetic_tree
        return synthetic_tree(args.tree, seed=args.seed)
    try:
        data = yaml.safe_load(Path(args.file).read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise ValueError(f'{args.file}: {exc}') from None
    if not isinstance(data, list) or not data:
        raise ValueError(f'{args.file}: expected a YAML list of apples, [x, y, z] or {{position: ..., rpy: ...}}')
    poses = []
    for k, item in enumerate(data):
        position, rpy = (item.get('position'), item.get('rpy', args.rpy)) if isinstance(item, dict) else (item, args.rpy)
        try:
            p, r = np.asarray(position, float), np.asarray(rpy, float)
        except (TypeError, ValueError):
            p = r = np.array([])
        if p.shape != (3,) or r.shape != (3,) or not (np.all(np.isfinite(p)) and np.all(np.isfinite(r))):
            raise ValueError(f'{args.file}: apple {k}: a position is [x, y, z] in m and rpy [r, p, y] in degrees, '
                             f'got {item!r}')
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = Rotation.from_euler('xyz', r, degrees=True).as_matrix(), p
        poses.append(T)
    return poses


def harvest(args, node, poses):
    """Send a harvest on ``harvest_targets`` (a tree on ``tree_targets``) and follow it on
    ``planner_status`` (``harvester_status``) to its end."""
    topic, status_topic, who = (('tree_targets', 'harvester_status', 'picking-harvester') if args.kind == 'tree'
                                else ('harvest_targets', 'planner_status', 'picking-planner'))
    seen_apples = getattr(args, 'seen', False)
    if seen_apples:
        topic = 'harvest_seen'
    pub = node.create_publisher(Header if seen_apples else PoseArray, topic, BURST)
    statuses = []
    node.create_subscription(DiagnosticStatus, status_topic, statuses.append, BURST)
    where = f'{node.get_namespace().rstrip("/")}/{topic}'
    if not node.spin_until(lambda: pub.get_subscription_count() > 0, min(DISCOVERY, args.timeout)):
        print(f'picking-goal: nobody subscribes to {where} yet (is {who} running in this namespace, with '
              f'this ROS_DOMAIN_ID?); waiting up to {args.timeout:g} s', file=sys.stderr, flush=True)
        if not node.spin_until(lambda: pub.get_subscription_count() > 0, max(args.timeout - DISCOVERY, 0.0)):
            print(f'picking-goal: nobody subscribes to {where}', file=sys.stderr)
            return EXIT_TIMEOUT
    if seen_apples:
        msg = Header(stamp=node.get_clock().now().to_msg())
        key, what = stamp_key(msg.stamp), 'a harvest of the apples seen'
    else:
        from picking_common.poses import pose_msg  # (scipy: loaded only by the commands that need it)
        msg = PoseArray(poses=[pose_msg(T) for T in poses])
        msg.header.frame_id, msg.header.stamp = args.frame, node.get_clock().now().to_msg()
        key = stamp_key(msg.header.stamp)
        what = f'a {"tree" if args.kind == "tree" else "harvest"} of {len(poses)} apples'
    t_sent, seen = time.monotonic(), 0
    print(f'sent: {what}, goal {key} ({status_topic} names it so)', flush=True)

    last = [None]

    def news():
        """The next status of this goal (a resend when none came yet: discovery may drop the first); an answer
        the planner sent again for a resend is not news."""
        nonlocal seen
        while seen < len(statuses):
            seen += 1
            got = statuses[seen - 1]
            if status_values(got).get('goal') == key and got != last[0]:
                last[0] = got
                return got
        return None
    pub.publish(msg)
    answered = False
    try:
        while True:
            got = node.spin_until(news, 2.0 if not answered else 3600.0)
            if got is None:
                if time.monotonic() - t_sent > args.timeout:
                    print(f'picking-goal: the planner did not take the goal within {args.timeout:g} s', file=sys.stderr)
                    return EXIT_TIMEOUT
                pub.publish(msg)              # the same goal again: the planner answers it, never plans it twice
                continue
            answered = True
            values = status_values(got)
            print(f'  {time.monotonic() - t_sent:6.2f} s  {got.message}', flush=True)
            if values.get('state') in ('succeeded', 'refused', 'aborted', 'superseded', 'canceled'):
                return {'succeeded': EXIT_OK, 'refused': EXIT_REFUSED}.get(values['state'], EXIT_FAILED)
            if args.no_wait:
                return EXIT_OK
    except KeyboardInterrupt:
        if args.kind == 'tree':
            print('picking-goal: the arms harvest on; `picking-goal stop --ros-args -r __ns:=/<arm>` stops one',
                  flush=True)
            return EXIT_FAILED
        print('stopping the harvest: the arm brakes to rest', flush=True)
        stop(node, args.timeout)
        return EXIT_FAILED


def run(args, node):
    if args.kind == 'stop':
        return stop(node, args.timeout)
    if args.kind in ('harvest', 'tree'):
        return harvest(args, node, harvest_poses(args))
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
    if done.status != GoalStatus.STATUS_SUCCEEDED and outcome == 'succeeded':
        # An empty result on a goal the server did not succeed: the server ended it without its own answer.
        outcome, res.message = 'aborted', 'the action server ended the goal without a result (see its log)'
    moved = f'; plan {res.duration:.3f} s; largest tracking error {progress["error"]:.5f} rad' if res.duration > 0 else ''
    print(f'{outcome}: {res.message} ({took:.2f} s after sending{moved})')
    if done.status == GoalStatus.STATUS_SUCCEEDED:
        return EXIT_OK
    return EXIT_REFUSED if res.outcome == action_type.Result.REFUSED else EXIT_FAILED


def main(argv=None):
    argv = sys.argv if argv is None else argv
    parser = build_parser()
    try:
        own = remove_ros_args(argv)[1:]
    except (RCLInvalidROSArgsError, UnknownROSArgsError) as exc:
        parser.error(f"bad ROS arguments: {exc} (picking-goal's own options go before --ros-args)")
    args = parser.parse_args(own)
    args.timeout = getattr(args, 'timeout', 30.0)
    args.no_wait = getattr(args, 'no_wait', False)
    if not (np.isfinite(args.timeout) and args.timeout > 0):
        parser.error('--timeout must be > 0 s')
    try:
        if args.kind in ('harvest', 'tree'):
            harvest_poses(args)
        elif args.kind != 'stop':
            quaternion(args)
    except ValueError as exc:
        parser.error(str(exc))
    return in_a_node(lambda: GoalClient(f'picking_goal_{os.getpid()}'), argv, lambda node: run(args, node),
                     'the goal ended')


if __name__ == '__main__':
    sys.exit(main())
