"""``picking-planner``: the planner node, a ROS shell around the planning core and the goal policy.

Subscribes ``goal_pose`` (PoseStamped), ``goal_path`` (PoseArray),
``pick_target`` (PoseStamped), ``joint_states`` and ``joint_commands`` (the
controller's reference, so that a goal mid-motion continues smoothly);
publishes ``joint_trajectory``, ``planned_path`` and, for every goal,
``planner_status``: OK with a summary, or ERROR with the reason.

The method is the ``method`` parameter (pose goals) or ``path_method`` (path
goals), both settable at run time; ``picking-goal --method`` sets them for one
goal. Every parameter is validated when it is set.
"""

from __future__ import annotations

import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseArray, PoseStamped
from nav_msgs.msg import Path
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.serialization import serialize_message
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

from picking_common.codec import Codec
from picking_common.joint_state import reorder
from picking_common.run import run_node
from picking_common.status import Level, stamp_key, status, status_values
from picking_common.topics import BURST, RELIABLE, LatestMessage, newest_waiting

from .kinematics import ArmModel, Unreachable, pose_matrix
from .kinematics.paths import check_joint_limits
from .pick_cycle import PickCycle, PickSettings
from .goal_policy import WAIT_LIMIT, Goal, GoalPolicy
from .planning import Planner, PlannerSettings
from .resources import default_urdf

SETTINGS = ('method', 'path_method', 'speed_scale', 'duration', 'sample_period', 'cartesian_speed',
            'cartesian_accel', 'cartesian_profile', 'max_joint_step', 'limit_jerk')
PICK = ('approach_distance', 'lift_height', 'lift_method', 'approach_method', 'grasp_time', 'release_time', 'box_position',
        'box_drop_height', 'home_positions', 'transfer_method', 'transfer_lift', 'place_orientation_rpy',
        'place_yaw_free', 'blend', 'blend_radius')


def msg_pose(pose):
    """4x4 matrix from a geometry_msgs/Pose; ValueError for NaN or a zero quaternion."""
    p, o = pose.position, pose.orientation
    return pose_matrix([p.x, p.y, p.z], [o.x, o.y, o.z, o.w])


