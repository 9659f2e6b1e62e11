"""How goals flow through the planner node (part of :class:`~picking_planner.node.PlannerNode`).

Goals come from the topics and the actions, wait while the arm's state or the controller is not
known (or the controller has not answered the last plan), are planned, and go to the controller's
``follow_joint_trajectory`` action; its answers end them. The decisions are the pure classes'
(:class:`~picking_core.goal_policy.GoalPolicy`, :class:`~picking_core.lifecycle.Lifecycle`);
this part turns messages into their calls and their answers into messages.
"""

from __future__ import annotations

import time
import uuid
from dataclasses import replace
from functools import partial

import numpy as np
from action_msgs.msg import GoalStatus
from control_msgs.action import FollowJointTrajectory
from picking_interfaces.action import FollowPath, MoveToPose, Pick
from rclpy.action import CancelResponse
from rclpy.time import Time
from rclpy.task import Future

from picking_common.joint_state import seconds
from picking_common.status import Level, stamp_key, status
from picking_common.topics import newest_waiting

from picking_core import around
from picking_core.goal_policy import WAIT_LIMIT, ZERO_KEY, Goal, Unsettled
from picking_core.harvest import Harvest, HarvestGoal, HarvestRun
from picking_core.collision import STEP as COLLISION_STEP, Allowed
from picking_core.kinematics import Unreachable, pose_matrix
from picking_core.kinematics.paths import check_joint_limits
from picking_core.lifecycle import Ending, Flight, Outcome
from picking_core.pick_cycle import PickCycle
from picking_core.planning import JERK_UNBOUNDED, PATH_METHODS, POSE_METHODS
from picking_core.pick_cycle import GRIPPER_JOINT
from picking_core.trajectory import waypoints

RESULTS = {'pose': MoveToPose, 'path': FollowPath, 'pick': Pick}


def msg_pose(pose):
    """4x4 matrix from a geometry_msgs/Pose; ValueError for NaN or a zero quaternion."""
    p, o = pose.position, pose.orientation
    return pose_matrix([p.x, p.y, p.z], [o.x, o.y, o.z, o.w])


def goal_id(header):
    """The id of a goal that came on a topic: its stamp as text, or a fresh one when it is zero."""
    key = stamp_key(header.stamp)
    return uuid.uuid4().hex if key == ZERO_KEY else key


def _stamp(goal):
    """The status value naming a topic goal as its sender knows it: its header stamp."""
    return {'stamp': goal.stamp} if goal.stamp else {}


