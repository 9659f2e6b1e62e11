"""``picking-goal``: send a goal to the planner, wait for the plan and the motion, report.

    picking-goal pose 0.6 0.1 0.4 --rpy 180 0 0 [--method quintic|cubic|lspb|line]
    picking-goal path --pose 0.6 0.1 0.4 --pose 0.5 -0.2 0.5 --rpy 180 0 0 [--method via_lspb|...]
    picking-goal path --arc --pose 0.6 0.1 0.5 --pose 0.6 0.2 0.4 --rpy 180 0 0
    picking-goal pick 0.7 0.15 0.65 --rpy 0 90 0

Positions are metres in base_link; ``--rpy`` is roll, pitch, yaw in degrees (fixed
axes x, y, z), ``--quat`` a quaternion x y z w. ``--method`` sets the planner's
``method`` (pose goals) or ``path_method`` (path goals) parameter for this goal
and after it. Add ``--ros-args -r __ns:=/arm2`` to talk to another arm.

Exit codes: 0 the goal was reached; 1 the planner refused it; 2 bad arguments;
3 the controller reported a failure (or the planner gave the goal up, its plans
having reached the controller too late three times); 4 timed out.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import Pose, PoseArray, PoseStamped
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.utilities import remove_ros_args
from scipy.spatial.transform import Rotation

from picking_common.status import stamp_key, status_values

RELIABLE = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
EXIT_OK, EXIT_REFUSED, EXIT_ARGS, EXIT_FAILED, EXIT_TIMEOUT = 0, 1, 2, 3, 4
RESEND_EVERY = 1.0   # s without an answer before the goal is sent again


def build_parser():
    parser = argparse.ArgumentParser(prog='picking-goal', description=__doc__.split('\n\n')[0],
                                     epilog=__doc__.split('\n\n', 1)[1],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--timeout', type=float, default=30.0, help='s to wait for each answer')
    parser.add_argument('--no-wait', action='store_true', help='return once the planner has answered')
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
    def __init__(self):
        super().__init__(f'picking_goal_{os.getpid()}')
        self.planner_status, self.controller_status = [], []
        self.sub_planner = self.create_subscription(DiagnosticStatus, 'planner_status',
                                                    lambda m: self.planner_status.append(m), RELIABLE)
        self.sub_controller = self.create_subscription(DiagnosticStatus, 'controller_status',
                                                       lambda m: self.controller_status.append(m), RELIABLE)

    def spin_until(self, predicate, timeout):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            rclpy.spin_once(self, timeout_sec=0.05)
            result = predicate()
            if result:
                return result
        return None


def run(args, node):
    if args.kind == 'path' and args.arc:
        args.method = 'arc'
    quat = quaternion(args)
    if args.kind == 'path':
        topic, msg_type = 'goal_path', PoseArray
    else:
        topic, msg_type = ('goal_pose' if args.kind == 'pose' else 'pick_target'), PoseStamped
    pub = node.create_publisher(msg_type, topic, RELIABLE)

    if getattr(args, 'method', None):
        name = 'path_method' if args.kind == 'path' else 'method'
        client = AsyncParameterClient(node, 'picking_planner')
        if not client.wait_for_services(timeout_sec=args.timeout):
            print('picking-goal: no planner answers (is picking-planner running in this namespace?)',
                  file=sys.stderr)
            return EXIT_TIMEOUT
        future = client.set_parameters([Parameter(name, value=args.method)])
        rclpy.spin_until_future_complete(node, future, timeout_sec=args.timeout)
        result = future.result()
        if result is None or not result.results[0].successful:
            reason = result.results[0].reason if result else 'no answer'
            print(f'picking-goal: the planner refused {name}={args.method!r}: {reason}', file=sys.stderr)
            return EXIT_REFUSED

    if not node.spin_until(lambda: pub.get_subscription_count() > 0
                           and node.sub_planner.get_publisher_count() > 0, args.timeout):
        print(f'picking-goal: nobody subscribes to {node.resolve_topic_name(topic)} '
              '(is picking-planner running in this namespace?)', file=sys.stderr)
        return EXIT_TIMEOUT
    # Hear the controller before moving: a status sent before discovery completes is lost.
    if not args.no_wait and not node.spin_until(lambda: node.sub_controller.get_publisher_count() > 0,
                                                args.timeout):
        print('picking-goal: no controller publishes controller_status (is picking-controller running?)',
              file=sys.stderr)
        return EXIT_TIMEOUT
    stamp = node.get_clock().now().to_msg()
    key = stamp_key(stamp)
    if args.kind == 'path':
        msg = PoseArray()
        msg.poses = [make_pose(p, quat) for p in args.pose]
    else:
        msg = PoseStamped()
        msg.pose = make_pose(args.xyz, quat)
    msg.header.frame_id = args.frame
    msg.header.stamp = stamp
    node.controller_status.clear()
    t_sent = time.monotonic()
    # Sent again while no answer comes: a message sent as discovery completes can be lost
    # (we see the planner's subscription before it sees us). The planner answers a repeat
    # of the same goal (same stamp) again without planning it twice.
    answer, end = None, t_sent + args.timeout
    while answer is None and time.monotonic() < end:
        pub.publish(msg)
        answer = node.spin_until(lambda: next((m for m in node.planner_status
                                               if status_values(m).get('goal') == key), None),
                                 min(RESEND_EVERY, end - time.monotonic()))
    if answer is None:
        print(f'picking-goal: no answer from the planner within {args.timeout:g} s', file=sys.stderr)
        return EXIT_TIMEOUT
    t_planned = time.monotonic()
    if answer.level != DiagnosticStatus.OK:
        print(f'refused: {answer.message}')
        return EXIT_REFUSED
    v = status_values(answer)
    print(f'planned: {answer.message} (answer after {1e3 * (t_planned - t_sent):.0f} ms)')
    for key_name in ('segments', 'peak_velocity', 'peak_acceleration'):
        if v.get(key_name):
            print(f'  {key_name.replace("_", " ")}: {v[key_name]}')
    if args.no_wait:
        return EXIT_OK
    duration = float(v.get('duration', 0.0))

    def outcome():
        # A plan the controller refused as late is planned again by the planner, which answers
        # the goal with an ERROR should it give up.
        for m in node.planner_status:
            if m.level == DiagnosticStatus.ERROR and status_values(m).get('goal') == key:
                return m
        for m in node.controller_status:
            if m.level == DiagnosticStatus.ERROR and status_values(m).get('late') != 'True':
                return m
            if m.message.startswith('goal reached'):
                return m
        return None
    done = node.spin_until(outcome, duration + args.timeout)
    if done is None:
        print(f'picking-goal: the motion did not finish within {duration + args.timeout:.1f} s', file=sys.stderr)
        return EXIT_TIMEOUT
    t_done = time.monotonic()
    if done.level == DiagnosticStatus.ERROR:
        print(f'failed: {done.message}')
        return EXIT_FAILED
    dv = status_values(done)
    print(f'reached: goal reached {t_done - t_sent:.2f} s after sending (plan {duration:.3f} s); '
          f'largest tracking error {float(dv.get("max_tracking_error", "nan")):.5f} rad, '
          f'final error {float(dv.get("final_error", "nan")):.5f} rad')
    return EXIT_OK


def main(argv=None):
    argv = sys.argv if argv is None else argv
    parser = build_parser()
    args = parser.parse_args(remove_ros_args(argv)[1:])
    if not (np.isfinite(args.timeout) and args.timeout > 0):
        parser.error('--timeout must be > 0 s')
    rclpy.init(args=argv)
    node = GoalClient()
    try:
        return run(args, node)
    except KeyboardInterrupt:
        return EXIT_TIMEOUT
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