class PlannerNode(Node):
    """ROS interface of the planner."""

    def __init__(self, **kwargs):
        super().__init__('picking_planner', **kwargs)
        defaults = PlannerSettings()
        self.declare_parameter('urdf_path', '')
        self.declare_parameter('reference_timeout', 0.1)
        self.declare_parameter('start_delay', 0.1)
        for name in SETTINGS:
            self.declare_parameter(name, getattr(defaults, name))
        pick = PickSettings()
        for name in PICK:
            self.declare_parameter(name, getattr(pick, name))
        self.arm = ArmModel.from_urdf(self.get_parameter('urdf_path').value or default_urdf())
        # The compiled IK and forward kinematics load now (a fraction of a second from
        # numba's cache), not on the first goal.
        if not self.arm.load_ik() and self.arm.solver != 'numeric':
            self.get_logger().warning('the compiled IK did not load (is numba installed?): IK runs '
                                      'the vectorised closed form (the same solutions, slower)')
        self.names = list(self.arm.joint_names)
        self.planner = Planner(self.arm, self._settings({}))
        self.pick = PickSettings(**{n: self.get_parameter(n).value for n in PICK}).validate(self.arm)
        self.add_on_set_parameters_callback(self._on_parameters)

        self.policy = GoalPolicy(self.arm, self.get_parameter('start_delay').value)
        self.create_timer(0.1, self._serve_waiting)
        # Trajectories and tool paths are written straight to CDR bytes (much faster than the
        # message classes) where this middleware reads them back as the same messages.
        self.codec = Codec()
        if not self.codec.raw:
            self.get_logger().warning('this middleware does not read back our CDR bytes: trajectories are built as '
                                      'messages (slower)')
        self.pub_traj = self.create_publisher(JointTrajectory, 'joint_trajectory', RELIABLE)
        self.pub_path = self.create_publisher(Path, 'planned_path', RELIABLE)
        self.pub_status = self.create_publisher(DiagnosticStatus, 'planner_status', BURST)
        self.sub_pose = self.create_subscription(PoseStamped, 'goal_pose', self._on_goal_pose, BURST)
        self.sub_path = self.create_subscription(PoseArray, 'goal_path', self._on_goal_path, BURST)
        self.sub_pick = self.create_subscription(PoseStamped, 'pick_target', self._on_pick_target, BURST)
        self.sub_controller = self.create_subscription(DiagnosticStatus, 'controller_status',
                                                       self._on_controller_status, RELIABLE)
        self._superseded = 0          # goals answered as superseded since the last log line
        self._superseded_logged = 0.0
        # The measured state and the controller's reference, taken when a goal comes: no
        # executor callbacks at their rates (rclpy spends about a millisecond on each).
        self.states = LatestMessage(self, JointState, 'joint_states', reader=self.codec.state_reader())
        self.commands = LatestMessage(self, JointState, 'joint_commands', reader=self.codec.state_reader())
        self.get_logger().info(f'planning for {self.arm.name} ({self.arm.dof} joints, IK: {self.arm.solver}); '
                               f'method {self.planner.settings.method}, path_method '
                               f'{self.planner.settings.path_method}, speed_scale {self.planner.settings.speed_scale}')

    # -- parameters -------------------------------------------------------------------
    def _settings(self, changes):
        values = {n: self.get_parameter(n).value for n in SETTINGS}
        values.update(changes)
        return PlannerSettings(**values).validate()

    def _on_parameters(self, params):
        changes = {p.name: p.value for p in params}
        try:
            if set(changes) & set(SETTINGS):
                planner = Planner(self.arm, self._settings({k: v for k, v in changes.items() if k in SETTINGS}))
            else:
                planner = self.planner
            if set(changes) & set(PICK):
                values = {n: self.get_parameter(n).value for n in PICK}
                values.update({k: v for k, v in changes.items() if k in PICK})
                pick = PickSettings(**values).validate(self.arm)
            else:
                pick = self.pick
            if 'urdf_path' in changes:
                raise ValueError('urdf_path cannot change while the node runs')
            start_delay = float(changes.get('start_delay', self.policy.start_delay))
            if not start_delay >= 0.0:
                raise ValueError(f'start_delay must be >= 0 s, got {start_delay}')
        except (ValueError, TypeError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        self.planner, self.pick = planner, pick
        self.policy.start_delay = start_delay
        return SetParametersResult(successful=True)

    # -- state ---------------------------------------------------------------------------
    def _now(self):
        return time.monotonic()

    def _ros_now(self):
        """The controller's clock (the ROS clock), s."""
        return self.get_clock().now().nanoseconds * 1e-9

    def measured(self):
        """The newest valid joint_states: ``(q, gripper opening or None)``, or None before any."""
        msg = self.states.take()
        if msg is None:
            return None
        try:
            q = reorder(msg.name, msg.position, self.names, 'joint_states')
        except (ValueError, IndexError):
            return None
        if not np.all(np.isfinite(q)):
            return None
        gripper = None
        if 'gripper_joint' in msg.name:
            g = msg.position[list(msg.name).index('gripper_joint')]
            gripper = g if np.isfinite(g) else None
        return q, gripper

    def _reference(self):
        """The controller's newest reference ``(q, qd, qdd, stamp)`` if fresh, else None."""
        msg = self.commands.take()
        if msg is None:
            return None
        stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        if self._ros_now() - stamp > self.get_parameter('reference_timeout').value:
            return None                      # no controller is publishing: start from the measurement
        try:
            q = reorder(msg.name, msg.position, self.names, 'joint_commands')
            qd = reorder(msg.name, msg.velocity, self.names, 'joint_commands') if len(msg.velocity) else 0 * q
            qdd = reorder(msg.name, msg.effort, self.names, 'joint_commands') if len(msg.effort) else 0 * q
        except (ValueError, IndexError):
            return None
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(qd)) and np.all(np.isfinite(qdd))):
            return None
        return q, qd, qdd, stamp

    # -- goals ---------------------------------------------------------------------------
    def _check_frame(self, header):
        frame = header.frame_id.lstrip('/')
        if frame not in ('', self.arm.base_frame):
            raise ValueError(f'goal frame {header.frame_id!r} is not the base frame {self.arm.base_frame!r} '
                             '(no TF here: give poses in the base frame, or leave frame_id empty)')

    def _take(self, sub, msg, kind, plan):
        """The newest goal waiting on ``sub`` (every older one answered as superseded), planned with
        ``plan(msg, start_state, gripper)`` unless it is a resend of a goal already taken."""
        msg = newest_waiting(sub, msg, lambda old: self._supersede(kind, stamp_key(old.header.stamp)))
        key = stamp_key(msg.header.stamp)
        repeat, answer = self.policy.repeat(key, serialize_message(msg), self._now())
        if repeat:
            if answer is not None:            # (None: it is still waiting)
                self.pub_status.publish(answer)
            self.get_logger().info(f'goal {key} came again: its answer was sent again, it is not planned twice')
            return
        try:
            self._check_frame(msg.header)
        except ValueError as exc:
            self._refuse(kind, key, str(exc))
            return
        self._handle(Goal(kind, key, lambda start, gripper: plan(msg, start, gripper), self._now()))

    def _on_goal_pose(self, msg):
        self._take(self.sub_pose, msg, 'pose', lambda m, start, _: self.planner.plan_pose(start, msg_pose(m.pose)))

    def _on_goal_path(self, msg):
        def plan(m, start, _):
            if not m.poses:
                raise ValueError('goal_path has no poses')
            return self.planner.plan_path(start, [msg_pose(p) for p in m.poses])
        self._take(self.sub_path, msg, 'path', plan)

    def _on_pick_target(self, msg):
        self._take(self.sub_pick, msg, 'pick', lambda m, start, gripper: PickCycle(self.planner, self.pick).plan(
            start, msg_pose(m.pose), gripper_start=gripper))

    def _answer(self, key, msg):
        """Publish the answer to goal ``key`` (kept, should the goal come again)."""
        self.policy.answered(key, msg)
        self.pub_status.publish(msg)

    def _supersede(self, kind, key):
        self._answer(key, status('picking_planner', Level.WARN, f'{kind} goal superseded by a newer goal before '
                                 'it was planned', goal=key, kind=kind))
        self._superseded += 1
        if self._now() - self._superseded_logged > 1.0:
            self.get_logger().warn(f'{self._superseded} goals superseded by newer ones before they were planned')
            self._superseded, self._superseded_logged = 0, self._now()

    def _refuse(self, kind, key, reason):
        self._answer(key, status('picking_planner', Level.ERROR, f'{kind} goal refused: {reason}', goal=key, kind=kind))
        self.get_logger().error(f'{kind} goal refused: {reason}')

    def _ready(self):
        """None when a goal can be planned now, else why not (the arm's state or a controller unknown yet)."""
        if self.measured() is None:
            return 'no joint_states received: the planner does not know where the arm is'
        if self.pub_traj.get_subscription_count() == 0:
            return f'no controller subscribes to {self.pub_traj.topic_name}: the plan cannot be sent'
        return None

    def _serve_waiting(self):
        """The goal that waits for the arm's state or a controller: planned once both are known,
        refused after a few seconds (discovery may still be running when a node starts)."""
        why = self._ready() if self.policy.waiting is not None else None
        ready, refused = self.policy.waited(why is None, self._now())
        if ready is not None:
            self._handle(ready)
        if refused is not None:
            self._refuse(refused.kind, refused.key, f'{why} (waited {WAIT_LIMIT:g} s)')

    def _handle(self, goal):
        """Plan a goal and send the plan; a goal that comes before the arm's state or a controller
        is known waits (never blocking the executor)."""
        if self._ready() is not None:
            old = self.policy.wait(goal)
            if old is not None:
                self._supersede(old.kind, old.key)
            return
        kind, key, policy = goal.kind, goal.key, self.policy
        measured = self.measured()
        t0 = time.perf_counter()
        try:
            # The plan must end planning DELIVERY s before its start, else it is planned again further ahead.
            delay = policy.delay(goal)
            ref = self._reference()
            for _ in range(4):
                start = policy.start_state(self._ros_now() + delay, ref, measured[0])
                plan = goal.plan(start.state, measured[1])
                if policy.on_time(self._ros_now(), start):
                    break
                delay = 2.0 * delay + (time.perf_counter() - t0)
        except (ValueError, Unreachable) as exc:
            self._refuse(kind, key, str(exc))
            return
        planning_ms = (time.perf_counter() - t0) * 1e3
        policy.planned(goal, planning_ms * 1e-3)
        names = list(plan.joint_names or self.names)
        period = self.planner.settings.sample_period
        own = plan.samples(period)
        points, stamp = policy.points(own, start, period, names)
        try:
            # Checked as the controller will check it: a plan it would reject is never sent as accepted.
            check_joint_limits(self.arm, *points, names=names)
        except Unreachable as exc:
            self._refuse(kind, key, f'the plan breaks a limit (from {start.words()}: the arm\'s motion '
                                    f'cannot be carried on within it): {exc}')
            return
        stamp_ns = int(round(stamp * 1e9))
        self.pub_traj.publish(self.codec.joint_trajectory(stamp_ns, '', names, *points))
        policy.sent_plan(goal, plan.trajectory, start, names, stamp_key(stamp_ns), self._ros_now(),
                         self.get_parameter('reference_timeout').value)
        summary = plan.summary(period)
        segments = '; '.join(f'{s.label}: {s.method} {s.duration:.3f} s' for s in plan.segments)
        again = ' again (the last plan reached the controller too late)' if goal.attempt else ''
        self._answer(key, status(
            'picking_planner', Level.OK, f'{kind} goal accepted{again}: {plan.method}, {plan.duration:.3f} s',
            goal=key, kind=kind, method=plan.method, duration=plan.duration, start=start.source,
            peak_velocity=summary['peak_velocity'], peak_acceleration=summary['peak_acceleration'],
            segments=segments, planning_ms=planning_ms, attempt=goal.attempt + 1, **getattr(plan, 'extra', {})))
        self._publish_tool_path(own[1])
        self.get_logger().info(f'{kind} goal: {plan.method}, {plan.duration:.3f} s, planned in {planning_ms:.1f} ms')

    def _on_controller_status(self, msg):
        """A goal whose plan the controller refused as late is planned again, from where the arm
        is now, further ahead (see :meth:`GoalPolicy.late`), or answered as not run."""
        if Level.of(msg.level) != Level.ERROR:
            return
        values = status_values(msg)
        late = self.policy.late(values.get('trajectory')) if values.get('late') == 'True' else None
        if late is None:
            return
        goal = late.goal
        if not late.again:
            self._answer(goal.key, status(
                'picking_planner', Level.ERROR, f'{goal.kind} goal not run: its plan reached the controller '
                f'too late {goal.attempt + 1} times (a stalled or overloaded machine?)', goal=goal.key, kind=goal.kind))
            self.get_logger().error(f'{goal.kind} goal {goal.key}: its plan reached the controller too late '
                                    f'{goal.attempt + 1} times; not planned again')
            return
        self.get_logger().warning(f'{goal.kind} goal {goal.key}: the controller got its plan too late '
                                  f'({msg.message}); planning it again, further ahead')
        self._handle(goal)

    def _publish_tool_path(self, q):
        """The tool poses of the plan (every other point) on ``planned_path``, for RViz or Foxglove."""
        arm_q = q[:, :self.arm.dof]
        tool = self.arm.fk(arm_q[::2] if len(arm_q) > 2 else arm_q)
        quats = Rotation.from_matrix(tool[:, :3, :3]).as_quat()
        self.pub_path.publish(self.codec.path(self.get_clock().now().nanoseconds, self.arm.base_frame,
                                              tool[:, :3, 3], quats))

    def close(self):
        self.states.destroy()
        self.commands.destroy()


def main(args=None):
    return run_node(PlannerNode, args)


if __name__ == '__main__':
    raise SystemExit(main())
