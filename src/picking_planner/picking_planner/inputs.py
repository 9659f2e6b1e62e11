"""The planner's goals as ROS gives them: its goal topics and actions, made into the goal flow's goals.

Topics: ``goal_pose`` (PoseStamped), ``goal_path`` (PoseArray), ``pick_target`` (PoseStamped),
``harvest_targets`` (PoseArray): each message a goal without a result, named by its header stamp (a
zero stamp, as ``ros2 topic pub`` sends it, gets an id of its own); ``retarget`` (PoseStamped) moves
the running pose or pick goal's target. Actions: ``move_to_pose``, ``follow_path``, ``pick``
(picking_interfaces), each goal ending in a result.
"""

from __future__ import annotations

import uuid
from functools import partial

from geometry_msgs.msg import PoseArray, PoseStamped
from picking_interfaces.action import FollowPath, MoveToPose, Pick
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.task import Future

from picking_common.poses import msg_pose
from picking_common.status import stamp_key
from picking_common.topics import BURST, newest_waiting
from picking_core.goals.intake import ZERO_KEY
from picking_core.goals.lifecycle import Ending, Outcome
from picking_core.goals.requests import Goal, Kind, Target

RESULTS = {Kind.POSE: MoveToPose, Kind.PATH: FollowPath, Kind.PICK: Pick}
#: s an ended goal's result is kept for its client (rclpy's default, 15 min, lets every client's status array grow).
RESULT_TIMEOUT = 30


def goal_id(header):
    """The id of a goal that came on a topic: its stamp as text, or a fresh one when it is zero."""
    key = stamp_key(header.stamp)
    return uuid.uuid4().hex if key == ZERO_KEY else key


class GoalInputs:
    """The goal topics and actions of ``node``, handed to its goal flow ``runner``; ``in_base(header)`` is the 4x4
    transform of a message's frame into the arm's base (ValueError naming the frames when there is none)."""

    def __init__(self, node, runner, in_base):
        self.node, self.runner, self.in_base = node, runner, in_base
        self.subs = {kind: node.create_subscription(msg_type, topic, partial(self._on_topic, kind), BURST)
                     for kind, msg_type, topic in ((Kind.POSE, PoseStamped, 'goal_pose'),
                                                   (Kind.PATH, PoseArray, 'goal_path'),
                                                   (Kind.PICK, PoseStamped, 'pick_target'),
                                                   (Kind.HARVEST, PoseArray, 'harvest_targets'))}
        self.sub_retarget = node.create_subscription(PoseStamped, 'retarget', self._on_retarget, BURST)
        self.actions = [ActionServer(node, RESULTS[kind], name, execute_callback=partial(self._execute, kind),
                                     goal_callback=lambda _: GoalResponse.ACCEPT, cancel_callback=self._cancel)
                        for kind, name in ((Kind.POSE, 'move_to_pose'), (Kind.PATH, 'follow_path'), (Kind.PICK, 'pick'))]

    def target(self, kind, msg, method=''):
        """The :class:`Target` of a goal message (PoseStamped or PoseArray) in the arm's base frame; ValueError naming
        what is wrong."""
        poses = (msg.pose,) if kind in (Kind.POSE, Kind.PICK) else tuple(msg.poses)
        poses = tuple(msg_pose(p) for p in poses)
        T = self.in_base(msg.header)
        return Target(kind, tuple(T @ pose for pose in poses), method)

    # -- topics ------------------------------------------------------------------------------------
    def _on_topic(self, kind, msg):
        """The newest goal waiting on the topic (every older one answered as superseded), taken unless it is a
        resend of a goal already taken (compared as messages: their bytes may differ in the padding)."""
        older = []
        msg = newest_waiting(self.subs[kind], msg, older.append)
        stamp = stamp_key(msg.header.stamp)
        for old in older:
            # (The same goal sent again while the planner was busy is that goal, not an older one.)
            if stamp == ZERO_KEY or old != msg:
                passed = Goal(kind, goal_id(old.header), None, stamp=stamp_key(old.header.stamp))
                try:
                    passed.target = self.target(kind, old)
                except ValueError:
                    pass                       # superseded all the same; only a place of a pick's apple is used
                self.runner.passed_over(passed)
        goal = Goal(kind, goal_id(msg.header), None, self.runner.port.wall(),
                    stamp=stamp)
        try:
            goal.target = self.target(kind, msg)
        except ValueError as exc:
            self.runner.end(goal, Ending(Outcome.REFUSED, str(exc)))
            return
        self.runner.take(goal, content=msg)

    def retarget_waiting(self):
        """Handle a re-target that is waiting. The executor runs timers before subscriptions: the runner's tick,
        which ends a re-targeted goal whose stream has paused, must first see the update that already came."""
        got = self.sub_retarget.handle.take_message(self.sub_retarget.msg_type, self.sub_retarget.raw)
        if got is not None:
            self._on_retarget(got[0])

    def _on_retarget(self, msg):
        msg = newest_waiting(self.sub_retarget, msg, self._replaced)
        try:
            pose = self.in_base(msg.header) @ msg_pose(msg.pose)
        except ValueError as exc:
            self.node.get_logger().error(f'retarget refused: {exc}', throttle_duration_sec=1.0)
            return
        why = self.runner.retarget(pose, self.runner.port.wall(), stamp_key(msg.header.stamp))
        if why is not None:
            self.node.get_logger().warning(f'retarget not taken: {why}', throttle_duration_sec=1.0)

    def _replaced(self, msg):
        """A re-target a newer one replaced before it was taken: counted, and for a pick a place of its apple."""
        try:
            pose = self.in_base(msg.header) @ msg_pose(msg.pose)
        except ValueError:
            pose = None
        self.runner.replaced(pose, stamp_key(msg.header.stamp))

    # -- actions -----------------------------------------------------------------------------------
    async def _execute(self, kind, handle):
        """One action goal, through the same flow as the topics' goals; its result is the controller's (or the
        reason it never ran)."""
        done = Future()
        result_type, feedback_type = RESULTS[kind].Result, RESULTS[kind].Feedback

        def finish(outcome, message, code, duration):
            if not done.done():
                done.set_result(result_type(outcome=int(outcome), message=message, controller_error_code=code,
                                            duration=duration))

        def feedback(phase, time_left, tracking_error):
            handle.publish_feedback(feedback_type(phase=phase, time_left=time_left, tracking_error=tracking_error))

        goal = Goal(kind, bytes(handle.goal_id.uuid).hex(), None, self.runner.port.wall(),
                    finish=finish, feedback=feedback)
        request = handle.request
        try:
            goal.target = self.target(kind, request.target if kind == Kind.PICK else
                                      request.pose if kind == Kind.POSE else request.path,
                                      '' if kind == Kind.PICK else request.method)
        except ValueError as exc:
            self.runner.end(goal, Ending(Outcome.REFUSED, str(exc)))
        else:
            self.runner.take(goal)
        result = await done
        if result.outcome == Outcome.SUCCEEDED:
            handle.succeed()
        elif result.outcome == Outcome.CANCELED and handle.is_cancel_requested:
            handle.canceled()
        else:
            handle.abort()
        return result

    def _cancel(self, handle):
        """A goal under way is canceled (at the controller, which brakes the arm to rest, then answers)."""
        taken = self.runner.cancel(bytes(handle.goal_id.uuid).hex())
        return CancelResponse.ACCEPT if taken else CancelResponse.REJECT
