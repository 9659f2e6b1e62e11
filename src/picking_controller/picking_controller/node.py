"""``picking-controller``: the joint trajectory controller node (ROS shell around core.py).

Subscribes ``joint_trajectory`` and ``joint_states``; publishes ``joint_commands``
at ``update_rate`` from a timing thread with absolute deadlines, and
``controller_status`` for every accepted or rejected trajectory, goal reached,
tolerance violation, and feedback lost or restored.

``joint_commands`` carries position (rad), velocity (rad/s) and, in ``effort``,
the reference acceleration (rad/s^2) as feedforward for the servo.
"""

from __future__ import annotations

import threading
import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

from picking_planner.kinematics import ArmModel
from picking_planner.resources import default_urdf
from picking_planner.ros_common import ERROR, OK, WARN, joint_state, reorder, run_node, status

from .core import ControllerCore, Tolerances

LEVELS = {'OK': OK, 'WARN': WARN, 'ERROR': ERROR}
RELIABLE = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)


def _seconds(stamp):
    return stamp.sec + stamp.nanosec * 1e-9


class ControllerNode(Node):
    """ROS interface of the trajectory controller."""

    def __init__(self, **kwargs):
        super().__init__('picking_controller', **kwargs)
        get = lambda name, value: self.declare_parameter(name, value).value  # noqa: E731
        urdf = get('urdf_path', '')
        self.rate = float(get('update_rate', 1000.0))
        if not self.rate > 0:
            raise ValueError(f'update_rate must be > 0 Hz, got {self.rate}')
        tol = Tolerances(path=get('path_tolerance', 0.1), goal=get('goal_tolerance', 0.005),
                         goal_time=get('goal_time_tolerance', 2.0),
                         stopped_velocity=get('stopped_velocity_tolerance', 0.02),
                         state_timeout=get('state_timeout', 0.5))
        self.arm = ArmModel.from_urdf(urdf or default_urdf())
        self.core = ControllerCore(self.arm.all_joint_names, *self.arm.all_limits, tol,
                                   optional=self.arm.extra_joint_names)
        self.lock = threading.Lock()
        self.pub_cmd = self.create_publisher(JointState, 'joint_commands', RELIABLE)
        self.pub_status = self.create_publisher(DiagnosticStatus, 'controller_status', RELIABLE)
        self.create_subscription(JointTrajectory, 'joint_trajectory', self._on_trajectory, RELIABLE)
        self.create_subscription(JointState, 'joint_states', self._on_state, qos_profile_sensor_data)
        self.ticks = 0
        self.late = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name='control', daemon=True)
        self._thread.start()
        self.get_logger().info(f'controlling {len(self.core.names)} joints at {self.rate:g} Hz; waiting for joint_states')

    def now(self):
        return self.get_clock().now().nanoseconds * 1e-9

    def _report(self, events):
        for e in events:
            self.pub_status.publish(status('picking_controller', LEVELS[e.level], e.message, **e.values))
            if e.level == 'ERROR':
                self.get_logger().error(e.message)
            else:
                self.get_logger().info(e.message)

    def _on_state(self, msg):
        try:
            q = reorder(msg.name, msg.position, self.core.names, 'joint_states position')
            qd = reorder(msg.name, msg.velocity, self.core.names, 'joint_states velocity') \
                if len(msg.velocity) == len(msg.name) else None
        except (ValueError, IndexError) as exc:
            self.get_logger().warn(f'ignoring joint_states: {exc}', throttle_duration_sec=2.0)
            return
        if not np.all(np.isfinite(q)):
            self.get_logger().warn('ignoring joint_states with non-finite positions', throttle_duration_sec=2.0)
            return
        with self.lock:
            events = self.core.on_state(q, qd, _seconds(msg.header.stamp), self.now())
        self._report(events)

    def _on_trajectory(self, msg):
        pts = msg.points
        with self.lock:
            event = self.core.load(
                msg.joint_names,
                [p.time_from_start.sec + p.time_from_start.nanosec * 1e-9 for p in pts],
                [p.positions for p in pts], [p.velocities for p in pts], [p.accelerations for p in pts],
                _seconds(msg.header.stamp), self.now())
        self._report([event])

    def _loop(self):
        """The control loop: absolute deadlines, so the rate does not drift."""
        period = 1.0 / self.rate
        next_t = time.monotonic()
        names = self.core.names
        while not self._stop.is_set():
            next_t += period
            stamp = self.get_clock().now()
            now = stamp.nanoseconds * 1e-9
            with self.lock:
                events = self.core.tick(now)
                ref = self.core.reference(now)
            if events:
                self._report(events)
            if ref is not None:
                # Stamped with the time the reference was sampled at: the tick's time.
                self.pub_cmd.publish(joint_state(names, stamp.to_msg(), *ref))
            self.ticks += 1
            delay = next_t - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            elif delay < -period:
                self.late += 1
                next_t = time.monotonic()        # too far behind: resynchronise, do not burst

    def close(self):
        self._stop.set()
        self._thread.join(timeout=1.0)


def main(args=None):
    return run_node(ControllerNode, args)


if __name__ == '__main__':
    raise SystemExit(main())