class GoalFlow:
    """Goals from the topics and the actions, through planning, to the controller and back."""

    # -- goals ---------------------------------------------------------------------------
    def _check_frame(self, header):
        frame = header.frame_id.lstrip('/')
        if frame not in ('', self.arm.base_frame):
            raise ValueError(f'goal frame {header.frame_id!r} is not the base frame {self.arm.base_frame!r} '
                             '(no TF here: give poses in the base frame, or leave frame_id empty)')

    def _plan_pose(self, pose_stamped, method=''):
        self._check_frame(pose_stamped.header)
        planner = self._planner_for(method, POSE_METHODS, 'method')
        return lambda start, _: around.plan_pose(planner, self.world.checker, start, msg_pose(pose_stamped.pose),
                                                 method or None)

    def _plan_path(self, pose_array, method=''):
        self._check_frame(pose_array.header)
        if not pose_array.poses:
            raise ValueError('the path has no poses')
        planner = self._planner_for(method, PATH_METHODS, 'path_method')
        poses = [msg_pose(p) for p in pose_array.poses]
        return lambda start, _: around.plan_path(planner, self.world.checker, start, poses, method or None)

    def _planner_for(self, method, methods, parameter):
        """The planner for a goal that names its own method (empty: the node's parameter). A method that
        steps the acceleration (cubic, LSPB), asked for by name, is planned as the paper defines it: with
        the velocity and acceleration limits, not the jerk limits."""
        if not method:
            return self.planner
        if method not in methods:
            raise ValueError(f'unknown {parameter} {method!r}; choose one of {", ".join(methods)}')
        if method in JERK_UNBOUNDED and self.planner.settings.limit_jerk:
            return self.planner.with_settings(limit_jerk=False, **{parameter: method})
        return self.planner

    def _plan_pick(self, target):
        self._check_frame(target.header)
        pose = msg_pose(target.pose)

        def plan(start, gripper):
            return PickCycle(self.planner, self.pick, self.world.checker).plan(start, pose, gripper_start=gripper)
        plan.apples = [pose]
        return plan

    def _plan_harvest(self, targets):
        self._check_frame(targets.header)
        if not targets.poses:
            raise ValueError('the harvest has no apples (an empty PoseArray)')
        return HarvestGoal(Harvest(PickCycle(self.planner, self.pick, self.world.checker)),
                           [msg_pose(p) for p in targets.poses])

    def _after_apple_in_hand(self, t):
        """A harvest replacing the running one starts when its apple in hand is in the box."""
        newest = next(reversed(self._harvests.values()), None)
        return t if newest is None else newest.after_apple_in_hand(t)

    def _every_tenth(self):
        """The node's one timer: the goal that waits, then a running harvest's apples."""
        self._serve_waiting()
        self._harvest_progress()

    def _harvest_progress(self):
        """Each apple of a running harvest reported once it is in the box."""
        now = self._ros_now()
        for key, run in self._harvests.items():
            for k, apple in run.newly_picked(now):
                self._publish_apple(key, apple.index, 'picked', f'in the box ({k} of {len(run.plan.apples)})',
                                    picked=k, started=apple.start, at=apple.end)

    def _publish_apple(self, key, index, word, words, **values):
        state = {'picked': 'executing', 'skipped': 'planned'}.get(word, 'ended')
        self.pub_status.publish(status('picking_planner', Level.OK if word == 'picked' else Level.WARN,
                                       f'harvest goal {key}: apple {index} {word}: {words}', goal=key,
                                       kind='harvest', state=state, apple=index, apple_state=word, **values))

    # -- goals from the topics -----------------------------------------------------------
    # A goal's id is its header stamp (a sender that hears no answer sends the same goal again, and
    # is answered again) or, stamped zero as `ros2 topic pub` sends it, an id of its own.
    def _take(self, sub, msg, kind, plan):
        """The newest goal waiting on ``sub`` (every older one answered as superseded), planned with
        ``plan(msg)`` unless it is a resend of a goal already taken."""
        older = []
        msg = newest_waiting(sub, msg, older.append)
        key, stamp = goal_id(msg.header), stamp_key(msg.header.stamp)
        for old in older:
            # (The same goal sent again while the planner was busy is that goal, not an older one.)
            if stamp == ZERO_KEY or old != msg:
                self._end_waiting(kind, goal_id(old.header), stamp_key(old.header.stamp))
        # (Compared as messages: their CDR bytes may differ in the padding between fields.)
        repeat, answer = self.policy.repeat(key, msg, self._now())
        if repeat:
            if answer is not None:            # (None: it is still in flight)
                self.pub_status.publish(answer)
            self.get_logger().info(f'goal {key} came again: its answer was sent again, it is not planned twice')
            return
        try:
            planner = plan(msg)
        except ValueError as exc:
            self._end(Goal(kind, key, None, stamp=stamp), Ending(Outcome.REFUSED, str(exc)))
            return
        self._handle(Goal(kind, key, planner, self._now(), stamp=stamp))

    def _on_goal_pose(self, msg):
        self._take(self.sub_pose, msg, 'pose', self._plan_pose)

    def _on_goal_path(self, msg):
        self._take(self.sub_path, msg, 'path', self._plan_path)

    def _on_pick_target(self, msg):
        self._take(self.sub_pick, msg, 'pick', self._plan_pick)

    def _on_harvest_targets(self, msg):
        self._take(self.sub_harvest, msg, 'harvest', self._plan_harvest)

    # -- goals from the actions ----------------------------------------------------------
    async def _execute(self, kind, plan, handle):
        """One action goal, through the same lifecycle as the topics' goals; its result is the
        controller's (or the reason it never ran)."""
        key = bytes(handle.goal_id.uuid).hex()
        done = Future()
        result_type, feedback_type = RESULTS[kind].Result, RESULTS[kind].Feedback

        def finish(outcome, message, code, duration):
            if not done.done():
                done.set_result(result_type(outcome=int(outcome), message=message, controller_error_code=code,
                                            duration=duration))

        def feedback(phase, time_left, tracking_error):
            handle.publish_feedback(feedback_type(phase=phase, time_left=time_left, tracking_error=tracking_error))

        try:
            planner = plan(handle.request)
        except ValueError as exc:
            goal = Goal(kind, key, None, self._now(), finish=finish)
            self._end(goal, Ending(Outcome.REFUSED, str(exc)))
        else:
            self._handle(Goal(kind, key, planner, self._now(), finish=finish, feedback=feedback))
        result = await done
        if result.outcome == Outcome.SUCCEEDED:
            handle.succeed()
        elif result.outcome == Outcome.CANCELED and handle.is_cancel_requested:
            handle.canceled()
        else:
            handle.abort()
        return result

    def _recheck_running(self):
        """The world changed (a new scene or canopy): the rest of every plan the controller runs is
        checked against it. A harvest that would touch something only after the apple in hand is planned
        again from there, its apples not started around the new world (the same goal goes on); any other
        plan that would now touch something is stopped there (the controller brakes to rest; the goal
        ends aborted with the contact)."""
        now = self._ros_now()
        for flight in list(self.lifecycle.flights.values()):
            if flight.handle is None or flight.plan is None or flight.cancel or flight.stopped:
                continue
            rest = _Rest(flight.plan, max(0.0, now - flight.start))
            if rest.duration <= 0.0:
                continue
            contact = self.world.check(rest, list(flight.regions), slack=COLLISION_STEP / 2)
            if contact is None:
                continue
            changed = f'the world changed while it ran: {contact} (t from the change)'
            again = self._harvest_around(flight, now, contact, changed)
            if again is None:
                self._stop(flight, changed)
                continue
            words = (f'{changed}; the apples not started ({" ".join(str(i) for i in again.plan.indices)}) are '
                     'planned again around it, from the box after the apple in hand')
            self.get_logger().warning(f'harvest goal {flight.goal.key}: {words}')
            self._answer(flight.goal.key, status('picking_planner', Level.WARN, f'harvest goal replanned: {words}',
                                                 goal=flight.goal.key, kind='harvest', state='replanned',
                                                 **_stamp(flight.goal)))
            self._handle(again)

    def _stop(self, flight, why):
        """Stop a running plan at the controller (it brakes to rest): its goal ends aborted, ``why``."""
        flight.stopped = f'{why}; the arm braked to rest'
        self.get_logger().warning(f'{flight.goal.kind} goal {flight.goal.key}: {flight.stopped}')
        flight.handle.cancel_goal_async()

    def _refuse(self, goal, words):
        """A goal's plan cannot go out: the goal ends refused; or, for the rest of a running harvest
        planned again around a changed world, the plan still running is stopped (it would hit)."""
        running = self.lifecycle.flights.get(goal.key)
        if getattr(goal.plan, 'continues', False) and running is not None and running.handle is not None:
            self._stop(running, f'{goal.plan.why}, and the rest could not be planned again around it ({words})')
            return
        self._end(goal, Ending(Outcome.REFUSED, words))

    def _harvest_around(self, flight, now, contact, changed):
        """The goal of a running harvest planned again around a changed world (``contact``, the first along
        the rest of its plan; ``changed``, it in words), its apples not started before the apple in hand
        is in the box (None: not a harvest, the contact comes sooner, or no apple is left)."""
        run = self._harvests.get(flight.goal.key)
        if flight.goal.kind != 'harvest' or run is None or not isinstance(flight.goal.plan, HarvestGoal):
            return None
        # Where a plan made now would take over (as _handle will place it).
        splice = run.after_apple_in_hand(now + self.policy.delay(flight.goal))
        left = [a.index for a in run.plan.apples if run.start + a.start >= splice - 1e-9]
        if now + contact.time <= splice or not left:
            return None
        rest = flight.goal.plan.rest(Harvest(PickCycle(self.planner, self.pick, self.world.checker)), left, changed,
                                     splice)
        return replace(flight.goal, plan=rest, came=self._now())     # (it may wait: from now)

    def _cancel(self, handle):
        """A goal in flight is canceled at the controller (which brakes the arm to rest, then
        answers); a waiting one ends at once."""
        key = bytes(handle.goal_id.uuid).hex()
        flight = self.lifecycle.flights.get(key)
        if flight is not None:
            flight.cancel = True
            if flight.handle is not None:
                flight.handle.cancel_goal_async()
            return CancelResponse.ACCEPT
        waiting = self.policy.waiting
        if waiting is not None and waiting.key == key:
            self.policy.waiting = None
            self._end(waiting, Ending(Outcome.CANCELED, 'canceled before it was planned'))
            return CancelResponse.ACCEPT
        return CancelResponse.REJECT

    # -- the lifecycle -------------------------------------------------------------------
    def _end(self, goal, ending, duration=0.0):
        """A goal's final answer: on planner_status, in the log, and to its action client."""
        outcome = ending.outcome
        level = {Outcome.SUCCEEDED: Level.OK, Outcome.SUPERSEDED: Level.WARN, Outcome.CANCELED: Level.WARN}.get(
            outcome, Level.ERROR)
        text = f'{goal.kind} goal {outcome.word}: {ending.message}'
        harvest = {}
        run = self._harvests.pop(goal.key, None) if goal.kind == 'harvest' else None
        if run is not None:
            finished = outcome == Outcome.SUCCEEDED
            text += f' ({run.words(self._ros_now(), finished)})'
            harvest = run.summary(self._ros_now(), finished)
            apple = None if finished else run.in_hand(self._ros_now())
            if apple is not None:
                self._publish_apple(goal.key, apple.index, 'failed', f'the harvest {outcome.word} during its cycle: '
                                    f'{ending.message}', started=apple.start)
        self._answer(goal.key, status('picking_planner', level, text, goal=goal.key, kind=goal.kind,
                                      state=outcome.word, controller_error_code=ending.code, **_stamp(goal), **harvest))
        if outcome == Outcome.SUPERSEDED:
            self._superseded += 1
            if self._now() - self._superseded_logged > 1.0:
                self.get_logger().warn(f'{self._superseded} goals superseded by newer ones')
                self._superseded, self._superseded_logged = 0, self._now()
        elif level == Level.ERROR:
            self.get_logger().error(text)
        else:
            self.get_logger().info(text)
        if goal.finish is not None:
            goal.finish(outcome, ending.message, ending.code, duration)

    def _end_waiting(self, kind, key, stamp=''):
        self._end(Goal(kind, key, None, stamp=stamp),
                  Ending(Outcome.SUPERSEDED, 'a newer goal came before it was planned'))

    def _answer(self, key, msg):
        """Publish the answer to goal ``key`` (kept, should the goal come again)."""
        self.policy.answered(key, msg)
        self.pub_status.publish(msg)

    def _ready(self):
        """None when a goal can be planned now, else why not (the arm's state or a controller unknown yet)."""
        if self.measured() is None:
            return 'no joint_states received: the planner does not know where the arm is'
        if not self.controller.server_is_ready():
            return 'no controller serves follow_joint_trajectory: the plan cannot be run'
        if self.lifecycle.unanswered():
            return 'the controller has not answered the last plan yet'
        return None

    def _serve_waiting(self):
        """The goal that waits for the arm's state or a controller: planned once both are known,
        refused after a few seconds (discovery may still be running when a node starts). Goals
        the controller leaves unanswered end as aborted."""
        why = self._ready() if self.policy.waiting is not None else None
        ready, refused = self.policy.waited(why is None, self._now())
        if ready is not None:
            self._handle(ready)
        if refused is not None:
            self._end(refused, Ending(Outcome.REFUSED, f'{why} (waited {WAIT_LIMIT:g} s)'))
        for flight, ending in self.lifecycle.overdue(self._now(), self._ros_now()):
            if flight.handle is not None:
                flight.handle.cancel_goal_async()
            self._end(flight.goal, ending, flight.duration)

    def _handle(self, goal):
        """Plan a goal and send the plan to the controller; a goal that comes before the arm's
        state or a controller is known waits (never blocking the executor)."""
        if self._ready() is not None:
            old = self.policy.wait(goal)
            if old is not None:
                self._end(old, Ending(Outcome.SUPERSEDED, 'a newer goal came while it waited'))
            return
        kind, policy = goal.kind, self.policy
        measured = self.measured()
        t0 = time.perf_counter()
        try:
            # The plan must end planning DELIVERY s before its start, else it is planned again further ahead.
            # Planned again after coming too late: also allow for how long delivery takes now.
            delay = policy.delay(goal) + (2.0 * self.lifecycle.latency if goal.attempt else 0.0)
            ref = self._reference()
            for _ in range(4):
                t_start = self._ros_now() + delay
                if kind == 'harvest':
                    t_start = self._after_apple_in_hand(t_start)
                    if t_start > getattr(goal.plan, 'after', np.inf) + 1e-6:
                        # (The rest of a harvest planned again: the running plan starts another apple by then.)
                        raise ValueError('it could not be planned in time to take over after the apple in hand')
                # A harvest replacing a running one starts in the box after the apple in hand: exactly there.
                start = policy.start_state(t_start, ref, measured[0], exact=kind == 'harvest' and bool(self._harvests))
                # The gripper as the plan running then leaves it (the reference carries the arm's joints only).
                gripper = policy.planned_joint(start.time, GRIPPER_JOINT) if start.carries_on else None
                plan = policy.plan(goal, start, measured[1] if gripper is None else gripper)
                if policy.on_time(self._ros_now(), start):
                    break
                # (Allowing as long again as planning took for the rest: building the message, sending it.)
                later = policy.postponed(start, self._ros_now() + policy.start_delay + (time.perf_counter() - t0))
                if later is not None:
                    start = later
                    break
                delay = 2.0 * delay + (time.perf_counter() - t0)
        except Unsettled as exc:
            # Asked again at the node's next tenth of a second, until WAIT_LIMIT after it came.
            if self._now() - goal.came < WAIT_LIMIT:
                old = self.policy.wait(goal)
                if old is not None and old is not goal:
                    self._end(old, Ending(Outcome.SUPERSEDED, 'a newer goal came while it waited'))
                return
            self._refuse(goal, f'{exc} (waited {WAIT_LIMIT:g} s)')
            return
        except (ValueError, Unreachable) as exc:
            self._refuse(goal, str(exc))
            return
        # Every plan is checked against the world before it is sent (a pick's cycles were planned clear of
        # it; this also catches a pose or path goal's plan, and a harvest's way home).
        regions = [Allowed(np.asarray(T)[:3, 3], self.pick.apple_region) for T in getattr(goal.plan, 'apples', ())]
        contact = self.world.check(plan.trajectory, regions, slack=COLLISION_STEP / 2)
        if contact is not None:
            self._refuse(goal, f'the plan would hit an obstacle: {contact}')
            return
        planning_ms = (time.perf_counter() - t0) * 1e3
        names = list(plan.joint_names or self.names)
        period = self.planner.settings.sample_period
        own = waypoints(plan.trajectory, period, before=start.state[2])
        points, stamp = policy.points(own, start, period, names)
        try:
            # Checked as the controller will check it: a plan it would refuse is never sent.
            check_joint_limits(self.arm, *points, names=names)
        except Unreachable as exc:
            self._refuse(goal, f'the plan breaks a limit (from {start.words()}: the arm\'s motion cannot be '
                               f'carried on within it): {exc}')
            return
        trajectory = self.messages.joint_trajectory(self._stamp_ns(stamp), '', names, *points)
        # A long plan from rest (a harvest) may be due before its message is even built: it starts later as
        # it is, allowing as long again as its preparation took for the sending.
        if not policy.on_time(self._ros_now(), start):
            later = policy.postponed(start, self._ros_now() + policy.start_delay + (time.perf_counter() - t0))
            if later is not None:
                start, stamp = later, later.time
                trajectory.header.stamp = Time(nanoseconds=self._stamp_ns(stamp)).to_msg()
        stamp_ns = self._stamp_ns(stamp)
        policy.planned(goal, time.perf_counter() - t0)     # the next goal of its kind expects as long to be ready
        running = self.lifecycle.flights.get(goal.key) if getattr(goal.plan, 'continues', False) else None
        flight = self.lifecycle.sent(Flight(
            goal, start.time, plan.duration, [(s.label, s.start, s.start + s.duration) for s in plan.segments],
            self._now(), stamp_key(stamp_ns), plan=plan.trajectory, regions=tuple(regions), replaces=running))
        future = self.controller.send_goal_async(FollowJointTrajectory.Goal(trajectory=trajectory),
                                                 feedback_callback=partial(self._on_feedback, goal, flight))
        future.add_done_callback(partial(self._on_response, goal, flight))
        self.pub_traj.publish(trajectory)
        policy.sent_plan(goal, plan.trajectory, start, names, flight.trajectory, self._ros_now(),
                         self.get_parameter('reference_timeout').value, stamp=stamp)
        summary = plan.summary(period)
        flight.extra = dict(method=plan.method, duration=plan.duration, start=start.source,
                            peak_velocity=summary['peak_velocity'], peak_acceleration=summary['peak_acceleration'],
                            segments='; '.join(f'{s.label}: {s.method} {s.duration:.3f} s' for s in plan.segments),
                            planning_ms=planning_ms, attempt=goal.attempt + 1, **getattr(plan, 'extra', {}))
        self._publish_tool_path(own[1])
        if kind == 'harvest':
            for run in self._harvests.values():   # the one it replaces: the apples in the box by then
                run.until = min(run.until, start.time)
            # (The same goal planned again around a changed world carries on from its run: those apples count.)
            before = self._harvests.pop(goal.key, None)
            self._harvests[goal.key] = HarvestRun(goal.plan.last, start.time,
                                                  before=before if goal.plan.continues else None)
            for skip in goal.plan.last.skipped:
                self._publish_apple(goal.key, skip.index, 'skipped', skip.reason)
        self.get_logger().info(f'{kind} goal: {plan.method}, {plan.duration:.3f} s, planned in {planning_ms:.1f} ms')

    def _transition(self, goal, state, words):
        flight = self.lifecycle.flights.get(goal.key)
        extra = flight.extra if flight is not None else {}
        again = ' again (the last plan reached the controller too late)' if goal.attempt else ''
        self._answer(goal.key, status('picking_planner', Level.OK, f'{goal.kind} goal {state}{again}: {words}', **_stamp(goal),
                                      goal=goal.key, kind=goal.kind, state=state, **extra))

    def _on_response(self, goal, sent, future):
        handle = future.result()
        ending = self.lifecycle.response(goal.key, handle.accepted, self._now(), sent)
        self._serve_waiting()                 # the goal that waited for this answer
        if ending is not None:
            self._refuse(self._restored(goal, sent), ending.message)
            return
        flight = self.lifecycle.flights.get(goal.key)
        if flight is not sent:                # ended meanwhile (overdue), or planned again since
            handle.cancel_goal_async()
            return
        flight.handle = handle
        if flight.cancel:
            handle.cancel_goal_async()
        taken = ''.join(f', {flight.extra[k]}' for k in ('approach', 'detours') if k in flight.extra)
        self._transition(goal, 'accepted', f"{flight.extra.get('method')}, {flight.duration:.3f} s{taken}")
        handle.get_result_async().add_done_callback(partial(self._on_result, goal, flight))

    def _on_feedback(self, goal, sent, msg):
        fb = msg.feedback
        error = float(np.max(np.abs(fb.error.positions))) if len(fb.error.positions) else 0.0
        if self.lifecycle.feedback(goal.key, error, sent):
            self._transition(goal, 'executing', 'the controller runs its plan')
        # A controller that stalled runs the plan later than sent: everything timed by it moves too.
        later = self.policy.runs_late(sent.trajectory, self._clock_time(fb.header.stamp),
                                      seconds(fb.desired.time_from_start), list(fb.joint_names),
                                      fb.desired.positions)
        if later:
            run = self._harvests.get(goal.key)
            while run is not None and run.start != sent.start:     # the run of this plan (see HarvestRun.before)
                run = run.before
            sent.start += later
            if run is not None:
                run.start += later
        if goal.feedback is not None and goal.key in self.lifecycle.flights:
            # (The plan this feedback is about: one the same goal was planned again after runs on until the
            # newer one takes over.)
            phase, left = sent.phase(self._ros_now())
            goal.feedback(phase, left, error)

    def _on_result(self, goal, flight, future):
        response = future.result()
        words = {GoalStatus.STATUS_SUCCEEDED: 'succeeded', GoalStatus.STATUS_CANCELED: 'canceled'}.get(
            response.status, 'aborted')
        ending = self.lifecycle.result(goal.key, words, response.result.error_code, response.result.error_string,
                                       flight)
        if ending is None:
            return                            # ended already (overdue)
        if not ending.late:
            self._end(goal, ending, flight.duration)
            return
        late = self.policy.late(flight.trajectory)
        if late is None or not late.again:
            self._end(goal, Ending(Outcome.REFUSED, f'its plan reached the controller too late {goal.attempt + 1} '
                                                    f'times (a stalled or overloaded machine?): {ending.message}',
                                   ending.code))
            return
        self.get_logger().warning(f'{goal.kind} goal {goal.key}: the controller got its plan too late '
                                  f'({ending.message}); planning it again, further ahead')
        self._handle(self._restored(late.goal, flight))

    def _restored(self, goal, sent):
        """``goal`` after its plan ``sent`` did not run: the plan it was to take over from (the rest of a
        harvest planned again around a changed world) is the goal's running plan again, its run the goal's."""
        if sent.replaces is not None and goal.key not in self.lifecycle.flights:
            self.lifecycle.flights[goal.key] = sent.replaces
        run = self._harvests.get(goal.key)
        if run is not None and run.before is not None and run.start == sent.start:
            run.before.until = np.inf
            self._harvests[goal.key] = run.before
        return goal


class _Rest:
    """The part of a trajectory from ``t0`` (s) on, as its own trajectory (time 0 at ``t0``)."""

    def __init__(self, trajectory, t0):
        self.trajectory, self.t0 = trajectory, t0
        self.duration = max(0.0, trajectory.duration - t0)

    def sample(self, t):
        return self.trajectory.sample(np.asarray(t, float) + self.t0)
