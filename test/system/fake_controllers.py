"""A joint trajectory controller and a gripper action controller as ros2_controllers documents them, for
tests that drive the planner against a standard arm (written from their user documentation, not from
picking-controller). The hardware under them follows the commands exactly.

- :class:`JointTrajectoryController`: ``<name>/follow_joint_trajectory`` (FollowJointTrajectory) for its
  ``joints`` only; a goal naming other joints, missing one (no partial goals), or with no points or
  times not increasing is rejected when sent; a zero header stamp starts it at once, another at that
  time; a new goal replaces the running one from its start, and the running goal ends aborted; a
  cancel holds the position and ends canceled; success once the last point's time has passed. It
  publishes ``<name>/controller_state`` (JointTrajectoryControllerState) and ``joint_states`` (as
  joint_state_broadcaster), with the gripper's joint.
- :class:`GripperActionController`: ``<name>/gripper_cmd`` (GripperCommand); the fingers move at
  ``speed`` toward the command; closing on an object (every close while open wider than ``object_width``
  finds one) they stop at its width and, after ``stall_timeout`` s at rest short of the target, the
  goal ends aborted with ``stalled`` (allow_stalling false, the default); within ``goal_tolerance`` of
  the target it ends succeeded with ``reached_goal``.
"""

from __future__ import annotations

import threading
import time

import numpy as np
from control_msgs.action import FollowJointTrajectory, GripperCommand
from control_msgs.msg import JointTrajectoryControllerState
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.task import Future
from sensor_msgs.msg import JointState

PERIOD = 0.01              # s, both controllers' update period
FEEDBACK_PERIOD = 0.05     # s, action feedback (action_monitor_rate 20 Hz)


def _seconds(duration):
    return duration.sec + duration.nanosec * 1e-9


def _stamp(ns):
    sec, nanosec = divmod(int(ns), 1_000_000_000)
    return sec, nanosec


class _Trajectory:
    """Points sampled by quintic (positions, velocities, accelerations given), cubic or linear segments."""

    def __init__(self, start, q0, points):
        self.start = start
        times = [_seconds(p.time_from_start) for p in points]
        n = len(q0)
        rows = [(np.asarray(p.positions, float),
                 np.asarray(p.velocities, float) if len(p.velocities) else np.zeros(n),
                 np.asarray(p.accelerations, float) if len(p.accelerations) else np.zeros(n)) for p in points]
        if times[0] > 0.0:                          # from where the joints are to the first point
            times.insert(0, 0.0)
            rows.insert(0, (np.asarray(q0, float), np.zeros(n), np.zeros(n)))
        self.times, self.rows = np.array(times), rows
        self.end = start + times[-1]

    def sample(self, t):
        rel = t - self.start
        if rel <= self.times[0]:
            return self.rows[0][0].copy()
        if rel >= self.times[-1]:
            return self.rows[-1][0].copy()
        k = int(np.searchsorted(self.times, rel) - 1)
        (p0, v0, a0), (p1, v1, a1) = self.rows[k], self.rows[k + 1]
        T = self.times[k + 1] - self.times[k]
        s = rel - self.times[k]
        # Quintic through both ends' position, velocity and acceleration.
        c0, c1, c2 = p0, v0, a0 / 2.0
        c3 = (20 * (p1 - p0) - (8 * v1 + 12 * v0) * T - (3 * a0 - a1) * T ** 2) / (2 * T ** 3)
        c4 = (30 * (p0 - p1) + (14 * v1 + 16 * v0) * T + (3 * a0 - 2 * a1) * T ** 2) / (2 * T ** 4)
        c5 = (12 * (p1 - p0) - 6 * (v1 + v0) * T - (a0 - a1) * T ** 2) / (2 * T ** 5)
        return c0 + s * (c1 + s * (c2 + s * (c3 + s * (c4 + s * c5))))


