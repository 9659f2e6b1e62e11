"""``picking-sim``: the kinematic arm simulator node (ROS shell around picking_sim.servo).

Subscribes ``joint_commands`` (sensor_msgs/JointState: position, velocity, and
acceleration feedforward in ``effort``), runs the servo loop at ``servo_rate``
in a thread of its own with absolute deadlines, and publishes ``joint_states``
at ``publish_rate`` and the URDF on ``robot_description`` (transient local),
like a real arm driver.
"""

from __future__ import annotations

import threading
import time

import numpy as np
from builtin_interfaces.msg import Time
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from picking_planner.kinematics import ArmModel
from picking_planner.resources import default_urdf
from picking_planner import cdr
from picking_planner.ros_common import (LatestMessage, check_loop_phase, joint_state, joint_state_reader,
                                        loop_origin, make_realtime, reorder, run_node)

from .servo import Servo, ServoParams

#: s: a servo loop woken this much late says so (the longest such stall, at most once a second).
STALL_REPORT = 0.02
#: s: a loop woken that late first lets the process's other threads run this long (see _loop).
CATCH_UP_YIELD = 0.002

LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)


class SimNode(Node):
    """The simulated arm: servo loop thread + ROS interface."""

    def __init__(self, **kwargs):
        super().__init__('picking_sim', **kwargs)
        p = self._declare_parameters()
        self.arm = ArmModel.from_urdf(p['urdf_path'] or default_urdf())
        self.names = list(self.arm.all_joint_names)
        lower, upper, max_velocity, _ = self.arm.all_limits
        n = len(self.names)
        q0 = np.array(p['initial_positions'] or np.clip(np.zeros(n), lower, upper), dtype=float)
        if q0.shape != (n,) or not np.all(np.isfinite(q0)):
            raise ValueError(f'initial_positions must be {n} finite values, for {self.names}')
        if np.any(q0 < lower) or np.any(q0 > upper):
            raise ValueError(f'initial_positions {q0.tolist()} are outside the joint limits')
        if not (p['servo_rate'] > 0 and p['publish_rate'] > 0 and p['publish_rate'] <= p['servo_rate']):
            raise ValueError('servo_rate and publish_rate must be > 0 and publish_rate <= servo_rate')
        params = ServoParams(bandwidth=p['servo.bandwidth'], damping=p['servo.damping'],
                             integral=p['servo.integral'], inertia=p['servo.inertia'],
                             friction=p['servo.friction'], max_torque=p['servo.max_torque'],
                             max_velocity=max_velocity * p['servo.velocity_margin'])
        self.servo = Servo(q0, dt=1.0 / p['servo_rate'], params=params,
                           command_timeout=p['command_timeout'])
        self.noise_std = float(p['noise_std'])
        self.thread_priority = int(p['thread_priority'])
        self.loop_phase = check_loop_phase(p['loop_phase'])
        if not 0 <= self.thread_priority <= 99:
            raise ValueError(f'thread_priority must be 0 (normal) or 1-99 (SCHED_FIFO), got {self.thread_priority}')
        self.rng = np.random.default_rng()
        self.publish_every = max(1, int(round(p['servo_rate'] / p['publish_rate'])))
        self.lock = threading.Lock()

        self.pub_states = self.create_publisher(JointState, 'joint_states', 10)
        self.pub_description = self.create_publisher(String, 'robot_description', LATCHED)
        self.pub_description.publish(String(data=self.arm.urdf))
        # The servo thread takes the newest command itself: no 1 kHz executor callbacks.
        self.commands = LatestMessage(self, JointState, 'joint_commands', reader=joint_state_reader())
        self._writer = cdr.JointStateWriter(self.names) if cdr.check() else None
        self._applied = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name='servo', daemon=True)
        self._thread.start()
        self.get_logger().info(
            f'simulating {self.arm.name} ({n} joints) at {p["servo_rate"]:g} Hz, '
            f'publishing joint_states at {p["publish_rate"]:g} Hz from {np.round(q0, 4).tolist()}')

    def _declare_parameters(self):
        defaults = {
            'urdf_path': '', 'publish_rate': 100.0, 'servo_rate': 1000.0,
            'noise_std': 0.0, 'command_timeout': 0.05,
            'servo.bandwidth': 25.0, 'servo.damping': 1.0, 'servo.integral': 2.0,
            'servo.inertia': 0.5, 'servo.friction': 0.8, 'servo.max_torque': 400.0,
            'servo.velocity_margin': 1.2, 'thread_priority': 0, 'loop_phase': -1.0,
        }
        out = {}
        for name, value in defaults.items():
            out[name] = self.declare_parameter(name, value).value
        # No default: unset means "all zeros".
        out['initial_positions'] = list(
            self.declare_parameter('initial_positions', Parameter.Type.DOUBLE_ARRAY).value or [])
        return out

    def _apply_newest_command(self, t_state):
        """Apply the newest command, moved on from its stamp to ``t_state`` (the servo's time)."""
        msg = self.commands.take()
        if msg is None or msg is self._applied:
            return
        self._applied = msg
        try:
            q = reorder(msg.name, msg.position, self.names, 'joint_commands position')
            qd = reorder(msg.name, msg.velocity, self.names, 'joint_commands velocity') \
                if len(msg.velocity) else None
            qdd = reorder(msg.name, msg.effort, self.names, 'joint_commands effort') \
                if len(msg.effort) else None
            stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
            self.servo.command(q, qd, qdd, age=t_state - stamp)
        except (ValueError, IndexError) as exc:
            self.get_logger().warn(f'ignoring joint_commands: {exc}', throttle_duration_sec=2.0)

    def _loop(self):
        """Fixed-step servo at absolute deadlines; catches up when the OS wakes it late.

        Step ``k`` ends at ``t0 + k dt`` on the ROS clock: that is the stamp of the
        state it produces, and commands are moved on to it from their own stamps.
        """
        make_realtime(self.thread_priority, self.get_logger())
        dt = self.servo.dt
        now = time.monotonic()
        start = loop_origin(dt, self.loop_phase, now)
        t0 = self.get_clock().now().nanoseconds * 1e-9 - (now - start)    # the ROS time at start
        done = 0
        commanded = False
        reported, stalls, worst = -np.inf, 0, 0.0      # stalls are reported at most once a second
        while not self._stop.is_set():
            due = int((time.monotonic() - start) / dt) + 1 - done
            if due * dt > STALL_REPORT:
                stalls, worst = stalls + 1, max(worst, due * dt)
                # Woken far behind: the whole process may have been stopped, its DDS threads too.
                # Let them take in the commands sent meanwhile, then catch up along the newest.
                time.sleep(CATCH_UP_YIELD)
                due = int((time.monotonic() - start) / dt) + 1 - done
            if stalls and time.monotonic() - reported >= 1.0:
                reported = time.monotonic()
                self.get_logger().warn(
                    f'servo loop stalled for {worst:.3f} s'
                    + (f' (the longest of {stalls} stalls over {STALL_REPORT * 1e3:g} ms since the last report)'
                       if stalls > 1 else '')
                    + ': ran the missed steps at once, the reference following the commands through them')
                stalls, worst = 0, 0.0
            if due > 0:
                with self.lock:
                    self._apply_newest_command(t0 + done * dt)
                    for _ in range(due):
                        self.servo.step()
                        done += 1
                        if done % self.publish_every == 0:
                            self._publish(t0 + done * dt)
                    if self.servo.commanded != commanded:
                        commanded = self.servo.commanded
                        self._say_commanded(commanded)
            next_deadline = start + (done + 1) * dt
            # Always sleep a little: a real-time thread that never sleeps starves the rest.
            time.sleep(max(next_deadline - time.monotonic(), 5e-5))

    def _say_commanded(self, commanded):
        if commanded:
            self.get_logger().info('joint_commands flowing: following them')
        else:
            self.get_logger().warn(f'no joint_commands for {self.servo.command_timeout} s: holding the last '
                                   'commanded position until a controller commands again')

    def _publish(self, t_state):
        q = self.servo.q
        if self.noise_std > 0:
            q = q + self.rng.normal(0.0, self.noise_std, q.shape)
        sec = int(t_state // 1)
        nanosec = min(int(round((t_state - sec) * 1e9)), 999_999_999)
        if self._writer is not None:
            self.pub_states.publish(self._writer.write(sec * 1_000_000_000 + nanosec, q, self.servo.qd,
                                                       self.servo.torque))
            return
        stamp = Time(sec=sec, nanosec=nanosec)
        self.pub_states.publish(joint_state(self.names, stamp, q, self.servo.qd, self.servo.torque))

    def close(self):
        self._stop.set()
        self._thread.join(timeout=1.0)
        self.commands.destroy()


def main(args=None):
    return run_node(SimNode, args)


if __name__ == '__main__':
    raise SystemExit(main())
