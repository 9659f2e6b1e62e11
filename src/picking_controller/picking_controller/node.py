"""``picking-controller``: the joint trajectory controller node (ROS shell around core.py).

Serves the ``follow_joint_trajectory`` action (``control_msgs/action/FollowJointTrajectory``, as
ros2_controllers' joint trajectory controller) and subscribes ``joint_trajectory`` (the same
trajectories without a result) and ``joint_states``; publishes ``joint_commands``
at ``update_rate`` from a timing thread with absolute deadlines,
``controller_status`` for every accepted or rejected trajectory, goal reached,
tolerance violation, and feedback lost or restored, and ``controller_loop``
once a second: how well the loop keeps its clock since it began commanding
(achieved rate, period error percentiles, missed deadlines, CPU).

``joint_commands`` carries position (rad), velocity (rad/s) and, in ``effort``,
the reference acceleration (rad/s^2) as feedforward for the servo.
"""

from __future__ import annotations

import collections
import threading
import time

import numpy as np
from control_msgs.action import FollowJointTrajectory, GripperCommand
from control_msgs.msg import JointTrajectoryControllerState
from diagnostic_msgs.msg import DiagnosticStatus
from rcl_interfaces.msg import SetParametersResult
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.task import Future
from rclpy.time import Time
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

from picking_common.codec import Codec
from picking_common.joint_state import reorder, seconds
from picking_common.loop import PeriodicLoop, check_priority, make_realtime
from picking_common.loop_stats import LoopStats
from picking_common.params import declare, usage
from picking_common.run import run_node
from picking_common.status import Diagnostics, Level, stamp_key, status
from picking_common.topics import BURST, RELIABLE, LatestMessage, newest_waiting
from picking_core.kinematics import ArmModel
from picking_description import default_urdf

from .core import ControllerCore, ErrorCode, Event, Mode, Outcome, Tolerances
from .parameters import PARAMS, RUNTIME

#: s an ended goal's result is kept for its client: past the planner's first ask again (RESULT_RETRY after a plan's
#: end). Every goal kept is in every goal status message, which each client reads whole, in Python: a stream of
#: re-targets at 30 Hz keeps this many seconds of goals in each.
RESULT_TIMEOUT = 2
#: Hz of controller_state (a joint trajectory controller publishes it at its update rate; this one's loop is 1 kHz).
STATE_RATE = 100.0


def _tolerances(p):
    return Tolerances(path=p['path_tolerance'], goal=p['goal_tolerance'], goal_time=p['goal_time_tolerance'],
                      stopped_velocity=p['stopped_velocity_tolerance'], state_timeout=p['state_timeout'])


