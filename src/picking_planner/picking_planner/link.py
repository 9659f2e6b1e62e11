"""The planner node's side of the goal flow's :class:`~picking_core.goals.runner.Port`: the controller's
FollowJointTrajectory action (``controller_action``), a GripperCommand action where the gripper has its own
(``gripper_action``), the arm's state and the controller's reference, the clock, and what the planner publishes
(``planned_trajectory``, ``planned_path``, ``planner_status``)."""

from __future__ import annotations

import collections
import os
import time
from functools import partial

import numpy as np
from action_msgs.msg import GoalStatus
from control_msgs.action import FollowJointTrajectory, GripperCommand
from control_msgs.msg import GripperCommand as GripperTarget
from control_msgs.msg import JointTrajectoryControllerState
from diagnostic_msgs.msg import DiagnosticStatus
from nav_msgs.msg import Path
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory
from unique_identifier_msgs.msg import UUID

from picking_common.actions import ActionClient
from picking_common.codec import Codec
from picking_common.joint_state import reorder, seconds
from picking_common.status import Level, stamp_key, status
from picking_common.topics import BURST, RELIABLE, LatestMessage
from picking_core.goals.gripper import GripperSchedule, gripper_moves, judge
from picking_core.pick_cycle import gripper_column

RESULT_WORDS = {GoalStatus.STATUS_SUCCEEDED: 'succeeded', GoalStatus.STATUS_CANCELED: 'canceled'}
#: s between two questions to a controller that has not answered the planner yet.
PROBE_PERIOD = 1.0
#: Probes left waiting for their answer at most (older ones are given up: a deaf controller leaks none).
PROBES_PENDING = 5
#: s between two looks at the gripper's commands due (while some are pending).
GRIPPER_PERIOD = 0.005
#: s a trajectory's result waits for its gripper commands' answers before it is given without them.
GRIPPER_ANSWER = 5.0


