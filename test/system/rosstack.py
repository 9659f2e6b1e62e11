"""Helpers for system tests: start the three nodes as processes, talk to them over ROS.

Every process inherits ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST and this test
run's ROS_DOMAIN_ID (set in conftest.py), and is stopped by its process id.
"""

from __future__ import annotations

import os
import queue
import threading
import time
from contextlib import contextmanager

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import Pose, PoseArray, PoseStamped
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from rclpy.subscription import Subscription
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

from picking_bringup import stack as launcher
from picking_bringup.stack import NodeProcess, stop_all, write_stacks  # noqa: F401  (the tests stop processes with it)
from picking_common.middleware import use_fast_discovery
from picking_common.status import stamp_key, status_values
from picking_common.topics import LatestMessage
from picking_core.kinematics import ArmModel
from picking_description import default_urdf

BIN = launcher.BIN
RELIABLE = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
#: The planner's goal QoS (reliable, keep last 10 000; see picking_planner.node.BURST): a goal
#: lost in transport during a flood must still be in our history when the planner asks again.
BURST = QoSProfile(depth=10_000, reliability=ReliabilityPolicy.RELIABLE)
RENEW_AFTER = 3        # goal sends unanswered before the client sends it on a new publisher too
STATUSES = QoSProfile(depth=40_000, reliability=ReliabilityPolicy.RELIABLE)
ARM_JOINTS = ['shoulder_pan_joint', 'shoulder_lift_joint', 'elbow_joint', 'wrist_1_joint', 'wrist_2_joint',
              'wrist_3_joint']
HOME = [0.0, 0.2, 1.6, 0.0, 1.3, 0.0]
DOWN = Rotation.from_euler('xyz', [180, 0, 0], degrees=True).as_quat().tolist()
ARM = ArmModel.from_urdf(default_urdf())


#: Every goal a test client heard of in this run: its key -> its newest state (for the run's tally).
GOALS = {}
#: The state of a goal whose planner a test killed while it ran: the controller's result is its end.
KILLED = 'its planner killed (the controller finished its plan)'

#: The nodes as processes, stopped by pid (the launcher's own).
Process = NodeProcess


class Stack(launcher.Stack):
    """The arm as ``picking-stack`` brings it up, at the home pose, with the planner's own file only and half its
    speed (the tests' goals and timeouts assume it), and per-node extra arguments by keyword."""

    def __init__(self, ns, log_dir, sim_args=(), controller_args=(), planner_args=(), foxglove=None):
        super().__init__(ns, log_dir, foxglove=foxglove, files={'picking-planner': ('planner.yaml',)}, args={
            'picking-sim': ['-p', 'initial_positions:=[' + ','.join(str(v) for v in HOME + [0.09]) + ']',
                            *sim_args],
            'picking-controller': list(controller_args),
            'picking-planner': ['-p', 'speed_scale:=0.5', *planner_args]})

    def restart_sim(self):
        self.start('picking-sim')

    def restart_controller(self):
        self.start('picking-controller')

    def restart_planner(self):
        self.start('picking-planner')


