"""``picking-sim``: the kinematic arm simulator node (ROS shell around picking_sim.servo).

Subscribes ``joint_commands`` (sensor_msgs/JointState: position, velocity, and
acceleration feedforward in ``effort``), runs the servo loop at ``servo_rate``
in a thread of its own with absolute deadlines, and publishes ``joint_states``
at ``publish_rate``, like a real arm driver (the URDF and the frames are the state publisher's).
As a witness (picking_sim.witness), it reports every contact of the arm with the scene
(``scene_file``, or the latched ``scene`` topic) on ``sim_contacts``, and draws that scene on
``world_markers`` (latched, in the arm's base frame) for viewers.

With a ``tree``, its apples are bodies (picking_core.fruit) judged from the published joint states: every
grasp, detachment, drop, missed grasp, knock and bruise on ``fruit_events`` and the tally on ``/diagnostics``;
their true positions on ``fruit_truth`` (for tests and viewers only); and a depth camera (picking_core.camera)
reports what it sees of them on ``detections`` (vision_msgs/Detection3DArray) in its frame, on /tf_static.
"""

from __future__ import annotations

import collections
import dataclasses
import threading
import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from sensor_msgs.msg import JointState
from visualization_msgs.msg import MarkerArray

from picking_common.codec import Codec
from picking_common.joint_state import reorder, seconds
from picking_common.loop import PeriodicLoop
from picking_common.params import declare, usage
from picking_common.run import run_node
from picking_common.scene_msgs import scene_markers, take_scene
from picking_common.status import Diagnostics, Level, status
from picking_common.tf import FrameError, FrameListener, stamp_seconds
from picking_common.topics import BURST, LATCHED, LatestMessage
from picking_core.collision import CollisionChecker, Scene
from picking_core.kinematics import ArmModel
from picking_core.kinematics.capsules import ArmCapsules
from picking_description import default_urdf, scene_path

from .fruit_node import FruitSim
from .parameters import PARAMS
from .servo import Servo, ServoParams
from .witness import Witness

#: s a scene in another frame waits for its transform into the arm's base.
TRANSFORM_TIMEOUT = 0.2
#: s the first scene in another frame waits: the listener it starts must first discover /tf's publishers.
LISTEN_TIMEOUT = 2.0
#: Servo steps run at each wake of the loop thread.
STEPS_PER_WAKE = 2
#: Hz of the witness's look at the samples published since its last.
WITNESS_RATE = 20.0
#: s a servo loop woken late lets the process's middleware threads take in the commands sent
#: meanwhile before it catches up along the newest.
CATCH_UP_YIELD = 0.002
#: s more a servo woken late while following commands waits for one sent during the stall: the
#: middleware may take longer to take in what came (held instead, the arm lagged the controller's
#: reference by the stall and it aborted the goal on its tolerance).
CATCH_UP_WAIT = 0.02


def newest_since(take, since, wait, poll=0.001):
    """The newest message ``take()`` gives that is stamped after ``since`` (s), waiting up to ``wait``
    s for one; else the newest there is (older, or None)."""
    end = time.monotonic() + wait
    while True:
        msg = take()
        if (msg is not None and seconds(msg.header.stamp) > since) or time.monotonic() >= end:
            return msg
        time.sleep(poll)


