"""``picking-planner``: the planner node (ROS shell around planning.py).

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

import threading
import time
from collections import OrderedDict, deque
from typing import NamedTuple

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
from .planning import Planner, PlannerSettings, feasible_start
from .resources import default_urdf
from .sent_plans import SentPlan, carried_points, carry_start, forget_before, plan_active, predict_reference

#: s a plan must leave between the end of planning and its start: sending it, and the
#: controller's checks (a few ms per hundred points).
DELIVERY = 0.08
#: s a first goal of a kind is expected to take to plan (later ones: what the last took). A plan
#: that ends too late to start on time is planned again further ahead, so a guess too short
#: costs a second planning: a pick cycle (about ten lines and moves) takes 0.1-0.4 s here.
FIRST_PLANNING = {'pose': 0.05, 'path': 0.1, 'pick': 0.4}
#: rad: the controller's reference is following our last plan when within this of it.
FOLLOWING = 1e-3
SETTINGS = ('method', 'path_method', 'speed_scale', 'duration', 'sample_period', 'cartesian_speed',
            'cartesian_accel', 'cartesian_profile', 'max_joint_step', 'limit_jerk')
PICK = ('approach_distance', 'lift_height', 'lift_method', 'approach_method', 'grasp_time', 'release_time', 'box_position',
        'box_drop_height', 'home_positions', 'transfer_method', 'transfer_lift', 'place_orientation_rpy',
        'place_yaw_free', 'blend', 'blend_radius')


def msg_pose(pose):
    """4x4 matrix from a geometry_msgs/Pose; ValueError for NaN or a zero quaternion."""
    p, o = pose.position, pose.orientation
    return pose_matrix([p.x, p.y, p.z], [o.x, o.y, o.z, o.w])


ZERO_KEY = '0.000000000'
#: Plans remembered to tell whether the controller's reference follows them: those that may still
#: run (a goal flood sends one every few ms, each to start start_delay or more ahead), at most this many.
SENT_KEPT = 2000
GOALS_KEPT = 1000    # goals remembered (with their answers) to know one sent again
REPEAT_WINDOW = 30.0  # s after a goal in which the same goal again is a resend, not a new goal
#: Times a goal is planned again when the controller refused its plan as late (the plan reached it
#: too late to run, after a stall in transport or in a process on a loaded machine; or it was
#: planned from a reference the controller no longer follows), each time starting twice as far ahead.
LATE_REPLANS = 2


class Start(NamedTuple):
    """Where a plan starts (see :meth:`PlannerNode.start_state`)."""

    state: tuple                  # (q, qd, qdd)
    source: str                   # 'reference' (the controller's) or 'measured'
    time: float                   # on the controller's clock, s
    carry_from: float | None = None   # where the points carry the sent plans from (None: nothing to carry)
    carries_on: bool = False      # from a sent plan the reference follows, at ``time``

    def words(self):
        """What the plan started from, in words (for a refusal)."""
        if self.carries_on:
            return 'the plan running then'
        return "the controller's reference, extrapolated" if self.source == 'reference' else 'the measured state'


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

        self.lock = threading.Lock()
        self.pending = []             # goals that came before the first joint_states
        self._planning_time = {}      # kind of goal -> s its last planning took
        self._sent = deque(maxlen=SENT_KEPT)   # SentPlan: the plans sent that may still run
        # The newest plan sent: its trajectory's stamp key, the goal (kind, header, plan_fn), how many times
        # it was planned again, its entry in _sent. Planned again if the controller says it came too late.
        self._newest_plan = None
        self.create_timer(0.1, self._serve_pending)
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
        self._goals = OrderedDict()   # goal key -> [its bytes, its answer, when it came]: a resend is answered again
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
        except (ValueError, TypeError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        self.planner, self.pick = planner, pick
        return SetParametersResult(successful=True)

    # -- state ---------------------------------------------------------------------------
    def _now(self):
        return time.monotonic()

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
        now = self.get_clock().now().nanoseconds * 1e-9
        if now - stamp > self.get_parameter('reference_timeout').value:
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

    def start_state(self, delay, reference, measured):
        """Where the plan starts: a :class:`Start`.

        The plan starts ``delay`` s from now and the trajectory is stamped to
        start then, so planning and delivery time never make the arm jump and
        the plan's clock is the controller's. While the controller publishes a
        fresh reference, the start state is where that reference will be at the
        start time. When the reference follows the plans this planner sent (each
        one spliced onto the one before at its start time, so the reference at
        its stamp lies on the plan active then, perhaps one that a newer plan,
        not started yet, will take over from), the exact state of the plan
        active at the start time, even across its end. Else the reference
        extrapolated from its stamp with its velocity, its acceleration brought
        to zero by the start (:func:`predict_reference`: another client's
        trajectory, a catch-up lead-in, a stalled controller), held within the
        limits. Without a reference, the measured state, at rest.
        ``reference`` and ``measured`` (from :meth:`measured`) are snapshots
        taken when the goal came. ``carry_from``: when the plan carries on from
        plans that start after the reference's stamp (the controller may not
        run them: see :func:`carried_points`), where to carry them from
        (:func:`carry_start`); else None.
        """
        t_start = self.get_clock().now().nanoseconds * 1e-9 + delay
        if reference is not None:
            q, qd, qdd, stamp = reference
            then = forget_before(self._sent, stamp) if stamp > 0 else None
            n = q.size
            if then is not None and np.abs(then.trajectory.state_at(stamp - then.start)[0][:n] - q).max() < FOLLOWING:
                plan = plan_active(self._sent, t_start) or then
                return Start(tuple(x[:n].copy() for x in plan.trajectory.state_at(t_start - plan.start)),
                             'reference', t_start, carry_start(self._sent, stamp, t_start), carries_on=True)
            dt = max(0.0, t_start - stamp) if stamp > 0 else 0.0
            return Start(feasible_start(self.arm, *predict_reference(q, qd, qdd, dt)), 'reference', t_start)
        if measured is None:
            raise ValueError('no joint_states received yet: the planner does not know where the arm is')
        q = measured[0]
        return Start((q, np.zeros_like(q), np.zeros_like(q)), 'measured', t_start)

    def _forget_old(self):
        """Forget the sent plans that no fresh reference can be on (see :func:`forget_before`),
        also while no reference comes: memory stays small."""
        now = self.get_clock().now().nanoseconds * 1e-9
        forget_before(self._sent, now - self.get_parameter('reference_timeout').value)

    # -- goals ---------------------------------------------------------------------------
    def _check_frame(self, header):
        frame = header.frame_id.lstrip('/')
        if frame not in ('', self.arm.base_frame):
            raise ValueError(f'goal frame {header.frame_id!r} is not the base frame {self.arm.base_frame!r} '
                             '(no TF here: give poses in the base frame, or leave frame_id empty)')

    def _newest(self, sub, msg, kind):
        """The newest goal waiting on ``sub``; every older one is answered at once as superseded."""
        return newest_waiting(sub, msg, lambda old: self._supersede(kind, old.header))

    def _repeated(self, msg):
        """True when ``msg`` is a goal already taken (same stamp, same content): its answer
        is sent again and it is not planned again.

        A sender that hears no answer sends its goal again: a message published just as
        discovery completes can be lost (the sender already sees this subscription, this
        node does not yet see the sender). A zero stamp gives a goal no identity, and
        the same goal more than REPEAT_WINDOW s after the first is a new one (a
        client that stamps every goal alike).
        """
        key = stamp_key(msg.header.stamp)
        if key == ZERO_KEY:
            return False
        data = serialize_message(msg)
        seen = self._goals.get(key)
        if seen is not None and seen[0] == data and self._now() - seen[2] < REPEAT_WINDOW:
            if seen[1] is not None:           # (None: it waits for the first joint_states)
                self.pub_status.publish(seen[1])
            self.get_logger().info(f'goal {key} came again: its answer was sent again, it is not planned twice')
            return True
        self._goals[key] = [data, None, self._now()]
        self._goals.move_to_end(key)
        while len(self._goals) > GOALS_KEPT:
            self._goals.popitem(last=False)
        return False

    def _answer(self, msg):
        """Publish the answer to a goal (kept, should the goal come again)."""
        seen = self._goals.get(status_values(msg).get('goal'))
        if seen is not None:
            seen[1] = msg
        self.pub_status.publish(msg)

    def _supersede(self, kind, header):
        self._answer(status('picking_planner', Level.WARN, f'{kind} goal superseded by a newer goal before '
                            'it was planned', goal=stamp_key(header.stamp), kind=kind))
        self._superseded += 1
        if self._now() - self._superseded_logged > 1.0:
            self.get_logger().warn(f'{self._superseded} goals superseded by newer ones before they were planned')
            self._superseded, self._superseded_logged = 0, self._now()

    def _on_goal_pose(self, msg):
        msg = self._newest(self.sub_pose, msg, 'pose')
        if self._repeated(msg):
            return
        self._handle('pose', msg.header, lambda start, _: self.planner.plan_pose(start, self._pose(msg)))

    def _on_goal_path(self, msg):
        msg = self._newest(self.sub_path, msg, 'path')
        if self._repeated(msg):
            return

        def plan(start, _):
            if not msg.poses:
                raise ValueError('goal_path has no poses')
            return self.planner.plan_path(start, [msg_pose(p) for p in msg.poses])
        self._handle('path', msg.header, plan)

    def _on_pick_target(self, msg):
        msg = self._newest(self.sub_pick, msg, 'pick')
        if self._repeated(msg):
            return
        self._handle('pick', msg.header, lambda start, gripper: PickCycle(self.planner, self.pick).plan(
            start, self._pose(msg), gripper_start=gripper))

    def _pose(self, msg):
        return msg_pose(msg.pose)

    def _serve_pending(self):
        """Goals that came before the first joint_states: planned once a state comes, refused after 2 s."""
        if self.pending and self.measured() is not None:
            waiting, self.pending = self.pending, []
            for kind, header, plan_fn, _ in waiting:
                self._handle(kind, header, plan_fn)
        while self.pending and self._now() - self.pending[0][3] > 2.0:
            kind, header, _, _ = self.pending.pop(0)
            self._refuse(kind, stamp_key(header.stamp),
                         'no joint_states received within 2 s: the planner does not know where the arm is')

    def _refuse(self, kind, key, reason):
        self._answer(status('picking_planner', Level.ERROR, f'{kind} goal refused: {reason}', goal=key, kind=kind))
        self.get_logger().error(f'{kind} goal refused: {reason}')

    def _handle(self, kind, header, plan_fn, attempt=0):
        """Plan a goal and send the plan (``attempt`` > 0: again, its last plan having reached
        the controller too late; it then starts 2**attempt times further ahead)."""
        key = stamp_key(header.stamp)
        measured = self.measured()
        if measured is None:
            # Just started: discovery of the arm's joint_states may still be running. Only
            # the newest goal waits; an older one is superseded (memory stays bounded).
            for old_kind, old_header, _, _ in self.pending:
                self._supersede(old_kind, old_header)
            self.pending = [(kind, header, plan_fn, self._now())]
            return
        # Before planning: waiting for discovery afterwards would make the plan's start stale.
        if not self._controller_listens():
            self._refuse(kind, key, f'no controller subscribes to {self.pub_traj.topic_name}: '
                                    'the plan was not sent')
            return
        t0 = time.perf_counter()
        try:
            with self.lock:
                self._check_frame(header)
                # The plan starts start_delay after planning is expected to end (this kind of
                # goal took that long last time), stamped so; it must be planned with at least
                # DELIVERY s to spare for sending and for the controller, else planned again
                # further ahead.
                delay = (self.get_parameter('start_delay').value * 2 ** attempt
                         + 1.5 * self._planning_time.get(kind, FIRST_PLANNING[kind]))
                ref = self._reference()
                for _ in range(4):
                    start = self.start_state(delay, ref, measured)
                    plan = plan_fn(start.state, measured[1])
                    if self.get_clock().now().nanoseconds * 1e-9 < start.time - DELIVERY:
                        break
                    delay = 2.0 * delay + (time.perf_counter() - t0)
        except (ValueError, Unreachable) as exc:
            self._refuse(kind, key, str(exc))
            return
        planning_ms = (time.perf_counter() - t0) * 1e3
        self._planning_time[kind] = planning_ms * 1e-3
        names = list(plan.joint_names or self.names)
        period = self.planner.settings.sample_period
        own = points = plan.samples(period)
        t_start, carry_from = start.time, start.carry_from
        stamp = t_start
        carried = None if carry_from is None else carried_points(self._sent, carry_from, t_start, period, names)
        if carried is not None:
            # The plans this one carries on from, as far as the controller may not have them.
            points = (np.concatenate([carried[0], own[0] + (t_start - carry_from)]),
                      *(np.concatenate([c, o]) for c, o in zip(carried[1:], own[1:])))
            stamp = carry_from
        try:
            # Checked as the controller will check it: a plan it would reject is never sent as accepted.
            check_joint_limits(self.arm, *points, names=names)
        except Unreachable as exc:
            self._refuse(kind, key, f'the plan breaks a limit (from {start.words()}: the arm\'s motion '
                                    f'cannot be carried on within it): {exc}')
            return
        stamp_ns = int(round(stamp * 1e9))
        self._publish_trajectory(names, stamp_ns, points)
        self._forget_old()
        self._sent.append(SentPlan(plan.trajectory, t_start, names, start.carries_on))
        self._newest_plan = (stamp_key(stamp_ns), (kind, header, plan_fn), attempt, self._sent[-1])
        summary = plan.summary(self.planner.settings.sample_period)
        segments = '; '.join(f'{s.label}: {s.method} {s.duration:.3f} s' for s in plan.segments)
        again = ' again (the last plan reached the controller too late)' if attempt else ''
        self._answer(status(
            'picking_planner', Level.OK, f'{kind} goal accepted{again}: {plan.method}, {plan.duration:.3f} s',
            goal=key, kind=kind, method=plan.method, duration=plan.duration, start=start.source,
            peak_velocity=summary['peak_velocity'], peak_acceleration=summary['peak_acceleration'],
            segments=segments, planning_ms=planning_ms, attempt=attempt + 1, **getattr(plan, 'extra', {})))
        self._publish_tool_path(own[1])
        self.get_logger().info(f'{kind} goal: {plan.method}, {plan.duration:.3f} s, planned in {planning_ms:.1f} ms')

    def _on_controller_status(self, msg):
        """Plan the newest goal again, from where the arm is now, when the controller refused its
        plan as late (too late, or stale: see LATE_REPLANS), up to LATE_REPLANS times; then the
        goal is answered as not run."""
        if Level.of(msg.level) != Level.ERROR or self._newest_plan is None:
            return
        values = status_values(msg)
        trajectory, goal, attempt, sent = self._newest_plan
        if values.get('late') != 'True' or values.get('trajectory') != trajectory:
            return
        self._newest_plan = None
        with self.lock:
            if sent in self._sent:           # the controller never ran it: no later plan carries on from it
                self._sent.remove(sent)
        kind, header = goal[:2]
        key = stamp_key(header.stamp)
        if attempt >= LATE_REPLANS:
            self._answer(status('picking_planner', Level.ERROR, f'{kind} goal not run: its plan reached the controller '
                                f'too late {attempt + 1} times (a stalled or overloaded machine?)', goal=key, kind=kind))
            self.get_logger().error(f'{kind} goal {key}: its plan reached the controller too late '
                                    f'{attempt + 1} times; not planned again')
            return
        self.get_logger().warning(f'{kind} goal {key}: the controller got its plan too late ({msg.message}); '
                                  'planning it again, further ahead')
        self._handle(*goal, attempt=attempt + 1)

    def _controller_listens(self, wait=5.0):
        """True once a controller's subscription has matched (discovery may still be running)."""
        end = time.monotonic() + wait
        while self.pub_traj.get_subscription_count() == 0:
            if time.monotonic() > end:
                return False
            time.sleep(0.02)
        return True

    def _publish_trajectory(self, names, stamp_ns, points):
        """The plan on ``joint_trajectory``, stamped with its start time (integer ns)."""
        self.pub_traj.publish(self.codec.joint_trajectory(stamp_ns, '', names, *points))

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