class Client(Node):
    """A test's eyes and hands in one namespace: records every message it sees."""

    def __init__(self, ns):
        super().__init__(f'test_client_{os.getpid()}_{abs(hash(ns)) % 10000}', namespace=ns)
        self.lock = threading.Lock()
        self.states, self.commands, self.planner_status, self.controller_status = [], [], [], []
        self.create_subscription(JointState, 'joint_states', self._rec(self.states), RELIABLE)
        # Deep enough for every status of a flood (about three per goal): the run's tally counts them.
        self._planner_sub = self.create_subscription(DiagnosticStatus, 'planner_status',
                                                     self._rec(self.planner_status, self._tally), STATUSES)
        self._controller_sub = self.create_subscription(DiagnosticStatus, 'controller_status',
                                                        self._rec(self.controller_status), BURST)
        self.pub_pose = self.create_publisher(PoseStamped, 'goal_pose', BURST)
        self.pub_path = self.create_publisher(PoseArray, 'goal_path', BURST)
        self.pub_pick = self.create_publisher(PoseStamped, 'pick_target', BURST)
        self.pub_traj = self.create_publisher(JointTrajectory, 'joint_trajectory', RELIABLE)
        self._commands_tap = LatestMessage(self, JointState, 'joint_commands')
        self._goal = None                 # (publisher, message) of the last goal sent
        self._exec = SingleThreadedExecutor()
        self._exec.add_node(self)
        self._closing = threading.Event()
        self._retiring = queue.Queue()
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self):
        # Our own loop, ended by close() before the executor shuts down: shutting it down while
        # it spins races with a callback in flight ("cannot use Destroyable").
        while not self._closing.is_set():
            self._exec.spin_once(timeout_sec=0.05)
            while not self._retiring.empty():
                thing, done = self._retiring.get()
                self._destroy(thing)
                done.set()

    def _destroy(self, thing):
        # (A subscription goes through its node, which destroys its event handlers with it.)
        if isinstance(thing, Subscription):
            self.destroy_subscription(thing)
        else:
            thing.destroy()

    def retire(self, thing):
        """Destroy an action client or server, a subscription or a listener of this node between two
        turns of its spin thread: destroyed while the executor waits on it, the thread dies ("action
        client pointer is invalid") and the client hears nothing more."""
        if not self._thread.is_alive():
            self._destroy(thing)
            return
        done = threading.Event()
        self._retiring.put((thing, done))
        assert done.wait(10.0), 'the spin thread did not retire it'

    def watch_commands(self):
        """Record joint_commands too (1 kHz: only the tests that need it pay for it)."""
        if not getattr(self, '_commands_sub', None):
            self._commands_sub = self.create_subscription(JointState, 'joint_commands', self._rec(self.commands),
                                                          qos_profile_sensor_data)
            self.wait_for(lambda: len(self.commands) > 20, 10.0, 'joint_commands')

    def _rec(self, store, also=None):
        def callback(msg):
            with self.lock:
                store.append((time.monotonic(), msg))
            if also is not None:
                also(msg)
        return callback

    def _tally(self, msg):
        values = status_values(msg)
        key = f'{self.get_namespace()} {values.get("goal")}'
        if values.get('goal') and values.get('state') and GOALS.get(key) not in FINAL:   # a final state stays
            GOALS[key] = values['state']

    def wait_for(self, predicate, timeout=20.0, what='condition'):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            with self.lock:
                result = predicate()
            if result:
                return result
            time.sleep(0.02)
        raise AssertionError(f'timed out after {timeout} s waiting for {what}')

    def wait_ready(self, timeout=30.0):
        """Until joint_states flow and the planner and controller listen."""
        self.wait_for(lambda: len(self.states) > 5, timeout, 'joint_states')
        self.wait_for(lambda: self.pub_pose.get_subscription_count() > 0
                      and self.pub_traj.get_subscription_count() > 0, timeout, 'planner and controller')
        self.wait_for(lambda: self.pub_traj.get_subscription_count() > 0, timeout, 'the controller')
        # Statuses are volatile: hear the planner and the controller before asking them anything.
        self.wait_for(lambda: self._planner_sub.get_publisher_count() > 0
                      and self._controller_sub.get_publisher_count() > 0, timeout, 'planner and controller statuses')
        # The controller commands only once it has feedback: wait for a command sent from now on
        # (read on demand from a hidden subscription: no 1 kHz callbacks in this process).
        since = time.time()

        def commanding():
            msg = self._commands_tap.take()
            return msg is not None and msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9 > since
        self.wait_for(commanding, timeout, 'the controller to hold the arm')

    def mark(self):
        with self.lock:
            return {'states': len(self.states), 'commands': len(self.commands),
                    'planner': len(self.planner_status), 'controller': len(self.controller_status)}

    def send(self, publisher, msg):
        """Publish a goal; :meth:`planner_answer` sends it again while no answer comes."""
        self._goal = (publisher, msg)
        publisher.publish(msg)
        return msg

    @property
    def last_goal(self):
        """The last goal message sent with :meth:`send`."""
        return self._goal[1]

    def answers(self, since, key=None):
        """The planner's statuses since ``since`` about goal ``key`` (default: the last goal sent)."""
        key = key or stamp_key(self._goal[1].header.stamp)
        # (A topic goal's statuses carry its stamp; its id is the stamp, or its own when the stamp is zero.)
        return [m for _, m in self.planner_status[since['planner']:]
                if key in (status_values(m).get('goal'), status_values(m).get('stamp'))]

    def planner_answer(self, since, timeout=20.0, resend_every=2.0):
        """The planner's first answer about the last goal sent, since ``since``. The last goal is
        sent again (the planner answers a repeat without planning it twice) every ``resend_every``
        s without an answer: a goal sent as discovery completes can be lost. After RENEW_AFTER
        sends unanswered it goes out on a publisher made anew as well (a restarted planner has
        stayed unmatched by the old one's writer for longer than the timeout on a loaded machine)."""
        end = time.monotonic() + timeout
        sends = 1
        while True:
            try:
                return self.wait_for(lambda: self.answers(since)[:1] and self.answers(since)[0],
                                     min(resend_every, max(end - time.monotonic(), 0.0)), 'planner_status')
            except AssertionError:
                publisher, msg = self._goal or (None, None)
                if time.monotonic() >= end or publisher is None:
                    seen = '' if publisher is None else (
                        f' ({publisher.get_subscription_count()} readers of {publisher.topic_name}, '
                        f'{self._planner_sub.get_publisher_count()} writers of planner_status)')
                    raise AssertionError(f'timed out after {timeout} s waiting for planner_status{seen}') from None
                if sends % RENEW_AFTER == 0:
                    publisher = self._renewed(publisher)
                    self._goal = (publisher, msg)
                publisher.publish(msg)
                sends += 1

    def _renewed(self, publisher):
        """A new publisher like ``publisher``, in its place among this client's attributes (the old
        one is left alone: destroying it would race with the spinning executor)."""
        fresh = self.create_publisher(publisher.msg_type, publisher.topic, publisher.qos_profile)
        for name, value in list(vars(self).items()):
            if value is publisher:
                setattr(self, name, fresh)
        return fresh

    def controller_event(self, since, text, timeout=30.0):
        def find():
            for _, m in self.controller_status[since['controller']:]:
                if text in m.message:
                    return m
            return None
        return self.wait_for(find, timeout, f'controller_status "{text}"')

    def last_positions(self):
        with self.lock:
            msg = self.states[-1][1]
        names = list(msg.name)
        return np.array([msg.position[names.index(n)] for n in ARM_JOINTS])

    def send_pose(self, xyz, quat=DOWN):
        msg = PoseStamped()
        msg.header.frame_id = 'base_link'
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.pose = make_pose(xyz, quat)
        return self.send(self.pub_pose, msg)

    def set_planner_parameter(self, name, value, timeout=10.0):
        """Set one of the planner's parameters through its parameter service (as picking-goal does)."""
        self.set_planner_parameters({name: value}, timeout)

    def set_planner_parameters(self, values, timeout=10.0):
        """Set several of the planner's parameters at once (one request: they are checked together)."""
        client = AsyncParameterClient(self, 'picking_planner')
        assert client.wait_for_services(timeout_sec=timeout), 'the planner offers no parameter service'
        future = client.set_parameters_atomically([Parameter(n, value=v) for n, v in values.items()])
        self.wait_for(future.done, timeout, f'the planner to set {", ".join(values)}')
        assert future.result().result.successful, future.result().result.reason

    def close(self):
        self._closing.set()
        self._thread.join(timeout=10.0)       # the spin thread ends before the executor and node go
        self._exec.shutdown()
        self._commands_tap.destroy()
        self.destroy_node()