class SimNode(Node):
    """The simulated arm: servo loop thread + ROS interface."""

    def __init__(self, **kwargs):
        super().__init__('picking_sim', **kwargs)
        p, self.arm = self._declare_parameters()
        self.names = list(self.arm.all_joint_names)
        lower, upper, max_velocity, _ = self.arm.all_limits
        n = len(self.names)
        q0 = np.array(p['initial_positions'], dtype=float)
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
        self.rng = np.random.default_rng()
        self.publish_every = max(1, int(round(p['servo_rate'] / p['publish_rate'])))
        self.lock = threading.Lock()

        self.pub_states = self.create_publisher(JointState, 'joint_states', 10)
        # The servo thread takes the newest command itself: no 1 kHz executor callbacks.
        codec = Codec()
        self.commands = LatestMessage(self, JointState, 'joint_commands', reader=codec.state_reader())
        self._writer = codec.joint_state_writer(self.names)
        self._applied = None
        self._steps = 0
        self._commanded = False
        # The servo's time is the ROS clock: a loop deadline (monotonic) plus this offset.
        self._clock_offset = self.get_clock().now().nanoseconds * 1e-9 - time.monotonic()
        # The servo integrates in fixed steps of dt; its thread wakes every STEPS_PER_WAKE steps and
        # runs them at once, the command moved on to the first one's time: a simulated arm then
        # costs the machine it shares with the nodes under test half the wake-ups (woken every
        # step, the simulator took enough CPU from a planner under a flood of goals that its
        # plans came late).
        self.loop = PeriodicLoop(self.servo.dt * STEPS_PER_WAKE, self._tick, name='servo', logger=self.get_logger(),
                                 phase=p['loop_phase'], priority=p['thread_priority'], on_stall=self._say_stalled,
                                 catch_up_yield=CATCH_UP_YIELD)
        self.base_tf = p['frame_prefix'] + self.arm.base_frame
        # The witness: measured positions, as published, checked against the scene with no clearance.
        scene = Scene.from_yaml(p['scene_file'] or scene_path('workcell'))
        self.fruit = FruitSim.from_parameters(self, p, scene)
        if self.fruit is not None and self.fruit.tree_scene is not None:
            scene = self.fruit.tree_scene             # a tree among branches: they are in the world too
        if self.fruit is not None and self.arm.gripper_joint is not None:
            self.fruit.stop_fingers = self._stop_fingers
        self.witness = Witness(CollisionChecker(ArmCapsules.from_arm(self.arm), scene, clearance=0.0,
                                                self_check=False))
        self._watched = collections.deque(maxlen=int(10 * p['publish_rate']))
        self.pub_contacts = self.create_publisher(DiagnosticStatus, 'sim_contacts', BURST)
        # /tf is listened to from the first scene in another frame on: every arm's frames cost each listener its
        # share of a core, and the simulator needs them only for such a scene (a camera's mount is static).
        self.frames = None
        # The world the witness checks against, drawn for viewers (RViz, Foxglove) in the arm's base.
        self.pub_world = self.create_publisher(MarkerArray, 'world_markers', LATCHED)
        self.pub_world.publish(scene_markers(scene, self.base_tf))
        self.create_subscription(MarkerArray, 'scene', self._on_scene, LATCHED)
        self.create_timer(1.0 / WITNESS_RATE, self._watch)
        self.diagnostics = Diagnostics(self, self.arm.name, self._diagnose)
        self.loop.start()
        if self.fruit is not None:
            self.fruit.start()
        self.get_logger().info(
            f'simulating {self.arm.name} ({n} joints) at {p["servo_rate"]:g} Hz, '
            f'publishing joint_states at {p["publish_rate"]:g} Hz from {np.round(q0, 4).tolist()}')

    def _declare_parameters(self):
        """Every parameter with its descriptor; ``initial_positions`` defaults to the pick cycle's home
        with the gripper open, for an arm with those joints (else every joint at 0, within its limits)."""
        out = declare(self, [p for p in PARAMS if p.name != 'initial_positions'], check_unknown=False)
        arm = ArmModel.from_urdf(out['urdf_path'] or default_urdf())
        start = next(p for p in PARAMS if p.name == 'initial_positions')
        if len(start.default) != len(arm.all_joint_names):
            lower, upper, _, _ = arm.all_limits
            start = dataclasses.replace(start, default=np.clip(np.zeros(len(arm.all_joint_names)), lower, upper).tolist())
        out.update(declare(self, [start], others=list(out)))
        self.add_on_set_parameters_callback(self._on_parameters)
        return out, arm

    def _on_parameters(self, params):
        """``noise_std`` takes effect at once (ROS checked its range); the rest are read-only."""
        for p in params:
            if p.name == 'noise_std':
                self.noise_std = float(p.value)
        return SetParametersResult(successful=True)

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
            self.servo.command(q, qd, qdd, age=t_state - seconds(msg.header.stamp))
        except (ValueError, IndexError) as exc:
            self.get_logger().warn(f'ignoring joint_commands: {exc}', throttle_duration_sec=2.0)

    def _tick(self, deadline, periods):
        """The servo steps due by ``deadline``, the newest command moved on to the state's time first:
        after a stall the missed steps run at once, the reference following the command through them.
        The servo runs one step ahead of the clock (its state at the end of the step under way), as
        a drive reports the state it is driving to."""
        t_deadline = deadline + self._clock_offset
        dt = self.servo.dt
        due = periods * STEPS_PER_WAKE
        if periods > 1 and self._commanded:
            # Woken late while following commands: the controller went on commanding meanwhile.
            newest_since(self.commands.take, t_deadline - self.servo.command_timeout, CATCH_UP_WAIT)
        with self.lock:
            t_state = t_deadline + dt - due * dt
            self._apply_newest_command(t_state)
            for i in range(due):
                self.servo.step()
                self._steps += 1
                if self._steps % self.publish_every == 0:
                    self._publish(t_state + (i + 1) * dt)
            if self.servo.commanded != self._commanded:
                self._commanded = self.servo.commanded
                self._say_commanded(self._commanded)

    def _stop_fingers(self, width):
        """The fingers close no further than ``width`` (m; 0: freely): they rest on the apple between them, and
        the measured opening shows what they hold."""
        with self.lock:
            self.servo.stop_at(self.names.index(self.arm.gripper_joint), width if width > 0 else -np.inf)

    def _say_stalled(self, worst, count):
        more = f' (the longest of {count} stalls since the last report)' if count > 1 else ''
        self.get_logger().warn(f'servo loop stalled for {worst:.3f} s{more}: ran the missed steps at once, '
                               'the reference following the commands through them')

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
        self.pub_states.publish(self._writer.write(sec * 1_000_000_000 + nanosec, q, self.servo.qd, self.servo.torque))
        self._watched.append((t_state, self.servo.q[:self.arm.dof].copy()))
        if self.fruit is not None:
            self.fruit.samples.append((t_state, self.servo.q.copy()))

    def _in_base(self, header):
        """The transform of a scene marker's frame into the arm's base, from /tf (ValueError when there is none)."""
        frame = header.frame_id.lstrip('/')
        if frame in ('', self.arm.base_frame, self.base_tf):
            return np.eye(4)
        first = self.frames is None
        if first:
            self.frames = FrameListener(self)
        try:
            return self.frames.transform(self.base_tf, frame, stamp_seconds(header.stamp),
                                         LISTEN_TIMEOUT if first else TRANSFORM_TIMEOUT)
        except FrameError as exc:
            raise ValueError(str(exc)) from None

    def _on_scene(self, msg):
        scene = take_scene(msg, self._in_base, self.get_logger())
        if scene is None:
            return
        self.witness.checker = self.witness.checker.replaced(scene=scene)
        if self.fruit is not None:
            self.fruit.scene_changed(scene)
        self.pub_world.publish(scene_markers(scene, self.base_tf))
        self.get_logger().info(f'watching the arm against {len(scene)} obstacles from the scene topic')

    def _watch(self):
        """Every contact since the last look, on sim_contacts (ERROR when it starts, WARN when it ends)."""
        samples = [self._watched.popleft() for _ in range(len(self._watched))]
        if not samples:
            return
        times, q = zip(*samples)
        for e in self.witness.observe(np.array(times), np.array(q)):
            started = e.end is None
            level = Level.ERROR if started else Level.WARN
            text = e.words()
            if started:
                self.get_logger().error(text)
            else:
                self.get_logger().warn(text)
            self.pub_contacts.publish(status('picking_sim', level, text, link=e.link, obstacle=e.obstacle,
                                             # (times as text: epoch seconds need more than 6 digits)
                                             state='started' if started else 'ended', start=f'{e.start:.3f}',
                                             end=f'{e.end:.3f}' if e.end is not None else '', x=e.point[0], y=e.point[1],
                                             z=e.point[2], depth=e.depth, contacts=self.witness.count))

    def _diagnose(self):
        """For /diagnostics: the servo, following joint_commands or holding."""
        rate = 1.0 / self.servo.dt
        if self._commanded:
            out = [('servo', Level.OK, f'{rate:g} Hz, following joint_commands', {'servo_rate': rate})]
        else:
            out = [('servo', Level.WARN, f'{rate:g} Hz, no joint_commands: holding the last commanded position',
                    {'servo_rate': rate})]
        n = self.witness.count
        out.append(('contacts', Level.ERROR if self.witness.open else Level.OK,
                    f'{n} contacts with the scene since the start' + (', one now' if self.witness.open else ''),
                    {'contacts': n}))
        if self.fruit is not None:
            out.append(self.fruit.diagnose())
        return out

    def close(self):
        self.loop.stop()
        if self.fruit is not None:
            self.fruit.stop()
        self.commands.destroy()
        if self.frames is not None:
            self.frames.destroy()


def main(args=None):
    return run_node(SimNode, args, help=usage('picking-sim', __doc__, PARAMS))


if __name__ == '__main__':
    raise SystemExit(main())