class ControllerLink:
    """The port of ``node``'s goal flow (set ``runner`` once made): ``node`` has ``arm``, ``names``,
    ``goal_planner()`` and the parameter ``reference_timeout``."""

    def __init__(self, node):
        self.node, self.runner = node, None
        value = lambda name: node.get_parameter(name).value  # noqa: E731
        action = self.action_name = value('controller_action')
        self.client = ActionClient(node, FollowJointTrajectory, action)
        # A controller the planner has discovered may not yet have discovered the planner (on a loaded host one side
        # of DDS discovery has lagged the other by seconds): its answers to a plan would be lost. Plans wait until it
        # has answered a harmless question, the result of a goal it never had, on the action's own service.
        self.probe = node.create_client(FollowJointTrajectory.Impl.GetResultService, f'{action}/_action/get_result')
        self.heard, self._asked = False, -1e9
        self._probes = collections.deque()          # the probes still waiting for their answer, oldest first
        # Times on the ROS clock count from here: as float seconds of the epoch they would resolve a quarter of a
        # microsecond, too coarse for a plan's own times (its acceleration steps are a microsecond long).
        self._origin_ns = node.get_clock().now().nanoseconds - 1_000_000_000
        # Trajectories and tool paths are written straight to CDR bytes (much faster than the message classes)
        # where this middleware reads them back as the same messages; action goals are messages.
        self.codec, self.messages = Codec(), Codec(raw=False)
        self.pub_traj = node.create_publisher(JointTrajectory, 'planned_trajectory', RELIABLE)
        self.pub_path = node.create_publisher(Path, 'planned_path', RELIABLE)
        self.pub_status = node.create_publisher(DiagnosticStatus, 'planner_status', BURST)
        # The measured state and the controller's reference, taken when a goal comes: no executor callbacks at
        # their rates (rclpy spends about a millisecond on each).
        self.states = LatestMessage(node, JointState, 'joint_states', reader=self.codec.state_reader())
        self.state_topic = value('controller_state')
        self.commands = (LatestMessage(node, JointTrajectoryControllerState, self.state_topic) if self.state_topic else
                         LatestMessage(node, JointState, 'joint_commands', reader=self.codec.state_reader()))
        # A gripper with an action of its own: commanded when a plan moves it; its opening is its action's newest word.
        gripper = value('gripper_action')
        self.gripper = ActionClient(node, GripperCommand, gripper) if gripper else None
        self.schedule = GripperSchedule()
        self.opening = None
        self._waiting = {}                          # flight serial -> (flight, its result, when it came)
        self._gripper_timer = node.create_timer(GRIPPER_PERIOD, self._gripper_tick) if gripper else None

    # -- clock and state ------------------------------------------------------------------------
    @staticmethod
    def wall():
        return time.monotonic()

    def now(self):
        """The controller's clock (the ROS clock), s from this link's origin."""
        return self.seconds(self.node.get_clock().now().nanoseconds)

    def seconds(self, ns):
        """A ROS time (ns) on :meth:`now`'s clock, s."""
        return (ns - self._origin_ns) * 1e-9

    def ready(self):
        if self.measured() is None:
            return 'no joint_states received: the planner does not know where the arm is'
        if not self.client.server_is_ready():
            self.heard = False
            return f'no controller serves {self.action_name}: the plan cannot be run'
        if not self.heard:
            self._ask_controller()
            return 'the controller has yet to hear the planner (discovery under way)'
        return None

    def _ask_controller(self):
        if self.wall() - self._asked < PROBE_PERIOD or not self.probe.service_is_ready():
            return
        self._asked = self.wall()
        while self._probes and self._probes[0].done():
            self._probes.popleft()
        if len(self._probes) >= PROBES_PENDING:
            self.probe.remove_pending_request(self._probes.popleft())
        request = FollowJointTrajectory.Impl.GetResultService.Request(goal_id=UUID(uuid=list(os.urandom(16))))
        future = self.probe.call_async(request)
        future.add_done_callback(self._on_answer)
        self._probes.append(future)

    def _on_answer(self, future):
        self.heard = True

    def measured(self):
        """The newest valid joint_states: ``(q, gripper opening or None)``, or None before any."""
        msg = self.states.take()
        if msg is None:
            return None
        try:
            q = reorder(msg.name, msg.position, self.node.names, 'joint_states')
        except (ValueError, IndexError):
            return None
        if not np.all(np.isfinite(q)):
            return None
        return q, self._opening(msg.name, msg.position)

    def _opening(self, names, positions):
        """The gripper's opening: its action's newest word where it has one, else its joint in ``names``."""
        return self.opening if self.gripper is not None else _gripper(names, positions, gripper_column(self.node.arm))

    def reference(self):
        """The controller's newest reference ``((q, qd, qdd), gripper)`` if fresh, else None: picking-controller's
        joint_commands (accelerations in ``effort``), or a joint trajectory controller's ``reference``."""
        msg = self.commands.take()
        if msg is None or self.now() - self.seconds(_ns(msg.header.stamp)) > \
                self.node.get_parameter('reference_timeout').value:
            return None
        if self.state_topic:
            ref = msg.reference
            given, p, v, a, what = msg.joint_names, ref.positions, ref.velocities, ref.accelerations, self.state_topic
        else:
            given, p, v, a, what = msg.name, msg.position, msg.velocity, msg.effort, 'joint_commands'
        names = self.node.names
        try:
            q = reorder(given, p, names, what)
            qd = reorder(given, v, names, what) if len(v) else 0 * q
            qdd = reorder(given, a, names, what) if len(a) else 0 * q
        except (ValueError, IndexError):
            return None
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(qd)) and np.all(np.isfinite(qdd))):
            return None
        return (q, qd, qdd), self._opening(given, p)

    def goal_planner(self):
        return self.node.goal_planner()

    # -- to the controller ----------------------------------------------------------------------
    def send(self, flight, points, stamp):
        """``flight``'s plan as a FollowJointTrajectory goal stamped ``stamp`` (schedule s; 0: now); its answers go
        to the runner."""
        stamp_ns = self._origin_ns + int(round(stamp * 1e9)) if stamp else 0
        names = list(flight.names)
        column = gripper_column(self.node.arm)
        if self.gripper is not None and column in names:
            # The arm's controller gets the arm's joints; the opening column becomes the gripper's commands.
            g = names.index(column)
            keep = [i for i in range(len(names)) if i != g]
            self.schedule.plan(flight.serial, stamp or self.now(), gripper_moves(points[0], points[1][:, g]))
            names = [names[i] for i in keep]
            points = (points[0], *(p[:, keep] for p in points[1:]))
            self._gripper_timer.reset()
        flight.trajectory = flight.extra['trajectory'] = stamp_key(stamp_ns)
        # (An action goal is a message; the topic takes the same trajectory as CDR bytes, far cheaper to write.)
        future = self.client.send_goal_async(
            FollowJointTrajectory.Goal(trajectory=self.messages.joint_trajectory(stamp_ns, '', names, *points)),
            feedback_callback=partial(self._on_feedback, flight))
        future.add_done_callback(partial(self._on_response, flight))
        self.pub_traj.publish(self.codec.joint_trajectory(stamp_ns, '', names, *points))
        self._publish_tool_path(points[1])

    def cancel(self, flight):
        self.schedule.drop(flight.serial)
        if flight.handle is not None:
            flight.handle.cancel_goal_async()

    def ask_result(self, flight):
        """Ask again for an overdue result; if the action's status topic already says the goal succeeded or was
        canceled, that ends it: a controller whose service answers do not reach this planner (one side of DDS
        discovery lagging the other on a loaded host) still publishes its goals' statuses. (An abort waits for its
        result, which says why.)"""
        if flight.handle is None:
            return
        ended = RESULT_WORDS.get(flight.handle.status)
        if ended is not None:
            self.runner.on_result(flight, ended, 0, f'{ended}, as the action status says (its result did not come)')
            return
        flight.handle.get_result_async().add_done_callback(partial(self._on_result, flight))

    def _on_response(self, flight, future):
        handle = future.result()
        if not handle.accepted:
            self.schedule.drop(flight.serial)
        self.runner.on_response(flight, handle.accepted, handle)
        if handle.accepted:
            handle.get_result_async().add_done_callback(partial(self._on_result, flight))

    def _on_feedback(self, flight, msg):
        fb = msg.feedback
        error = float(np.max(np.abs(fb.error.positions))) if len(fb.error.positions) else 0.0
        self.runner.on_feedback(flight, self.seconds(_ns(fb.header.stamp)), seconds(fb.desired.time_from_start), error,
                                dict(zip(fb.joint_names, fb.desired.positions)))

    def _on_result(self, flight, future):
        response = future.result()
        text = response.result.error_string
        if response.status == GoalStatus.STATUS_UNKNOWN:
            text = 'the controller does not know the goal (it restarted, or forgot it)'
        result = (RESULT_WORDS.get(response.status, 'aborted'), response.result.error_code, text)
        if self.gripper is None:
            self.runner.on_result(flight, *result)
            return
        if result[0] == 'succeeded':
            self._gripper_tick()                     # a command due by the end goes now, and is answered first
        else:
            self.schedule.drop(flight.serial)
        self._waiting[flight.serial] = (flight, result, self.wall())
        self._gripper_timer.reset()                  # (to give the result without its answers if they never come)
        self._settle(flight.serial)

    # -- the gripper's own action ----------------------------------------------------------------
    def _gripper_tick(self):
        """Send the gripper's commands due; give the results that waited too long for their gripper's answers."""
        for serial, command in self.schedule.due(self.now()):
            self._send_gripper(serial, command)
        for serial, (_, _, since) in list(self._waiting.items()):
            if self.wall() - since > GRIPPER_ANSWER:
                for c in self.schedule.commands.get(serial, []):
                    if c.sent and not c.done:
                        c.done, c.failure = True, f'the gripper did not answer the command to {c.target:g}'
                self._settle(serial)
        if self.schedule.next_time() is None and not self._waiting:
            self._gripper_timer.cancel()

    def _send_gripper(self, serial, command):
        goal = GripperCommand.Goal(command=GripperTarget(position=float(command.target), max_effort=0.0))
        if not self.gripper.server_is_ready():
            command.done, command.failure = True, 'no gripper action server: the gripper could not be commanded'
            self._settle(serial)
            return
        future = self.gripper.send_goal_async(goal, feedback_callback=self._on_gripper_feedback)
        future.add_done_callback(partial(self._on_gripper_response, serial, command))

    def _on_gripper_feedback(self, msg):
        self.opening = float(msg.feedback.position)

    def _on_gripper_response(self, serial, command, future):
        handle = future.result()
        if not handle.accepted:
            command.done, command.failure = True, judge(command, False, 'rejected', 0.0, False, False)
            self._settle(serial)
            return
        handle.get_result_async().add_done_callback(partial(self._on_gripper_result, serial, command))

    def _on_gripper_result(self, serial, command, future):
        response = future.result()
        r = response.result
        self.opening = float(r.position)
        word = RESULT_WORDS.get(response.status, 'aborted')
        command.done, command.failure = True, judge(command, True, word, r.position, r.stalled, r.reached_goal)
        if command.failure:
            self.log('WARN', command.failure)
        self._settle(serial)

    def _settle(self, serial):
        """A trajectory's result, once its gripper commands are answered (a gripper's failure fails a success)."""
        waiting = self._waiting.get(serial)
        if waiting is None:
            return
        done, failure = self.schedule.settled(serial)
        if not done:
            return
        flight, (word, code, text), _ = self._waiting.pop(serial)
        self.schedule.forget(serial)
        if word == 'succeeded' and failure:
            word, text = 'aborted', failure
        self.runner.on_result(flight, word, code, text)

    # -- what the planner says ------------------------------------------------------------------
    def status(self, level, text, **values):
        msg = status('picking_planner', Level[level], text, **values)
        self.pub_status.publish(msg)
        return msg

    def repeat(self, message):
        self.pub_status.publish(message)

    def log(self, level, text):
        logger = self.node.get_logger()
        # One call per severity: rclpy ties a call site to one severity.
        if level == 'ERROR':
            logger.error(text)
        elif level == 'WARN':
            logger.warning(text)
        elif level == 'DEBUG':
            logger.debug(text)
        else:
            logger.info(text)

    def _publish_tool_path(self, q):
        """The tool poses of the plan (every other point) on ``planned_path``, for RViz or Foxglove."""
        arm = self.node.arm
        arm_q = q[:, :arm.dof]
        tool = arm.fk(arm_q[::2] if len(arm_q) > 2 else arm_q)
        quats = Rotation.from_matrix(tool[:, :3, :3]).as_quat()
        self.pub_path.publish(self.codec.path(self.node.get_clock().now().nanoseconds, arm.base_frame,
                                              tool[:, :3, 3], quats))

    def close(self):
        self.states.destroy()
        self.commands.destroy()


def _ns(stamp):
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def _gripper(names, positions, joint):
    if joint not in names:
        return None
    g = positions[list(names).index(joint)]
    return float(g) if np.isfinite(g) else None