def send_goal(client, action, goal):
    """Send an action goal as `ros2 action send_goal` does: its accepted handle and the feedback it gets."""
    feedback = []
    future = action.send_goal_async(goal, feedback_callback=lambda fb: feedback.append(fb.feedback))
    handle = client.wait_for(lambda: future.done() and future.result(), 10.0, 'the goal response')
    assert handle.accepted
    return handle, feedback


def goal_result(client, handle, timeout=30.0):
    """The goal's result response (``.status``, ``.result``)."""
    future = handle.get_result_async()
    return client.wait_for(lambda: future.done() and future.result(), timeout, 'the result')


def make_pose(xyz, quat=DOWN):
    pose = Pose()
    pose.position.x, pose.position.y, pose.position.z = map(float, xyz)
    pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = map(float, quat)
    return pose


def ensure_rclpy():
    if not rclpy.ok():
        use_fast_discovery()
        rclpy.init()


@contextmanager
def running_stack(ns, log_dir, **args):
    """A stack in ``ns`` and a client, ready to take goals; afterwards both are stopped,
    and every node must have exited with 0."""
    ensure_rclpy()
    stack = Stack(ns, log_dir, **args)
    client = Client(ns)
    try:
        client.wait_ready()
        yield stack, client
    except BaseException:
        write_stacks(stack.processes)                # (the failing test's report shows them)
        raise
    finally:
        codes = stack.stop()
        client.close()
    assert set(codes.values()) == {0}, codes


