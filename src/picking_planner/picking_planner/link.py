"""The planner node's side of the goal flow's :class:`~picking_core.goals.runner.Port`: the controller's
``follow_joint_trajectory`` action, the arm's state, the clock, and what the planner publishes
(``planned_trajectory``, ``planned_path``, ``planner_status``)."""

from __future__ import annotations

import collections
import os
import time
from functools import partial

import numpy as np
from action_msgs.msg import GoalStatus
from control_msgs.action import FollowJointTrajectory
from diagnostic_msgs.msg import DiagnosticStatus
from nav_msgs.msg import Path
from rclpy.action import ActionClient
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory
from unique_identifier_msgs.msg import UUID

from picking_common.codec import Codec
from picking_common.joint_state import reorder, seconds
from picking_common.status import Level, stamp_key, status
from picking_common.topics import BURST, RELIABLE, LatestMessage
from picking_core.pick_cycle import GRIPPER_JOINT

RESULT_WORDS = {GoalStatus.STATUS_SUCCEEDED: 'succeeded', GoalStatus.STATUS_CANCELED: 'canceled'}
#: s between two questions to a controller that has not answered the planner yet.
PROBE_PERIOD = 1.0
#: Probes left waiting for their answer at most (older ones are given up: a deaf controller leaks none).
PROBES_PENDING = 5


class ControllerLink:
    """The port of ``node``'s goal flow (set ``runner`` once made): ``node`` has ``arm``, ``names``,
    ``goal_planner()`` and the parameter ``reference_timeout``."""

    def __init__(self, node):
        self.node, self.runner = node, None
        self.client = ActionClient(node, FollowJointTrajectory, 'follow_joint_trajectory')
        # A controller the planner has discovered may not yet have discovered the planner (on a loaded host one side
        # of DDS discovery has lagged the other by seconds): its answers to a plan would be lost. Plans wait until it
        # has answered a harmless question, the result of a goal it never had, on the action's own service.
        self.probe = node.create_client(FollowJointTrajectory.Impl.GetResultService,
                                        'follow_joint_trajectory/_action/get_result')
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
        self.commands = LatestMessage(node, JointState, 'joint_commands', reader=self.codec.state_reader())

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
            return 'no controller serves follow_joint_trajectory: the plan cannot be run'
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
        return q, _gripper(msg.name, msg.position)

    def reference(self):
        """The controller's newest reference ``((q, qd, qdd), gripper)`` if fresh, else None."""
        msg = self.commands.take()
        if msg is None or self.now() - self.seconds(_ns(msg.header.stamp)) > \
                self.node.get_parameter('reference_timeout').value:
            return None
        names = self.node.names
        try:
            q = reorder(msg.name, msg.position, names, 'joint_commands')
            qd = reorder(msg.name, msg.velocity, names, 'joint_commands') if len(msg.velocity) else 0 * q
            qdd = reorder(msg.name, msg.effort, names, 'joint_commands') if len(msg.effort) else 0 * q
        except (ValueError, IndexError):
            return None
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(qd)) and np.all(np.isfinite(qdd))):
            return None
        return (q, qd, qdd), _gripper(msg.name, msg.position)

    def goal_planner(self):
        return self.node.goal_planner()

    # -- to the controller ----------------------------------------------------------------------
    def send(self, flight, points, stamp):
        """``flight``'s plan as a FollowJointTrajectory goal stamped ``stamp`` (schedule s; 0: now); its answers go
        to the runner."""
        stamp_ns = self._origin_ns + int(round(stamp * 1e9)) if stamp else 0
        names = list(flight.names)
        flight.trajectory = flight.extra['trajectory'] = stamp_key(stamp_ns)
        # (An action goal is a message; the topic takes the same trajectory as CDR bytes, far cheaper to write.)
        future = self.client.send_goal_async(
            FollowJointTrajectory.Goal(trajectory=self.messages.joint_trajectory(stamp_ns, '', names, *points)),
            feedback_callback=partial(self._on_feedback, flight))
        future.add_done_callback(partial(self._on_response, flight))
        self.pub_traj.publish(self.codec.joint_trajectory(stamp_ns, '', names, *points))
        self._publish_tool_path(points[1])

    def cancel(self, flight):
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
        self.runner.on_result(flight, RESULT_WORDS.get(response.status, 'aborted'), response.result.error_code, text)

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


def _gripper(names, positions):
    if GRIPPER_JOINT not in names:
        return None
    g = positions[list(names).index(GRIPPER_JOINT)]
    return float(g) if np.isfinite(g) else None