class JointTrajectoryController:
    """See the module's docstring. ``gripper``: a :class:`GripperActionController` whose joint joins joint_states."""

    def __init__(self, node, name, joints, q0, gripper=None):
        self.node, self.joints, self.gripper = node, list(joints), gripper
        self.q = np.asarray(q0, float).copy()
        self.lock = threading.Lock()
        self.trajectory, self.active = None, None          # the running trajectory, (handle, future) of its goal
        self.accepted = []                                  # every goal accepted, in order
        group = ReentrantCallbackGroup()
        self.server = ActionServer(node, FollowJointTrajectory, f'{name}/follow_joint_trajectory',
                                   execute_callback=self._execute, goal_callback=self._check,
                                   cancel_callback=lambda _: CancelResponse.ACCEPT, callback_group=group)
        self.pub_state = node.create_publisher(JointTrajectoryControllerState, f'{name}/controller_state', 10)
        self.pub_joints = node.create_publisher(JointState, 'joint_states', 10)
        self._last_feedback = 0.0
        node.create_timer(PERIOD, self._update, callback_group=group)

    def _check(self, request):
        names = list(request.trajectory.joint_names)
        points = request.trajectory.points
        times = [_seconds(p.time_from_start) for p in points]
        ok = (sorted(names) == sorted(self.joints) and len(set(names)) == len(names) and points
              and all(len(p.positions) == len(names) for p in points)
              and all(b > a for a, b in zip(times, times[1:])))
        return GoalResponse.ACCEPT if ok else GoalResponse.REJECT

    async def _execute(self, handle):
        msg = handle.request.trajectory
        order = [list(msg.joint_names).index(j) for j in self.joints]
        for p in msg.points:
            for field in ('positions', 'velocities', 'accelerations'):
                values = list(getattr(p, field))
                if values:
                    setattr(p, field, [values[i] for i in order])
        stamp = _seconds(msg.header.stamp)
        now = self.node.get_clock().now().nanoseconds * 1e-9
        done = Future()
        with self.lock:
            start = stamp if stamp > 0.0 else now
            trajectory = _Trajectory(start, self.q, msg.points)
            if self.active is not None:              # preempted: it ends aborted
                self.active[1].set_result(('aborted', 'preempted by a new goal'))
            self.trajectory, self.active = trajectory, (handle, done)
            self.accepted.append(handle)
        word, text = await done
        result = FollowJointTrajectory.Result(error_string=text)
        if word == 'succeeded':
            handle.succeed()
        elif word == 'canceled':
            handle.canceled()
        else:
            result.error_code = FollowJointTrajectory.Result.PATH_TOLERANCE_VIOLATED
            handle.abort()
        return result

    def _update(self):
        now_ns = self.node.get_clock().now().nanoseconds
        now = now_ns * 1e-9
        with self.lock:
            if self.active is not None and self.active[0].is_cancel_requested:
                self.trajectory = None                        # hold where it is
                self.active[1].set_result(('canceled', 'canceled'))
                self.active = None
            if self.trajectory is not None and now >= self.trajectory.start:
                self.q = self.trajectory.sample(now)
                if self.active is not None and now >= self.trajectory.end:
                    self.active[1].set_result(('succeeded', ''))
                    self.active = None
            handle = self.active[0] if self.active is not None else None
            q = self.q.copy()
        state = JointTrajectoryControllerState()
        state.header.stamp.sec, state.header.stamp.nanosec = _stamp(now_ns)
        state.joint_names = self.joints
        state.reference.positions = state.feedback.positions = state.output.positions = q.tolist()
        state.reference.velocities = state.reference.accelerations = [0.0] * len(q)
        state.error.positions = [0.0] * len(q)
        self.pub_state.publish(state)
        joints = JointState()
        joints.header.stamp = state.header.stamp
        joints.name = list(self.joints)
        joints.position = q.tolist()
        if self.gripper is not None:
            joints.name.append(self.gripper.joint)
            joints.position.append(self.gripper.position)
        self.pub_joints.publish(joints)
        if handle is not None and now - self._last_feedback >= FEEDBACK_PERIOD:
            self._last_feedback = now
            fb = FollowJointTrajectory.Feedback()
            fb.header.stamp = state.header.stamp
            fb.joint_names = self.joints
            fb.desired.positions = fb.actual.positions = q.tolist()
            fb.error.positions = [0.0] * len(q)
            handle.publish_feedback(fb)


class GripperActionController:
    """See the module's docstring."""

    def __init__(self, node, name, joint, position, speed=0.1, object_width=0.07, goal_tolerance=0.01,
                 stall_timeout=1.0):
        self.node, self.joint, self.position = node, joint, float(position)
        self.speed, self.object_width, self.goal_tolerance = speed, object_width, goal_tolerance
        self.stall_timeout = stall_timeout
        self.commands = []                                    # every command's position, in order
        self.lock = threading.Lock()
        self.target, self.active, self.still_since = None, None, None
        group = ReentrantCallbackGroup()
        self.server = ActionServer(node, GripperCommand, f'{name}/gripper_cmd', execute_callback=self._execute,
                                   cancel_callback=lambda _: CancelResponse.ACCEPT, callback_group=group)
        self._last_feedback = 0.0
        node.create_timer(PERIOD, self._update, callback_group=group)

    async def _execute(self, handle):
        done = Future()
        with self.lock:
            if self.active is not None:
                self.active[1].set_result('aborted')
            self.target = float(handle.request.command.position)
            self.commands.append(self.target)
            # Closing from wider than an apple: there is one between the fingers.
            self.stop_at = self.object_width if self.target < self.object_width <= self.position else None
            self.active, self.still_since = (handle, done), None
        word = await done
        with self.lock:
            result = GripperCommand.Result(position=self.position, effort=0.0,
                                           stalled=word == 'aborted' and self.still_since is not None,
                                           reached_goal=abs(self.position - self.target) <= self.goal_tolerance)
        if word == 'succeeded':
            handle.succeed()
        else:
            handle.abort()
        return result

    def _update(self):
        now = time.monotonic()
        with self.lock:
            if self.active is None:
                return
            handle, done = self.active
            goal = self.target if self.stop_at is None else max(self.target, self.stop_at)
            step = np.clip(goal - self.position, -self.speed * PERIOD, self.speed * PERIOD)
            self.position += float(step)
            if abs(self.position - self.target) <= self.goal_tolerance and self.stop_at is None:
                done.set_result('succeeded')
                self.active = None
            elif abs(step) < 1e-9:
                self.still_since = self.still_since or now
                if now - self.still_since >= self.stall_timeout:
                    done.set_result('aborted')                # stalled, and stalling is not allowed
                    self.active = None
            if now - self._last_feedback >= FEEDBACK_PERIOD:
                self._last_feedback = now
                handle.publish_feedback(GripperCommand.Feedback(position=self.position, stalled=False,
                                                                 reached_goal=False))