class ControllerNode(Node):
    """ROS interface of the trajectory controller."""

    def __init__(self, **kwargs):
        super().__init__('picking_controller', **kwargs)
        p = declare(self, PARAMS)
        urdf = p['urdf_path']
        self.rate = float(p['update_rate'])
        thread_priority = check_priority(p['thread_priority'])
        executor_priority = check_priority(p['executor_priority'], 'executor_priority')
        if not (executor_priority == 0 or executor_priority < thread_priority):
            raise ValueError(f'executor_priority must be 0 (normal) or 1 to thread_priority - 1 '
                             f'({thread_priority - 1}), got {executor_priority}')
        if not self.rate > 0:
            raise ValueError(f'update_rate must be > 0 Hz, got {self.rate}')
        loop_phase = p['loop_phase']
        self.arm = ArmModel.from_urdf(urdf or default_urdf())
        extra = len(self.arm.extra_joint_names)
        self.core = ControllerCore(self.arm.all_joint_names, *self.arm.all_limits, _tolerances(p),
                                   optional=self.arm.extra_joint_names, stall_limit=p['stall_limit'],
                                   max_jerk=np.concatenate([self.arm.max_jerk, np.full(extra, np.inf)]),
                                   gripper=self.arm.gripper_joint)
        self.lock = threading.Lock()
        self.add_on_set_parameters_callback(self._on_parameters)
        self.pub_cmd = self.create_publisher(JointState, 'joint_commands', RELIABLE)
        # Each status is an event (accepted, goal reached, ...): a slow reader must not lose one.
        self.pub_status = self.create_publisher(DiagnosticStatus, 'controller_status', BURST)
        self.pub_loop = self.create_publisher(DiagnosticStatus, 'controller_loop', RELIABLE)
        self.codec = Codec()
        self._splice_delay = 0.02       # s ahead that a new trajectory takes over (see _on_trajectory)
        self._commanding = False
        self.create_timer(1.0, self._report_loop)
        self.diagnostics = Diagnostics(self, self.arm.name, self._diagnose)
        # Taken as bytes and read with numpy where our reader agrees with this middleware: the
        # message class holds the GIL for milliseconds on a few hundred points, which the control
        # loop would wait for.
        self.sub_trajectory = self.create_subscription(JointTrajectory, 'joint_trajectory', self._on_trajectory,
                                                       RELIABLE, raw=self.codec.raw)
        # The control thread takes the newest joint_states itself at each tick: no
        # executor callbacks (and no GIL held by another thread) at the state's rate.
        self.states = LatestMessage(self, JointState, 'joint_states', reader=self.codec.state_reader())
        self._last_state = None
        self._writer = self.codec.joint_state_writer(self.core.names)
        # Action goals still running: their key -> (handle, the future their result arrives on). Events that
        # end goals come from the control thread; the executor thread settles them.
        self._goals = {}
        self._ended = collections.deque()
        self._settle = self.create_guard_condition(self._settle_goals)
        # Ended goals' results are kept RESULT_TIMEOUT s for their clients (rclpy's default, 15 min, lets the status
        # array every client reads grow with each goal of a stream of re-targets).
        self.action = ActionServer(self, FollowJointTrajectory, 'follow_joint_trajectory',
                                   execute_callback=self._execute, goal_callback=self._on_goal,
                                   cancel_callback=self._cancel, result_timeout=RESULT_TIMEOUT)
        # The gripper on a GripperCommand action of its own, as gripper_action_controller serves it (an alternative
        # to moving it in the trajectories; the planner's gripper_action parameter chooses).
        self._gripper_goal, self._gripper_answers = None, collections.deque()
        if self.core.gripper is not None:
            self.gripper_action = ActionServer(self, GripperCommand, 'gripper_cmd',
                                               execute_callback=self._execute_gripper,
                                               cancel_callback=lambda _: CancelResponse.ACCEPT,
                                               result_timeout=RESULT_TIMEOUT)
            self._gripper_settle = self.create_guard_condition(self._settle_gripper)
            # Runs only while a gripper goal does: an idle controller's executor stays asleep.
            self._gripper_feedback = self.create_timer(1.0 / p['action_monitor_rate'], self._publish_gripper_feedback)
            self._gripper_feedback.cancel()
        # The state a joint trajectory controller publishes (its reference, the measurement, their difference), for
        # clients written for ros2_controllers; joint_commands carries the same reference at the loop's rate.
        self.pub_state = self.create_publisher(JointTrajectoryControllerState, 'controller_state', RELIABLE)
        self._newest = None                          # (stamp ns, reference) of the loop's last command
        self.create_timer(1.0 / STATE_RATE, self._publish_state)
        monitor_rate = p['action_monitor_rate']
        # Runs only while an action goal does: an idle controller's executor stays asleep.
        self._feedback_timer = self.create_timer(1.0 / monitor_rate, self._publish_feedback)
        self._feedback_timer.cancel()
        self.loop = PeriodicLoop(1.0 / self.rate, self._tick, name='control', logger=self.get_logger(),
                                 phase=loop_phase, priority=thread_priority)
        self.loop_stats = self.loop.stats
        self.get_logger().info(f'controlling {len(self.core.names)} joints at {self.rate:g} Hz; waiting for joint_states')
        self.loop.start()
        # This thread goes on to run the executor: trajectories (milliseconds of Python each), status,
        # parameters. It shares the GIL with the loop; at normal priority, any real-time thread on
        # the machine (another arm's loops) can preempt it while it holds the GIL, and the loop
        # waits for it (priority inversion). Just below the loop, it is not preempted that way.
        make_realtime(executor_priority, self.get_logger(), 'the executor thread')

    def _on_parameters(self, params):
        """The tolerances and the stall limit take effect at once, for the trajectories that start after
        (ROS checked their ranges); the other parameters are read-only."""
        changed = {p.name: p.value for p in params if p.name in RUNTIME}
        if changed:
            values = {name: self.get_parameter(name).value for name in RUNTIME}
            values.update(changed)
            with self.lock:
                self.core.set_tolerances(_tolerances(values), values['stall_limit'])
        return SetParametersResult(successful=True)

    @staticmethod
    def now():
        """The controller's clock, s: the system clock (what the ROS clock reads without sim time;
        a 1 kHz loop runs on real time)."""
        return time.time_ns() * 1e-9

    def _report(self, events):
        for e in events:
            if e.goal is not None and e.outcome is not None:
                self._ended.append(e)
                self._settle.trigger()
            values = e.values if e.goal is None else {**e.values, 'goal': e.goal}
            self.pub_status.publish(status('picking_controller', e.level, e.message, **values))
            # One logging call per severity: rclpy ties a call site to one severity.
            if e.level == 'ERROR':
                self.get_logger().error(e.message)
            elif e.level == 'WARN':
                self.get_logger().warning(e.message)
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
            events = self.core.on_state(q, qd, seconds(msg.header.stamp), self.now())
        self._report(events)

    def _on_trajectory(self, msg):
        """A trajectory from the topic: run like an action goal's, without a result."""
        # Only the newest waiting trajectory counts: a burst never queues up.
        msg = newest_waiting(self.sub_trajectory, msg, lambda old: self._report(
            [Event('WARN', 'trajectory superseded by a newer one before it was checked; not run')]))
        self._run(self.codec.read_trajectory(msg))

    def _run(self, read, goal=None, tolerances=None):
        """Validate and splice a new trajectory without stalling the control loop.

        The checks and the spline run outside the loop's lock, for a splice a
        little ahead (twice the last preparation time); the loop keeps commanding
        the old trajectory until then. Only if the state changed meanwhile (or
        preparing took too long) twice in a row is the work done under the lock.
        """
        args = read.args()
        # Every answer names the trajectory by its stamp (its sender may plan again one that came too late).
        trajectory = stamp_key(read.header.stamp)
        event = None
        for _ in range(2):
            started = time.perf_counter()
            try:
                prepared = self.core.prepare(*args, self.now(), splice_delay=self._splice_delay,
                                             goal=goal, tolerances=tolerances)
            except ValueError as exc:
                event = self.core.rejected(exc, goal=goal, trajectory=trajectory)
                break
            self._splice_delay = min(max(0.005, 2.0 * (time.perf_counter() - started)), 0.05)
            with self.lock:
                event = self.core.commit(prepared, self.now())
            if event is not None:
                break
        if event is None:
            with self.lock:
                event = self.core.load(*args, self.now(), goal=goal, tolerances=tolerances)
        event.values.setdefault('trajectory', trajectory)
        if event.level == 'OK':                  # when it went on the schedule, on the ROS clock (s, as text)
            event.values['spliced_at'] = f'{self.now():.6f}'
            if self.core.gripper is not None and self.arm.gripper_joint in list(args[0]):
                with self.lock:
                    self.core.gripper.release()  # a trajectory that names the gripper drives it again
        self._report([event])
        if event.level == 'OK' and goal is not None:
            # Its sender learns at once that the schedule has it (an accepted goal may still be refused, as late).
            self._publish_feedback(goal)

    # -- the follow_joint_trajectory action ---------------------------------------------
    def _on_goal(self, request):
        """A goal whose joints are not this arm's is rejected when it is sent, as a joint trajectory controller
        rejects it (the reason goes to controller_status: a rejection carries none)."""
        try:
            self.core.splicer.validator.order(request.trajectory.joint_names)
        except ValueError as exc:
            self._report([Event('ERROR', f'goal rejected: {exc}')])
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    async def _execute_gripper(self, handle):
        """A GripperCommand: the gripper's reference moves to the target; the goal ends when the fingers are there,
        or stalled short of it (see :class:`~.gripper.GripperChannel`); a newer command aborts it."""
        done = Future()
        with self.lock:
            try:
                self.core.command_gripper(handle.request.command.position, self.now())
            except ValueError as exc:
                self.get_logger().warning(f'gripper command refused: {exc}')
                done = None
            else:
                if self._gripper_goal is not None:
                    self._gripper_answers.append((self._gripper_goal, None))
                self._gripper_goal = (handle, done)
                self._gripper_feedback.reset()
        if done is None:
            handle.abort()
            return GripperCommand.Result(position=self.core.measured_gripper() or 0.0)
        if self._gripper_answers:
            self._gripper_settle.trigger()
        answer = await done
        result = GripperCommand.Result(position=self.core.measured_gripper() or 0.0)
        if answer is None:                               # preempted by a newer command
            handle.abort()
        elif answer == 'canceled':
            handle.canceled()
        else:
            result.position, result.stalled, result.reached_goal = answer.position, answer.stalled, answer.reached
            handle.succeed() if answer.word == 'succeeded' else handle.abort()
        return result

    def _judge_gripper(self, now):
        """From the control loop: the running gripper command's end, if it came (settled in the executor)."""
        goal = self._gripper_goal
        if goal is None:
            return
        with self.lock:
            measured = self.core.measured_gripper()
            if goal[0].is_cancel_requested:
                self.core.gripper.cancel(now, measured if measured is not None else self.core.gripper.target)
                answer = 'canceled'
            else:
                answer = self.core.gripper.judge(now, measured) if measured is not None else None
        if answer is not None:
            self._gripper_goal = None
            self._gripper_answers.append((goal, answer))
            self._gripper_settle.trigger()

    def _settle_gripper(self):
        while self._gripper_answers:
            (_, done), answer = self._gripper_answers.popleft()
            if not done.done():
                done.set_result(answer)

    def _publish_gripper_feedback(self):
        goal, measured = self._gripper_goal, self.core.measured_gripper()
        if goal is None:
            self._gripper_feedback.cancel()
        elif measured is not None:
            goal[0].publish_feedback(GripperCommand.Feedback(position=measured))

    def _publish_state(self):
        newest, state = self._newest, self._last_state
        if newest is None or self.pub_state.get_subscription_count() == 0:
            return
        ns, (q, qd, qdd) = newest
        msg = JointTrajectoryControllerState()
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 1_000_000_000)
        msg.joint_names = list(self.core.names)
        msg.reference.positions, msg.reference.velocities = q.tolist(), qd.tolist()
        msg.reference.accelerations = qdd.tolist()
        msg.output.positions = q.tolist()
        if state is not None:
            try:
                measured = reorder(state.name, state.position, self.core.names, 'joint_states')
            except (ValueError, IndexError):
                measured = None
            if measured is not None:
                msg.feedback.positions = measured.tolist()
                msg.error.positions = (q - measured).tolist()
        self.pub_state.publish(msg)

    async def _execute(self, handle):
        """Run one goal; its result comes from the event that ends it (reached, a tolerance
        violated, preempted, canceled, feedback lost), or from the reason it was refused."""
        key = bytes(handle.goal_id.uuid).hex()
        done = Future()
        self._goals[key] = handle, done
        if self._feedback_timer.is_canceled():
            self._feedback_timer.reset()
        request = handle.request
        try:
            if request.multi_dof_trajectory.joint_names or request.multi_dof_trajectory.points:
                raise ValueError('multi_dof_trajectory is not supported: this arm has single-DOF joints only')
            if request.component_path_tolerance or request.component_goal_tolerance:
                raise ValueError('component tolerances are for multi-DOF joints, which this arm does not have')
            tolerances = self.core.default_tolerances.overridden(
                self.core.names, [(t.name, t.position, t.velocity, t.acceleration) for t in request.path_tolerance],
                [(t.name, t.position, t.velocity, t.acceleration) for t in request.goal_tolerance],
                seconds(request.goal_time_tolerance))
        except ValueError as exc:
            self._report([Event('ERROR', f'goal refused: {exc}', goal=key,
                                outcome=Outcome('aborted', ErrorCode.INVALID_GOAL, str(exc)))])
        else:
            self._run(self.codec.read_trajectory(request.trajectory), goal=key, tolerances=tolerances)
        outcome = await done
        if outcome.status == 'succeeded':
            handle.succeed()
        elif outcome.status == 'canceled' and handle.is_cancel_requested:
            handle.canceled()
        else:
            handle.abort()
        return FollowJointTrajectory.Result(error_code=int(outcome.code), error_string=outcome.text)

    def _settle_goals(self):
        while self._ended:
            event = self._ended.popleft()
            _, done = self._goals.pop(event.goal, (None, None))
            if done is not None and not done.done():
                done.set_result(event.outcome)

    def _cancel(self, handle):
        """A running goal brakes to rest within the limits, then ends as canceled."""
        with self.lock:
            accepted, events = self.core.cancel(bytes(handle.goal_id.uuid).hex(), self.now())
        self._report(events)
        return CancelResponse.ACCEPT if accepted else CancelResponse.REJECT

    def _publish_feedback(self, goal=None):
        """The reference, measured state and their difference, to the running goal (or to ``goal``, whose
        trajectory may wait on the schedule: its ``time_from_start`` is then negative)."""
        with self.lock:
            key = self.core.goal if goal is None else goal
            now = self.now()
            state = self.core.feedback(now) if key is not None else None
            elapsed = self.core.trajectory_time(now, goal)
        handle, _ = self._goals.get(key, (None, None))
        if not self._goals:
            self._feedback_timer.cancel()
        if state is None or handle is None:
            return
        (q, qd, qdd), q_meas, qd_meas = state
        fb = FollowJointTrajectory.Feedback()
        fb.header.stamp = Time(nanoseconds=int(now * 1e9)).to_msg()
        fb.joint_names = self.core.names
        fb.desired.positions, fb.desired.velocities, fb.desired.accelerations = q.tolist(), qd.tolist(), qdd.tolist()
        # Where in the goal's own points the reference is: its sender sees how late stalls made it run.
        if elapsed is not None:
            fb.desired.time_from_start = Duration(nanoseconds=int(round(elapsed * 1e9))).to_msg()
        fb.actual.positions = q_meas.tolist()
        fb.error.positions = (q - q_meas).tolist()
        if qd_meas is not None:
            fb.actual.velocities = qd_meas.tolist()
            fb.error.velocities = (qd - qd_meas).tolist()
        handle.publish_feedback(fb)

    def _tick(self, deadline, due):
        """One control period: the reference sampled at the tick's time, stamped with it."""
        ns = time.time_ns()                      # the controller's clock (see now())
        now = ns * 1e-9
        with self.lock:
            delayed = self.core.delayed
            events = self.core.advance(now)      # a stall delays the trajectory: before the feedback check
            later = self.core.delayed != delayed
        state = self.states.take()
        if state is not self._last_state:
            self._last_state = state
            self._on_state(state)
        with self.lock:
            events += self.core.tick(now)
            ref, limited = self.core.command(now)
            events += limited
        self._judge_gripper(now)
        if events:
            self._report(events)
        if later:                                # its sender learns at once how late the plan now runs
            self._publish_feedback()
        if ref is not None:
            if not self._commanding:             # the loop figures count from the first command
                self._commanding = True
                self.loop_stats.reset()
            self.pub_cmd.publish(self._writer.write(ns, *ref))
            self._newest = ns, ref

    def _report_loop(self):
        if self._commanding:
            s = self.loop_stats.summary()
            level = Level.OK if s['missed_percent'] < 0.1 else Level.WARN
            self.pub_loop.publish(status('picking_controller', level, LoopStats.describe(s), **s))

    def _diagnose(self):
        """For /diagnostics: the control loop's health, and what the arm is doing."""
        if self._commanding:
            s = self.loop_stats.summary()
            loop = ('control loop', Level.OK if s['missed_percent'] < 0.1 else Level.WARN, LoopStats.describe(s), s)
        else:
            loop = ('control loop', Level.WARN, 'not commanding yet: waiting for joint_states', {})
        with self.lock:
            mode, feedback, goal = self.core.mode, self.core.feedback_ok, self.core.goal
        if mode != Mode.WAITING and not feedback:
            arm = (Level.ERROR, 'feedback lost: holding, refusing trajectories')
        elif mode == Mode.FAULT:
            arm = (Level.ERROR, 'holding after a tolerance violation until a new trajectory')
        else:
            arm = (Level.OK if mode != Mode.WAITING else Level.WARN, mode.value + (f' (goal {goal})' if goal else ''))
        return [loop, ('trajectory', *arm, {'mode': mode.value})]

    def close(self):
        self.loop.stop()
        self.states.destroy()
        if self._commanding:
            self.get_logger().info('control loop: ' + LoopStats.describe(self.loop_stats.summary()))


def main(args=None):
    return run_node(ControllerNode, args, help=usage('picking-controller', __doc__, PARAMS))


if __name__ == '__main__':
    raise SystemExit(main())