@contextmanager
def shared_stack(ns, log_dir, **args):
    """A stack in ``ns`` and a client for a module's tests (started once, given a minute to come up on a loaded
    machine); afterwards both are stopped by pid."""
    ensure_rclpy()
    stack = Stack(ns, log_dir, **args)
    client = Client(ns)
    try:
        client.wait_ready(60.0)
        yield stack, client
    finally:
        client.close()
        stop_all(stack.processes)


FINAL = ('succeeded', 'aborted', 'superseded', 'canceled', 'refused')


def final_answer(client, since, timeout=40.0):
    """The planner's final status for the last goal sent (its result, as an action client gets it)."""
    return client.wait_for(lambda: [m for m in client.answers(since) if status_values(m).get('state') in FINAL],
                           timeout, 'the goal to end')[0]


def planner_says(client, ns, says, timeout=20.0, what='the planner to say so'):
    """The planner in ``ns``'s first /diagnostics status for which ``says(status)`` is true."""
    from diagnostic_msgs.msg import DiagnosticArray
    arrays = []
    sub = client.create_subscription(DiagnosticArray, '/diagnostics', arrays.append, 10)
    name = f'{ns.strip("/")}/picking_planner: planner'
    try:
        return client.wait_for(lambda: next((s for a in arrays for s in a.status if s.name == name and says(s)), None),
                               timeout, what)
    finally:
        client.retire(sub)


def planner_ready(client, ns, timeout=60.0):
    """Until the planner in ``ns`` says on /diagnostics that it can plan (it has discovered its controller and the
    controller has answered it: a fresh process on a saturated machine has taken over ten seconds)."""
    planner_says(client, ns, lambda s: s.level == DiagnosticStatus.OK, timeout, f'the planner in {ns} to be ready')


def reach(client, send, timeout=40.0):
    """Send a goal; wait until the planner accepted it (the controller took its plan) and it succeeded.
    Returns the 'accepted' answer (the plan's summary)."""
    for attempt in range(2):
        mark = client.mark()
        send()
        answer = client.planner_answer(mark)
        assert answer.level == DiagnosticStatus.OK, answer.message
        done = final_answer(client, mark, timeout)
        # A host that stops a process for longer than state_timeout makes the controller hold and
        # abort the goal, as it must (a simulator stopped for less lets the arm lag past the path
        # tolerance: the controller aborts as it must too); the goal is then sent once more (a new one,
        # from the hold).
        if attempt == 0 and ('feedback lost' in done.message or 'path tolerance violated' in done.message):
            client.wait_for(lambda: client.states and time.monotonic() - client.states[-1][0] < 0.1, 10.0, 'feedback')
            time.sleep(0.5)
            continue
        break
    assert status_values(done)['state'] == 'succeeded', done.message
    return answer


def tool_position(client):
    return ARM.fk(client.last_positions())[:3, 3]


def settles_at(client, target, tolerance=1e-3, timeout=5.0):
    """Wait until the measured tool position is within ``tolerance`` m of ``target``.

    "goal reached" means every joint within the goal tolerance (5 mrad) and at rest; the
    servo's integral action then takes the tool the rest of the way."""
    client.wait_for(lambda: np.linalg.norm(ARM.fk(np.array([
        client.states[-1][1].position[list(client.states[-1][1].name).index(n)] for n in ARM_JOINTS]))[:3, 3]
        - target) < tolerance, timeout, f'the tool within {tolerance * 1e3:g} mm of {list(target)}')


def largest_step(client, since, period=0.01):
    """Largest change of any arm joint between consecutive joint_states since ``since``, per
    ``period`` of their stamps (rad per joint_states period): messages a loaded client missed
    leave a gap of several periods, which is motion, not a jump."""
    with client.lock:
        msgs = [m for _, m in client.states[since['states']:]]
    if len(msgs) < 2:
        return 0.0
    q = np.array([[m.position[list(m.name).index(n)] for n in ARM_JOINTS] for m in msgs])
    t = np.array([m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in msgs])
    step = np.abs(np.diff(q, axis=0)).max(axis=1)
    return float((step * period / np.maximum(np.diff(t), period)).max())
