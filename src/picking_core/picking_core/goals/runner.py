"""The planner's goal flow: goals through planning to the controller and back (pure core).

:class:`GoalRunner` takes goals, lets them wait while the arm's state or a controller is unknown (or the
controller has not answered the plan before: one plan in flight at a time, the newest goal waiting),
plans each from a state it knows (:mod:`.start`), sends the plan to the controller through its
:class:`Port`, and turns the controller's answers into each goal's transitions and end
(:mod:`.lifecycle`). A running goal's target can be moved (:meth:`GoalRunner.retarget`: a stream of
re-targets, the newest winning), and a running harvest whose apples not yet started a changed world
blocks is planned again around it from the box after the apple in hand (:meth:`GoalRunner.world_changed`).

The node implements the port (ROS messages, the action client, the clock) and calls the runner's
``on_*`` methods with the controller's answers; everything else is here, tested without ROS.
"""

from __future__ import annotations

import collections
import itertools
import math
import traceback
from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np

from ..collision import STEP as COLLISION_STEP
from ..harvest import HarvestRun, carried, carrying, empty_below, new_apples
from ..kinematics.paths import check_joint_limits
from ..moving_pick import APPLE_WIDTH, AimHolds, Follow, final_approach
from ..sway import Sightings, SwayFit
from ..trajectory import waypoints
from .intake import WAIT_LIMIT, ZERO_KEY, GoalBook, Waiting
from .lifecycle import LATE_REPLANS, Ending, Flight, Lifecycle, Outcome, State
from .requests import Kind, Rest, Target
from .start import Running, Start, Timing, choose_start

#: s between the samples a plan's peak velocity and acceleration are read at (whatever its points' spacing).
PEAK_SAMPLING = 0.01
#: s a re-targeted pose goal stays open after the arm came to rest at its last target: a stream of re-targets that
#: pauses (a camera's dropout, a sender starved of CPU) moves the same goal on when it resumes.
STREAM_PAUSE = 1.0
#: m: a pick sent on the topic this near the running pick's target names the same apple (a stream of its places):
#: it moves that pick on, as a re-target.
SAME_APPLE = 0.05
#: m: the noise a stream of a pick's places is taken to have when its motion is fitted (a camera's).
STREAM_NOISE = 0.003
#: s: a place stamped further ahead of the clock than this is refused (a sender's clock set wrong).
AHEAD = 0.1
#: The camera's newest diameters of a pick's apple whose median its fingers are timed to meet.
WIDTHS = 60
#: s: a running harvest is aimed again at its next swaying apple once its apple in hand is dropped this soon after
#: a rest could take over (late enough that the aim looks one approach ahead, early enough to be planned in time).
REAIM = 0.3
LEVELS = {Outcome.SUCCEEDED: 'OK', Outcome.SUPERSEDED: 'WARN', Outcome.CANCELED: 'WARN'}


@dataclass
class PickState:
    """What the goal flow knows of a running pick's apple: ``fit`` its motion from its stamped places; ``widths``
    the diameters the camera saw it at (m); ``closes`` when the pick's last plan closes the fingers (ROS clock);
    ``holding_since`` when it first went to the stand-off to wait (wall clock); ``grip`` the narrowest opening
    measured while its plan carried the apple (m)."""

    fit: SwayFit = field(default_factory=SwayFit)
    widths: collections.deque = field(default_factory=lambda: collections.deque(maxlen=WIDTHS))
    closes: float | None = None
    holding_since: float | None = None
    grip: float | None = None

    @property
    def width(self):
        """m: the width its fingers are timed to meet: the camera's median, else a typical apple's."""
        return float(np.median(self.widths)) if self.widths else APPLE_WIDTH

    def sways(self):
        """Whether its places show the apple swaying."""
        fit = self.fit.fit()
        return fit is not None and fit.frequency > 0.0


class Port(Protocol):
    """What the goal flow needs from its node (times in s)."""

    def wall(self) -> float: ...                 # time.monotonic()
    def now(self) -> float: ...                  # the controller's clock (ROS time)
    def seconds(self, ns) -> float: ...          # a ROS time in ns on that clock
    def ready(self) -> str | None: ...           # why no goal can be planned now (no joint_states, no controller)
    def reference(self): ...                     # ((q, qd, qdd), gripper) the controller commands now, or None
    def measured(self): ...                      # (q, gripper) of the newest joint_states, or None
    def goal_planner(self): ...                  # the GoalPlanner of the moment (its settings may change)
    def send(self, flight, points, stamp): ...   # the plan's points (t, q, qd, qdd) to the controller, stamped
    def cancel(self, flight): ...                # cancel the flight's goal at the controller
    def ask_result(self, flight): ...            # ask the controller for the flight's result (once more)
    def status(self, level, text, **values): ... # publish a planner_status; returns what was published
    def repeat(self, message): ...               # publish an earlier status again (a goal sent again)
    def log(self, level, text): ...


class GoalRunner:
    """One planner's goals, through the :class:`Port` ``port``."""

    def __init__(self, port, timing=None):
        self.port = port
        self.book, self.waiting, self.lifecycle = GoalBook(), Waiting(), Lifecycle()
        self.timing = timing or Timing()
        self.running = None              # Running: our newest plan the controller accepted
        self.harvests = {}               # goal key -> HarvestRun of the harvests sent and not ended, oldest first
        self._places = {}                # goal key -> {apple index: (x, y, z)} of a harvest under way
        self._reaimed = {}               # goal key -> the drops of its apples in hand it was aimed again before
        self.retargets = {'spliced': 0, 'replaced': 0}
        #: Judge each picked or harvested apple by the measured gripper (else it is claimed by the plan's clock).
        self.grasp_check = True
        self._moves = {}                 # goal key -> its re-targets: received, spliced, replaced, refused
        self._paused = {}                # goal key -> (goal, ending, duration, until): re-targeted, at rest, open
        self._picks = {}                 # pick goal key -> PickState of its apple
        self.sightings = Sightings()     # the camera's recent frames (:meth:`seen`)
        self._serial = itertools.count(1)
        self._superseded, self._superseded_said = 0, -math.inf

    # -- goals in ------------------------------------------------------------------------------
    def resent(self, goal, content):
        """Whether ``goal`` with ``content`` (compared with ==) is one taken already, sent again: then its newest answer
        is sent again, and it is not to be planned twice."""
        repeat, answer = self.book.repeat(goal.key, content, goal.came)
        if repeat:
            if answer is not None:
                self.port.repeat(answer)
            self.port.log('INFO', f'goal {goal.key} came again: its answer was sent again, it is not planned twice')
        return repeat

    def take(self, goal, content=None):
        """A new goal; ``content`` (compared with ==) tells the same goal sent again, answered again and not
        planned twice (None: never a resend, or told apart by :meth:`resent` before)."""
        if content is not None and self.resent(goal, content):
            return
        if goal.kind == Kind.PICK and self._same_apple(goal):
            return
        self._end_paused()
        try:
            self.port.goal_planner().check(goal.target)
        except ValueError as exc:
            self.end(goal, Ending(Outcome.REFUSED, str(exc)))
            return
        if goal.kind == Kind.PICK:
            pick = self._picks[goal.key] = PickState()
            fit = pick.fit
            for t, p, diameter in self.sightings.of(goal.target.pose[:3, 3], SAME_APPLE):
                fit.update(t, p, np.eye(3) * STREAM_NOISE ** 2)
                pick.widths.append(diameter)
            # (Where the camera saw the apple, the sender's place of it is a rough one beside those.)
            noise = STREAM_NOISE if fit.newest is None else SAME_APPLE
            follow, why = self._place(goal.key, goal.target.pose, self._stamp_time(goal.stamp), noise)
            if why is not None:
                self.end(goal, Ending(Outcome.REFUSED, why.replace('its place', 'the apple', 1)))
                return
            if pick.sways():
                goal = goal.again(target=replace(goal.target, follow=follow))
        self._handle(goal)

    def passed_over(self, goal):
        """``goal`` came on its topic but a newer one came before it was taken: ended superseded. A pick's place of the
        running pick's apple is one more place of it all the same (its motion is fitted from every place seen; only
        the newest is planned)."""
        running = self._topic_pick_of(goal)
        if running is not None and not running.target.back_off:
            _, why = self._place(running.key, goal.target.pose, self._stamp_time(goal.stamp))
            taken = 'a place of it taken' if why is None else f'its place not taken: {why}'
            self.end(goal, Ending(Outcome.SUPERSEDED, f'the apple of pick goal {running.key} ({taken}); a newer place '
                                                      'came before it was planned'))
            return
        self.end(goal, Ending(Outcome.SUPERSEDED, 'a newer goal came before it was planned'))

    def _same_apple(self, goal):
        """A pick sent on the topic near the running topic pick's target moves that pick on (True: answered here)."""
        running = self._topic_pick_of(goal) if goal.feedback is None else None
        if running is None:
            return False
        why = self.retarget(goal.target.pose, goal.came, goal.stamp)
        if why is not None and why.startswith('its place'):
            self.end(goal, Ending(Outcome.REFUSED, f'the apple of pick goal {running.key}, but {why}'))
        else:
            taken = 'taken as its new target' if why is None else f'not moved: {why}'
            self.end(goal, Ending(Outcome.SUPERSEDED, f'the apple of pick goal {running.key}: {taken}'))
        return True

    def _topic_pick_of(self, goal):
        """The running pick (sent on the topic) whose apple pick ``goal`` places, or None."""
        running = self._retargetable()
        if goal.kind != Kind.PICK or goal.target is None or running is None or running.kind != Kind.PICK \
                or running.feedback is not None:
            return None
        near = self._near_apple(self._picks.get(running.key), running.target.pose[:3, 3], goal.target.pose[:3, 3],
                                self._stamp_time(goal.stamp))
        return running if near else None

    @staticmethod
    def _near_apple(pick, target, p, t):
        """Whether ``p`` seen at ``t`` (s, the port's clock) is ``pick``'s apple: within SAME_APPLE of its newest place
        (``target`` before it has one), or of where its sway puts it then (a stream that stalled finds it farther
        on)."""
        fit = pick.fit if pick is not None else None
        places = [target if fit is None or fit.newest is None else fit.newest]
        predicted = fit.predict(t) if fit is not None else None
        if predicted is not None:
            places.append(predicted[0])
        return min(np.linalg.norm(np.asarray(q) - p) for q in places) <= SAME_APPLE

    def _stamp_time(self, stamp):
        """A goal's stamp (text) on the port's clock (the ROS clock, as its places are stamped); now for none."""
        if not stamp or stamp == ZERO_KEY:
            return self.port.now()
        sec, nsec = stamp.split('.')
        return self.port.seconds(int(sec) * 1_000_000_000 + int(nsec))

    def _place(self, key, pose, t, noise=STREAM_NOISE):
        """Pick ``key``'s apple seen at ``pose`` at ``t`` (s, the port's clock), ``noise`` m: its motion fitted.
        Returns ``(follow, why)``: the Follow that aims the pick where the apple will be (None while its places are
        too few to tell how it moves), or why the place is refused (stamped ahead of the clock, older than the newest
        place, or far from both the newest place and where the apple's sway puts it then: another apple taken for
        it)."""
        pick = self._picks.get(key)
        if pick is None:
            return None, None
        fit, p = pick.fit, np.asarray(pose, float)[:3, 3]
        if t > self.port.now() + AHEAD:
            return None, f'its place is stamped {t - self.port.now():.3f} s ahead of the clock'
        motion = fit.fit()
        # (Near the newest place it is the same apple all the same: a sway fitted wrongly must not lock it out.)
        if motion is not None and motion.frequency > 0.0 and t >= fit.t and not self._near_apple(pick, fit.newest, p, t):
            off = float(np.linalg.norm(p - fit.predict(t)[0]))
            return None, f'its place jumps {off * 100:.1f} cm from where the apple sways then (another apple?)'
        if not fit.update(t, p, np.eye(3) * noise ** 2):
            return None, 'its place is stamped before the newest one taken (out of order)'
        motion = fit.fit()
        if motion is None or (motion.frequency <= 0.0 and motion.span < fit.s.min_span):
            return None, None                 # too few places to tell how it moves: aimed at the latest
        # (The fingers are timed to meet the apple's width: the camera's, where it saw the apple.)
        return Follow(fit.predict, pick.width, pick.closes, pick.holding_since is not None), None

    def retarget(self, pose, wall, stamp=''):
        """Move the running pose or pick goal's target to ``pose`` (4x4, base frame): planned and spliced on as
        the same goal; a newer re-target arriving while this one waits replaces it; ``stamp`` names the re-target (its
        message's stamp, in the statuses). Returns None, or why the re-target was not taken (no such goal; a pick
        whose final straight approach has begun: a new plan would back out of it; a pick's place refused, see
        :meth:`_place`)."""
        goal = self._retargetable()
        if goal is None:
            return 'no pose or pick goal runs to move'
        if goal.target.back_off:
            self._moved(goal.key, 'refused')
            return f'the pick backs off home: {goal.target.back_off}'
        follow = None
        if goal.kind == Kind.PICK:
            follow, why = self._place(goal.key, pose, self._stamp_time(stamp))
            if why is not None:
                self._moved(goal.key, 'refused')
                return why
        return self._move(goal, pose, follow, wall, stamp)

    def seen(self, places, diameters, stamp):
        """The camera's apples in one frame: their centres ``places`` (N, 3), m in the arm's base, and
        ``diameters`` (N,), m, captured at ``stamp`` (the frame's, as text). The running pick's apple among them
        (the nearest, if it is that apple) is one more place of it, as a stream's on the topic is; once its places
        show it swaying, each moves the pick on (:meth:`retarget`). A still apple's pick keeps its plan."""
        t = self._stamp_time(stamp)
        self.sightings.add(t, places, diameters)
        goal = self._retargetable()
        if goal is None or goal.kind != Kind.PICK or goal.target.back_off or not len(places):
            return
        pick = self._picks.get(goal.key)
        if pick is None:
            return
        fit = pick.fit
        near = fit.newest if fit.newest is not None else goal.target.pose[:3, 3]
        k = int(np.argmin(np.linalg.norm(np.asarray(places, float) - near, axis=1)))
        p = np.asarray(places, float)[k]
        if not self._near_apple(pick, goal.target.pose[:3, 3], p, t):
            return
        pick.widths.append(float(diameters[k]))
        pose = goal.target.pose.copy()
        pose[:3, 3] = p
        follow, why = self._place(goal.key, pose, t)
        if why is None and follow is not None and pick.sways():
            self._move(goal, pose, follow, self.port.wall(), stamp)

    def _move(self, goal, pose, follow, wall, stamp):
        """Re-target running ``goal`` to ``pose`` aimed by ``follow`` (a pick's): None, or why it was not taken."""
        self._paused.pop(goal.key, None)
        flight = self.lifecycle.flights.get(goal.key)
        if goal.kind == Kind.PICK and flight is not None and self._approach_begun(flight):
            return 'the final straight approach to the apple has begun: its target no longer moves'
        self._moved(goal.key, 'received')
        target = goal.target.moved_to(pose)
        if goal.kind == Kind.PICK:
            target = replace(target, follow=follow)
        self._handle(goal.again(target=target, came=wall, attempt=0, retargets=goal.retargets + 1,
                                moved_by=stamp))
        return None

    def _approach_begun(self, flight):
        """Whether pick ``flight``'s final straight approach has begun, by the controller's feedback or, when that is
        older (a plan that was not the goal's for a while), by the schedule clock."""
        elapsed = [t for t in (flight.elapsed, None if flight.start is None else self.schedule_now() - flight.start)
                   if t is not None]
        return bool(elapsed) and max(elapsed) >= final_approach(flight.planned.plan)

    def _moved(self, key, what):
        counts = self._moves.setdefault(key, dict.fromkeys(('received', 'spliced', 'replaced', 'refused', 'held'), 0))
        counts[what] += 1
        if what in ('spliced', 'replaced'):
            self.retargets[what] += 1

    def replaced(self, pose, stamp=''):
        """A re-target to ``pose`` (as :meth:`retarget` takes it) that a newer one replaced before it was taken in
        (coalesced on its topic): counted; for a pick, one more place of its apple all the same."""
        goal = self._retargetable()
        if goal is None:
            return
        self._moved(goal.key, 'received')
        self._moved(goal.key, 'replaced')
        if goal.kind == Kind.PICK and pose is not None and not goal.target.back_off:
            self._place(goal.key, pose, self._stamp_time(stamp))

    def _retargetable(self):
        waiting = self.waiting.goal
        if waiting is not None and waiting.kind in (Kind.POSE, Kind.PICK):
            return waiting
        flights = [f for f in self.lifecycle.flights.values() if f.goal.kind in (Kind.POSE, Kind.PICK) and not f.cancel]
        if flights:
            return max(flights, key=lambda f: f.sent).goal
        return next(reversed(self._paused.values()))[0] if self._paused else None

    def cancel(self, key):
        """Cancel goal ``key``: at the controller when its plan went out (the arm brakes to rest), at once when it
        waits. False when no such goal is under way."""
        flight = self.lifecycle.flights.get(key)
        if flight is not None:
            flight.cancel = True
            if flight.handle is not None:
                self.port.cancel(flight)
            return True
        if self.waiting.goal is not None and self.waiting.goal.key == key:
            self.end(self.waiting.take(), Ending(Outcome.CANCELED, 'canceled before it was planned'))
            return True
        if key in self._paused:
            goal, _, duration, _ = self._paused.pop(key)
            self.end(goal, Ending(Outcome.CANCELED, 'canceled at rest at its last target'), duration)
            return True
        return False

    def cancel_all(self):
        """Cancel every goal under way; returns how many."""
        keys = list(self.lifecycle.flights) + ([self.waiting.goal.key] if self.waiting.goal is not None else []) + \
            list(self._paused)
        return sum(self.cancel(k) for k in keys)

    def blocked(self):
        """Why no goal can be planned now, or None."""
        why = self.port.ready()
        if why is None and self.lifecycle.unanswered():
            why = 'the controller has not answered the last plan yet'
        return why

    def _handle(self, goal):
        if self.blocked() is None:
            self._plan_and_send(goal)
            return
        old = self.waiting.put(goal)
        if old is not None and old.key == goal.key:
            if old.retargets:                         # a newer target of the same goal: it wins
                self._moved(goal.key, 'replaced')
        elif old is not None:
            self.end(old, Ending(Outcome.SUPERSEDED, 'a newer goal came while it waited'))

    def tick(self):
        """A tenth of a second: the waiting goal, overdue answers, a running harvest's apples, re-targeted goals
        at rest whose stream has paused long enough."""
        self._serve_waiting()
        self._end_paused(self.port.wall())
        self._holds_over()
        for flight in self.lifecycle.results_to_ask(self.port.wall(), self.schedule_now()):
            self.port.ask_result(flight)
        for flight, ending in self.lifecycle.overdue(self.port.wall(), self.schedule_now()):
            if flight.handle is not None:
                self.port.cancel(flight)
            if ending.late:
                self._late(flight, ending)
            else:
                self.end(flight.goal, ending, flight.duration)
        self._harvest_progress()
        self._pick_grips()

    def _pick_grips(self):
        """The fingers measured while a running pick's plan carries its apple (from the grasp's end to the
        release): the newest opening noted, to tell at its end whether they held it (see ``carried``)."""
        measured = self.port.measured()
        if not self.grasp_check or measured is None or measured[1] is None:
            return
        now = self.schedule_now()
        for flight in self.lifecycle.flights.values():
            extra = flight.planned.plan.extra
            if flight.goal.kind != Kind.PICK or flight.start is None or 'release_start' not in extra:
                continue
            pick = self._picks.get(flight.goal.key)
            if pick is not None and carrying((extra['grasp_end'], extra['release_start']), now - flight.start):
                pick.grip = float(measured[1])

    def _serve_waiting(self):
        if self.waiting.goal is None:
            return
        why = self.blocked()
        if why is None:
            self._plan_and_send(self.waiting.take())
            return
        if 'not answered' in why:
            return
        expired = self.waiting.expired(self.port.wall(), ready=False)
        if expired is not None:
            self.refuse(expired, f'{why} (waited {WAIT_LIMIT:g} s)')

    def schedule_now(self):
        """The controller's schedule clock now, as its feedback says (s)."""
        return self.port.now() - self.timing.delay

    # -- planning and sending ---------------------------------------------------------------------
    def _plan_and_send(self, goal):
        t0 = self.port.wall()
        try:
            planner = self.port.goal_planner()
            start, planned, planned_at = self._plan(goal, planner)
            names = tuple(planned.plan.joint_names or planner.planner.arm.joint_names)
            points = self._points(planner, planned, start, names)
        except AimHolds:
            if goal.key in self.lifecycle.flights:
                self._moved(goal.key, 'held')         # a moving apple's pick keeps the plan it runs
            else:
                # No plan of its own runs to keep (its last came too late): aimed afresh, to close when it soonest can.
                self._picks[goal.key].closes = None
                self._handle(goal.again(target=replace(goal.target, follow=replace(goal.target.follow,
                                                                                   closes_at=None))))
            return
        except ValueError as exc:
            self.refuse(goal, str(exc))
            return
        except Exception as exc:  # noqa: BLE001 - a bug must still end the goal, with a reason
            self.port.log('ERROR', f'{goal.kind.value} goal {goal.key}: planning failed:\n{traceback.format_exc()}')
            self.refuse(goal, f'planning failed on an internal error ({type(exc).__name__}: {exc}; the '
                              'planner\'s log has the traceback)')
            return
        took = self.port.wall() - t0
        start = self._in_time(start, took)
        self.timing.planned(goal.kind.value, took)
        previous = self.lifecycle.flights.get(goal.key)
        # (The plan it takes over from runs on at the controller if this one never runs: the rest of a harvest,
        # and a re-target of a plan the controller took.)
        replaces = previous if goal.rest is not None or (
            goal.retargets and previous is not None and previous.handle is not None) else None
        flight = Flight(goal, planned, start.time or None, names, self.port.wall())
        flight.extra = self._figures(goal, planned, start, took, planner)
        flight.serial, flight.replaces = next(self._serial), replaces
        if replaces is not None:
            flight.displaced = (self.harvests.get(goal.key), self.running)
        self.lifecycle.sent(flight)
        if goal.kind == Kind.HARVEST:
            self._harvest_sent(goal, planned, flight)
        self.port.send(flight, points, start.time)
        if 'closes_in' in planned.plan.extra:
            self._picks[goal.key].closes = planned_at + planned.plan.extra['closes_in']
        if 'holds' in planned.plan.extra:
            self._hold(flight, planned.plan.extra['holds'], previous)
        # (A stream of re-targets is said on planner_status: the log says each goal's first plan.)
        self.port.log('DEBUG' if goal.retargets else 'INFO',
                      f'{goal.kind.value} goal: {planned.plan.method}, {planned.plan.duration:.3f} s from '
                      f'{start.words()}, planned in {took * 1e3:.1f} ms')

    def _hold(self, flight, margin, previous):
        """``flight`` takes its pick to the stand-off to wait for a closing it is sure of (``margin`` m, what the
        aim left inside the capture region): the closing instant is aimed afresh. The wait counts from the pick's
        first time there (a pick that went on and came back waits only what is left); said when it goes there
        (``previous``, the flight it replaces, did not hold)."""
        pick = self._picks[flight.goal.key]
        pick.closes = None
        if previous is not None and 'holds' in previous.planned.plan.extra:
            return
        if pick.holding_since is None:
            pick.holding_since = self.port.wall()
        left = max(0.0, self.port.goal_planner().pick.hold_time - (self.port.wall() - pick.holding_since))
        self._transition(flight, 'holding', f'the closing is not sure (the predicted centre {margin * 1e3:.1f} mm '
                                            f'inside the fingers\' reach, one deviation off): it waits at the '
                                            f'stand-off up to {left:.3g} s', margin=margin)

    def _holds_over(self):
        """Picks that have waited at the stand-off the pick cycle's ``hold_time`` since they first went there, and
        wait there still, without a sure closing, back off home; the goal ends aborted when they are there."""
        limit = self.port.goal_planner().pick.hold_time
        for key, pick in list(self._picks.items()):
            if pick.holding_since is None or self.port.wall() - pick.holding_since < limit:
                continue
            flight = self.lifecycle.flights.get(key)
            if key in self._paused:
                goal = self._paused.pop(key)[0]
            elif flight is not None and 'holds' in flight.planned.plan.extra:
                goal = flight.goal
            else:
                continue                      # on its way to a sure closing, or not running
            pick.holding_since = None
            why = f'no closing on the moving apple was sure in {limit:g} s at the stand-off'
            self._handle(goal.again(target=replace(goal.target, follow=None, back_off=why), attempt=0))

    def _plan(self, goal, planner):
        """``(start, planned, t0)``: where the plan starts, the plan, and the ROS time it is expected to start at."""
        if goal.rest is not None:
            at = goal.rest.at
            start = self._in_the_box(goal.key, goal.rest.at, goal.rest.plan_time)
            if start is None:
                raise ValueError('the harvest it runs is no longer the one the controller runs')
        else:
            at = self.timing.earliest(goal.kind.value, goal.attempt, self.port.now())
            start = self._after_apple_in_hand(at) if goal.kind == Kind.HARVEST else None
            if start is None:
                start = choose_start(self.running, at, self.port.reference(), self.port.measured())
        # (On the ROS clock a moving apple's places are stamped with: the schedule runs as late as the controller's
        # stalls have delayed it.)
        t0 = (start.time or at) + self.timing.delay
        return start, planner.plan(goal.target, start, t0), t0

    def _after_apple_in_hand(self, at):
        """A new harvest while one runs takes over at rest in the box after the apple in hand: its Start, or None when
        no harvest of ours runs."""
        for key, run in reversed(list(self.harvests.items())):
            if run.start is not None and key in self.lifecycle.flights:
                found = run.in_the_box_after(at)
                return None if found is None else self._in_the_box(key, *found)
        return None

    def _in_the_box(self, key, at, plan_time):
        """The Start at rest in the box ``plan_time`` s into goal ``key``'s running plan (schedule time ``at``), or
        None when that plan is not the one the controller runs."""
        running, current = self.running, self.lifecycle.flights.get(key)
        if running is None or not running.usable or current is None or running.key != current.serial:
            return None
        return Start(*running.at_plan_time(plan_time), at, 'plan')

    def _points(self, planner, planned, start, names):
        """The plan's points, checked as the controller will check them (a plan it would refuse is never sent)."""
        from ..kinematics import Unreachable
        arm, period = planner.planner.arm, planner.planner.settings.point_period
        before = np.concatenate([start.state[2], np.zeros(len(names) - arm.dof)])
        points = waypoints(planned.plan.trajectory, period, before=before)
        try:
            check_joint_limits(arm, *points, names=list(names))
        except Unreachable as exc:
            raise ValueError(f'the plan breaks a limit (from {start.words()}: the arm\'s motion cannot be carried on '
                             f'within it): {exc}') from None
        return points

    def _in_time(self, start, took):
        """A start that planning ran past, or that leaves less than the time planning took to send a plan of this size
        and have it checked, goes later as it is when the arm rests there (nothing moves until then: the end of our
        plan, or the controller's reference at rest). Any other start is sent as planned (the controller refuses it
        if its time has passed, and it is planned again)."""
        if not start.time or np.abs(start.state[1]).any() or np.abs(start.state[2]).any():
            return start
        if start.source == 'plan' and (self.running is None or start.time < self.running.end):
            return start
        soonest = self.schedule_now() + self.timing.lead + took
        return replace(start, time=soonest) if soonest > start.time else start

    @staticmethod
    def _figures(goal, planned, start, took, planner):
        plan = planned.plan
        summary = plan.summary(PEAK_SAMPLING)
        return dict(method=plan.method, duration=plan.duration, start=start.source,
                    peak_velocity=summary['peak_velocity'], peak_acceleration=summary['peak_acceleration'],
                    segments='; '.join(f'{s.label}: {s.method} {s.duration:.3f} s' for s in plan.segments),
                    planning_ms=took * 1e3, attempt=goal.attempt + 1, retargets=goal.retargets,
                    **({'retarget': goal.moved_by} if goal.moved_by else {}), **plan.extra)

    def _harvest_sent(self, goal, planned, flight):
        # Where each apple of the goal is (a re-plan of its rest keeps the indices of the first).
        self._places.setdefault(goal.key, {}).update(
            (i, tuple(float(v) for v in T[:3, 3])) for i, T in zip(goal.target.indices, goal.target.poses))
        for run in self.harvests.values():           # the one it replaces keeps the apples in the box by then
            if flight.start is not None:
                run.until = min(run.until, flight.start)
        before = self.harvests.pop(goal.key, None)
        self.harvests[goal.key] = HarvestRun(planned.harvest, flight.start,
                                             before=before if goal.rest is not None else None)
        for skip in planned.harvest.skipped:
            self._apple(goal, skip.index, 'skipped', skip.reason)

    # -- the controller's answers ------------------------------------------------------------------
    def on_response(self, flight, accepted, handle=None):
        """The controller's goal response to ``flight``'s plan."""
        ending = self.lifecycle.response(flight, accepted)
        self.timing.delivered(flight.goal.kind.value, self.port.wall() - flight.sent)
        if ending is not None:
            self._not_run(flight, ending.message)
        elif self.lifecycle.current(flight):
            flight.handle = handle
            self._transition(flight, 'accepted', f"{flight.extra['method']}, {flight.duration:.3f} s" + ''.join(
                f", {flight.extra[k]}" for k in ('approach', 'detours') if k in flight.extra),
                latency_ms=(self.port.wall() - flight.goal.came) * 1e3)
            if flight.cancel:
                self.port.cancel(flight)
        elif handle is not None:
            self.port.cancel(flight)                  # ended meanwhile (overdue), or planned again since
        self._serve_waiting()

    def on_feedback(self, flight, now, elapsed, tracking_error, desired=None):
        """The controller's feedback on ``flight``'s plan: at clock time ``now`` its reference is ``elapsed`` s into
        the plan's points (negative before them: the plan waits on the schedule, or its bridge runs), at
        ``desired`` (``{joint: position}``). Where the desired positions are not the plan's at ``elapsed`` (the
        controller brakes, or runs something else), where the plan is stays unknown. Its first feedback says the
        controller's schedule has the plan (:meth:`scheduled`)."""
        if not self.lifecycle.current(flight):
            return
        first_word = self._scheduled(flight)
        self._heard(flight, now, elapsed, tracking_error, desired)
        if first_word:
            self._serve_waiting()                     # a plan that waited for this one's word

    def _heard(self, flight, now, elapsed, tracking_error, desired):
        if elapsed is not None and elapsed < 0.0:
            # On the schedule before its points: waiting for its start, or the bridge to its first point runs.
            if flight.start is None:
                flight.start = now - self.timing.delay - elapsed
                self._learnt_start(flight)
            return
        if elapsed is not None and desired is not None and not _on_plan(flight, elapsed, desired):
            elapsed = None
        if elapsed is not None:
            if flight.start is None:                  # stamped 0: where the controller put it
                flight.start = now - self.timing.delay - elapsed
                self._learnt_start(flight)
            else:
                self.timing.heard(now, flight.start, elapsed)
        if self.lifecycle.feedback(flight, elapsed, tracking_error):
            self._transition(flight, 'executing', 'the controller runs its plan')
        if flight.goal.feedback is not None:
            phase, left = flight.phase()
            flight.goal.feedback(phase, left, tracking_error)

    def scheduled(self, flight):
        """The controller's schedule has ``flight``'s plan: it runs as sent, and the next plan may start from it
        (until then the next waits: an accepted goal may still be refused, as late)."""
        if self.lifecycle.current(flight) and self._scheduled(flight):
            self._serve_waiting()

    def _scheduled(self, flight):
        """As :meth:`scheduled`, without serving the goal that waits; True the first time."""
        if not self.lifecycle.scheduled(flight):
            return False
        self.running = Running(flight.planned.plan.trajectory, flight.names, flight.start, flight.serial,
                               self.port.goal_planner().planner.arm.dof)
        if flight.goal.retargets:
            self._moved(flight.goal.key, 'spliced')
        return True

    def _learnt_start(self, flight):
        if self.running is not None and self.running.key == flight.serial:
            self.running = replace(self.running, start=flight.start)
        # (A plan the controller bridged to runs later than planned: its fingers close later too.)
        self._closes_by(flight)
        run = self.harvests.get(flight.goal.key)
        if run is not None and run.start is None:
            run.start = run.first = flight.start

    def _closes_by(self, flight):
        """A moving pick's closing instant (schedule s) by ``flight``'s plan, once the plan's start is known."""
        pick = self._picks.get(flight.goal.key)
        if 'closes_in' in flight.planned.plan.extra and pick is not None and pick.closes is not None and \
                flight.start is not None:
            pick.closes = flight.start + self.timing.delay + flight.planned.plan.extra['closes_in']

    def on_result(self, flight, status, code, text):
        """The controller's result for ``flight``'s plan (``status``: 'succeeded', 'canceled' or 'aborted')."""
        if status == 'succeeded' and self.lifecycle.current(flight):
            self._scheduled(flight)                   # it ran, though no feedback said so
        ending = self.lifecycle.result(flight, status, code, text)
        if self.running is not None and self.running.key == flight.serial:
            self.running = replace(self.running, ended=status)
            if status == 'succeeded' and not self.lifecycle.flights:
                self.timing.delay = 0.0               # the arm holds with nothing scheduled: no delay left
        if ending is None:
            return
        goal = flight.goal
        if ending.outcome == Outcome.SUCCEEDED and goal.target.back_off:
            ending = Ending(Outcome.ABORTED, f'{goal.target.back_off}: it backed off home without closing')
        grip = self._picks[goal.key].grip if goal.key in self._picks else None
        if ending.outcome == Outcome.SUCCEEDED and \
                carried(grip, empty_below(self.port.goal_planner().pick.gripper_closed)) is False:
            ending = Ending(Outcome.ABORTED, f'the apple was not in the fingers: they closed to {grip * 100:.1f} cm '
                                             'while they should have carried it (the arm went on home)')
        if ending.late:
            self._late(flight, ending)
        elif ending.outcome == Outcome.SUCCEEDED and goal.kind == Kind.POSE and goal.retargets:
            self._paused[goal.key] = (goal, ending, flight.duration, self.port.wall() + STREAM_PAUSE)
        elif ending.outcome == Outcome.SUCCEEDED and 'holds' in flight.planned.plan.extra:
            # At rest at the stand-off: the pick waits there for a sure closing (or its hold ends).
            self._paused[goal.key] = (goal, Ending(Outcome.SUPERSEDED, 'a newer goal came while it waited at the '
                                                  'stand-off'), flight.duration, math.inf)
        else:
            self.end(flight.goal, ending, flight.duration)

    def _end_paused(self, now=math.inf):
        """End the re-targeted goals at rest whose stream has paused until ``now`` (all: a new goal came)."""
        for key, (goal, ending, duration, until) in list(self._paused.items()):
            if now >= until:
                del self._paused[key]
                self.end(goal, ending, duration)

    def _late(self, flight, ending):
        """``flight``'s plan reached the controller too late to run as planned, or was not answered by its start:
        its goal is planned again, further ahead, a bounded number of times."""
        self.timing.delivered(flight.goal.kind.value, self.port.wall() - flight.sent, late=True)
        if flight.replaces is not None and flight.goal.rest is not None:
            self._late_rest(flight, ending)
            return
        if flight.replaces is not None:
            # A re-target: the plan before it runs on and is the goal's again (a moving pick keeps its closing).
            self._displaced_runs_on(flight)
            if flight.goal.kind == Kind.PICK and self._approach_begun(flight.replaces):
                self._moved(flight.goal.key, 'held')  # its target no longer moves: a new plan would back out
                return
        if flight.goal.attempt >= LATE_REPLANS:
            self.refuse(flight.goal, f'its plan reached the controller too late {flight.goal.attempt + 1} times '
                                     f'(a stalled or overloaded machine?): {ending.message}', ending.code)
            return
        self.port.log('WARN', f'{flight.goal.kind.value} goal {flight.goal.key}: its plan came too late to run as '
                              f'planned ({ending.message}); planning it again, further ahead')
        self.timing.delay = 0.0
        self._handle(flight.goal.again(attempt=flight.goal.attempt + 1))

    def _late_rest(self, flight, ending):
        """The rest of a harvest came too late to take over after the apple in hand: the plan it was to take over
        from runs on, and the rest (with the apples it took in) is planned again to take over after the next apple
        in hand. A rest that only aimed the next apple at its sway is not: that apple runs as planned, and the one
        after it is aimed before its turn (:meth:`reaim`)."""
        self._displaced_runs_on(flight)
        goal, old = flight.goal, flight.replaces
        self.timing.delay = 0.0
        known = set(old.goal.target.indices)
        more = [(i, T) for i, T in zip(goal.target.indices, goal.target.poses) if i not in known]
        if goal.target.follows and not more:
            self._rest_failed(goal, old, f'its plan came too late ({ending.message})')
            return
        again = None if goal.attempt >= LATE_REPLANS else \
            self._harvest_rest(old, self.schedule_now(), goal.rest.why, more=more, keep=goal.rest.keep)
        if again is None:
            for i, _ in more:
                self._apple(goal, i, 'skipped', 'seen, but the plan that took it in came too late, and no apple in '
                                                'hand was left to take it in after')
            self._rest_failed(goal, old, f'its plan came too late ({ending.message}), and no later apple in hand '
                                         'was left to take over after' if goal.attempt < LATE_REPLANS else
                              f'its plan reached the controller too late {goal.attempt + 1} times')
            return
        self.port.log('WARN', f'harvest goal {goal.key}: the rest\'s plan came too late to run as planned '
                              f'({ending.message}); planning it again after the next apple in hand')
        self._handle(again.again(attempt=goal.attempt + 1))

    def _displaced_runs_on(self, flight):
        """``flight`` (the rest of a harvest, a re-target) will not run: the plan it was to take over from runs on,
        and is again what the planner knows runs (the goal's flight, its HarvestRun, the controller's plan, a
        pick's closing instant)."""
        run, running = flight.displaced
        old = self.lifecycle.flights[flight.goal.key] = flight.replaces
        old.superseded = old.overtaken = False
        self._closes_by(old)
        if run is not None:
            # (The apples the rest's run reported in the box meanwhile are the running plan's: said once.)
            gone = self.harvests.get(flight.goal.key)
            run.until, run.reported = np.inf, max(run.reported, gone.reported if gone is not None else 0)
            self.harvests[flight.goal.key] = run
        if self.running is not None and self.running.key == flight.serial:
            self.running = running

    def _not_run(self, flight, why):
        """``flight``'s plan will not run: its goal is refused; the rest of a harvest planned again stops the plan it
        was to take over from (that one would hit what changed)."""
        old = flight.replaces
        if old is not None and old.handle is not None:
            self._displaced_runs_on(flight)
            if flight.goal.rest is not None:
                self._rest_failed(flight.goal, old, why)
            else:
                self.refuse(flight.goal, why)         # a re-target: the plan before it runs on
            return
        self.end(flight.goal, Ending(Outcome.REFUSED, why))

    def _rest_failed(self, goal, running, why):
        """The rest of harvest ``goal`` could not be planned or run (``why``): the ``running`` plan is stopped, unless
        the rest only took in apples seen since (:class:`Rest` ``keep``): then it runs on as planned."""
        if not goal.rest.keep:
            self._stop(running, f'{goal.rest.why}, and the rest could not be planned again around it ({why})')
            return
        words = f'{goal.rest.why}, but they could not be planned in ({why}): the harvest runs on as planned'
        self.port.log('WARN', f'harvest goal {goal.key}: {words}')
        self._answer(goal, 'WARN', f'harvest goal not replanned: {words}', state='executing')

    def refuse(self, goal, why, code=0):
        """``goal`` cannot be planned or sent: refused with ``why`` (the rest of a harvest: see :meth:`_not_run`)."""
        running = self.lifecycle.flights.get(goal.key)
        if goal.rest is not None and running is not None and running.handle is not None:
            self._rest_failed(goal, running, why)
            return
        if goal.target is not None and goal.target.back_off:
            self.end(goal, Ending(Outcome.ABORTED, f'{goal.target.back_off}, and it could not back off home: {why}'))
            return
        if goal.retargets and running is not None:
            self._moved(goal.key, 'refused')
            self.port.log('WARN', f'{goal.kind.value} goal {goal.key}: its new target was refused ({why}); the plan '
                                  'before it runs on')
            self._transition(running, 'retarget refused', why)
            return
        self.end(goal, Ending(Outcome.REFUSED, why, code))

    # -- ends and statuses ------------------------------------------------------------------------
    def end(self, goal, ending, duration=0.0):
        """A goal's final answer: on planner_status, in the log, and to its action client."""
        outcome = ending.outcome
        level = LEVELS.get(outcome, 'ERROR')
        text = f'{goal.kind.value} goal {outcome.word}: {ending.message}'
        values = self._harvest_ended(goal, outcome, ending) if goal.kind == Kind.HARVEST else {}
        if 'summary' in values:
            text += f" ({values.pop('summary')})"
        values.update({f'retargets_{k}': n for k, n in self._moves.pop(goal.key, {}).items()})
        self._picks.pop(goal.key, None)
        self._answer(goal, level, text, state=outcome.word, controller_error_code=ending.code, **values)
        if outcome == Outcome.SUPERSEDED:
            self._superseded += 1
            if self.port.wall() - self._superseded_said > 1.0:
                self.port.log('WARN', f'{self._superseded} goals superseded by newer ones')
                self._superseded, self._superseded_said = 0, self.port.wall()
        else:
            self.port.log('ERROR' if level == 'ERROR' else 'INFO', text)
        if goal.finish is not None:
            goal.finish(outcome, ending.message, ending.code, duration)

    def _answer(self, goal, level, text, **values):
        stamp = {'stamp': goal.stamp} if goal.stamp else {}
        message = self.port.status(level, text, goal=goal.key, kind=goal.kind.value, **stamp, **values)
        self.book.answered(goal.key, message)

    def _transition(self, flight, state, words, **values):
        goal = flight.goal
        again = ' again (the last plan reached the controller too late)' if goal.attempt else ''
        moved = f' (target moved {goal.retargets} times)' if goal.retargets else ''
        self._answer(goal, 'OK', f'{goal.kind.value} goal {state}{again}{moved}: {words}', state=state,
                     **flight.extra, **values)

    # -- a changed world ---------------------------------------------------------------------------
    def world_changed(self):
        """The world changed (a new scene or canopy): the rest of every plan the controller runs is checked
        against it. A harvest that would touch something only after the apple in hand is planned again from the
        box after it, its apples not started around the new world (the same goal goes on); any other plan that
        would now touch something is stopped (the controller brakes to rest; the goal ends aborted with why)."""
        now, world = self.schedule_now(), self.port.goal_planner().world
        for flight in list(self.lifecycle.flights.values()):
            if flight.handle is None or flight.cancel or flight.stopped or flight.start is None:
                continue
            rest = _Rest(flight.planned.plan.trajectory, max(0.0, now - flight.start))
            if rest.duration <= 0.0:
                continue
            contact = world.check(rest, list(flight.planned.regions), slack=COLLISION_STEP / 2)
            if contact is None:
                continue
            changed = f'the world changed while it ran: {contact} (t from the change)'
            again = self._harvest_rest(flight, now, changed, before=now + contact.time)
            if again is None:
                self._stop(flight, changed)
                continue
            words = (f'{changed}; the apples not started ({" ".join(str(i) for i in again.target.indices)}) are '
                     'planned again around it, from the box after the apple in hand')
            self.port.log('WARN', f'harvest goal {flight.goal.key}: {words}')
            self._answer(flight.goal, 'WARN', f'harvest goal replanned: {words}', state='replanned')
            self._handle(again)

    def _harvest_rest(self, flight, now, why, before=math.inf, more=(), keep=False):
        """The goal of a running harvest, its apples not started by the end of the apple in hand (or by the start of
        a rest that has not begun) and the apples
        ``more`` (``(index, pose)`` pairs), to be planned again (``why``, in words; ``keep`` as :class:`Rest` takes
        it). None: not a harvest, the rest would take over at or after ``before`` (a schedule time: what it is
        planned around comes sooner), no apple is left, or the last apple is in hand already."""
        run = self.harvests.get(flight.goal.key)
        if flight.goal.kind != Kind.HARVEST or run is None or run.start is None:
            return None
        found = run.in_the_box_after(now + self.timing.lead + 1.5 * self.timing.expected('harvest'))
        if found is None:
            return None
        at, in_hand = found
        left = [a.index for a in run.plan.apples if run.start + a.start >= at - 1e-9] + [i for i, _ in more]
        if before <= at or not left:
            return None
        poses = dict(zip(flight.goal.target.indices, flight.goal.target.poses)) | dict(more)
        # (Aimed at no sway: fits frozen when the goal came, or its last aim, look too far ahead now; reaim aims.)
        target = replace(flight.goal.target, poses=tuple(poses[i] for i in left), indices=tuple(left), follows=None)
        return flight.goal.again(target=target, rest=Rest(why, at, in_hand, keep), came=self.port.wall())

    # -- apples seen as a harvest runs -------------------------------------------------------------
    def seen_more(self, poses):
        """``poses`` (4x4 each, the arm's base): the apples the camera sees now, settled where they hang. Those a
        running harvest of the apples seen does not know (:func:`~picking_core.harvest.new_apples`: an apple the
        arm hid at home, one behind an apple just picked) join the apples it has not started, planned again with
        them from the box after the apple in hand, as the same goal (the new apples numbered on from its own). An
        apple seen too late for that (the last one is in hand) is said, not taken. Returns how many were taken."""
        taken, now = 0, self.schedule_now()
        box = self.port.goal_planner().pick.box_position
        for flight in list(self.lifecycle.flights.values()):
            goal = flight.goal
            if goal.kind != Kind.HARVEST or not goal.target.seen or flight.handle is None or flight.cancel or \
                    flight.stopped or (self.waiting.goal is not None and self.waiting.goal.key == goal.key):
                continue
            places = self._places.setdefault(goal.key, {})
            new = new_apples(poses, list(places.values()), box)
            if not new:
                continue
            first = max(places, default=-1) + 1
            more = list(enumerate(new, start=first))
            # Known from now on, planned in or not: an apple is taken in once.
            places.update((i, tuple(float(v) for v in T[:3, 3])) for i, T in more)
            names = ' '.join(str(i) for i, _ in more)
            why = f'{len(more)} more apple{"s" if len(more) > 1 else ""} seen ({names})'
            again = self._harvest_rest(flight, now, why, more=more, keep=True)
            if again is None:
                for i, _ in more:
                    self._apple(goal, i, 'skipped', 'seen after the harvest\'s last apple was in hand: not taken in '
                                                    '(harvest the apples seen again for it)')
                continue
            self.port.log('INFO', f'harvest goal {goal.key}: {why}: the apples not started are planned again with '
                                  'them, from the box after the apple in hand')
            self._answer(goal, 'OK', f'harvest goal replanned: {why}, taken in', state='replanned')
            self._handle(again)
            taken += len(more)
        return taken

    def reaim(self, follow_of):
        """Aim a running harvest of the apples seen at its next apple's sway: ``follow_of(p)`` is the
        :class:`~picking_core.moving_pick.Follow` of the apple hanging at ``p`` (3,), m, if it sways (else None). Once
        the apple in hand is dropped within :data:`REAIM` s of the soonest a rest could take over, and the apple after
        it sways, the apples not started are planned again from the box, the first aimed where it will be when the
        fingers close (its prediction then looks one approach ahead, not a cycle or more); once for each apple in
        hand. Returns how many harvests were aimed again."""
        aimed, now = 0, self.schedule_now()
        for flight in list(self.lifecycle.flights.values()):
            goal, run = flight.goal, self.harvests.get(flight.goal.key)
            if goal.kind != Kind.HARVEST or not goal.target.seen or run is None or run.start is None or \
                    flight.handle is None or flight.cancel or flight.stopped or \
                    (self.waiting.goal is not None and self.waiting.goal.key == goal.key):
                continue
            soonest = now + self.timing.lead + 1.5 * self.timing.expected('harvest')
            at = run.after_apple_in_hand(soonest)
            after = [a for a in run.plan.apples if run.start + a.start >= at - 1e-9]
            done = self._reaimed.setdefault(goal.key, set())
            if not after or at - soonest > REAIM or round(at, 6) in done:
                continue
            poses = dict(zip(goal.target.indices, goal.target.poses))
            follows = {i: follow_of(np.asarray(poses[a.index])[:3, 3]) for a in after for i in (a.index,)}
            follows = {i: f for i, f in follows.items() if f is not None}
            if after[0].index not in follows:
                continue
            done.add(round(at, 6))
            again = self._harvest_rest(flight, now, f'apple {after[0].index} sways: aimed where it will be',
                                       keep=True)
            if again is None:
                continue
            self._answer(goal, 'OK', f'harvest goal replanned: {again.rest.why}, the apples not started planned '
                                     'again from the box after the apple in hand', state='replanned')
            self._handle(again.again(target=replace(again.target, follows=follows)))
            aimed += 1
        return aimed

    def _stop(self, flight, why):
        """Stop a running plan at the controller (it brakes to rest): its goal ends aborted, ``why``."""
        flight.stopped = f'{why}; the arm braked to rest'
        self.port.log('WARN', f'{flight.goal.kind.value} goal {flight.goal.key}: {flight.stopped}')
        self.port.cancel(flight)

    # -- harvests ---------------------------------------------------------------------------------
    def _harvest_progress(self):
        """Each apple of a running harvest reported once it is in the box (by the controller's schedule), if the
        fingers measured while they carried it held something."""
        now = self.schedule_now()
        measured = self.port.measured()
        for key, run in self.harvests.items():
            if run.start is None:
                continue
            if self.grasp_check and measured is not None and measured[1] is not None:
                run.watch(now, measured[1])
            flight = self.lifecycle.flights.get(key)
            for k, apple in run.newly_picked(now):
                if flight is not None:
                    self._apple_done(flight.goal, run, k, apple)

    def _apple_done(self, goal, run, k, apple):
        """Apple ``apple`` of ``run`` (the ``k``-th of its plan) through its release: picked, or missed when the
        fingers were measured holding nothing while they should have carried it."""
        held = run.holding(apple)
        if held is False:
            why = (f'the gripper held nothing while it should have carried it (its fingers closed to '
                   f'{run.grip[apple.index] * 100:.1f} cm, the apple was not between them)')
            run.miss(apple, why)
            self._apple(goal, apple.index, 'missed', why, started=apple.start, at=apple.end)
            return
        unmeasured = '' if held else ' by the plan (the gripper\'s opening was not measured)'
        self._apple(goal, apple.index, 'picked', f'in the box{unmeasured} ({k} of {len(run.picked_by(math.inf))})', picked=k,
                    started=apple.start, at=apple.end, verified=held is True)

    def _apple(self, goal, index, word, words, **values):
        """A harvest's apple ``index`` picked, skipped or failed, with where the goal put it (``x``, ``y``, ``z``, m
        in the arm's base: a client that did not send the poses, as for the apples seen, matches them by place)."""
        state = {'picked': 'executing', 'missed': 'executing', 'skipped': 'planned'}.get(word, 'ended')
        stamp = {'stamp': goal.stamp} if goal.stamp else {}
        place = self._places.get(goal.key, {}).get(index)
        where = {} if place is None else dict(zip('xyz', place))
        self.port.status('OK' if word == 'picked' else 'WARN', f'harvest goal {goal.key}: apple {index} {word}: {words}',
                         goal=goal.key, kind='harvest', state=state, apple=index, apple_state=word, **stamp,
                         **where, **values)

    def _harvest_ended(self, goal, outcome, ending):
        run = self.harvests.pop(goal.key, None)
        if run is None or run.start is None:
            self._places.pop(goal.key, None)
            self._reaimed.pop(goal.key, None)
            return {}
        now = self.schedule_now()
        finished = outcome == Outcome.SUCCEEDED
        if finished:
            for k, apple in run.newly_picked(math.inf):
                self._apple_done(goal, run, k, apple)
        else:
            apple = run.in_hand(now)
            if apple is not None:
                self._apple(goal, apple.index, 'failed', f'the harvest {outcome.word} during its cycle: '
                                                         f'{ending.message}', started=apple.start)
        self._places.pop(goal.key, None)
        self._reaimed.pop(goal.key, None)
        values = run.summary(now, finished)
        return dict(values, summary=run.words(now, finished))


#: rad: a controller's desired position this close to the plan's is on the plan.
ON_PLAN = 1e-4


def _on_plan(flight, elapsed, desired):
    """True when the controller's desired positions (``{joint: rad}``) are the plan's at ``elapsed`` s."""
    q = flight.planned.plan.trajectory.state_at(elapsed)[0]
    cols = [(k, desired[name]) for k, name in enumerate(flight.names) if name in desired]
    return bool(cols) and all(abs(q[k] - value) <= ON_PLAN for k, value in cols)


class _Rest:
    """The part of a trajectory from ``t0`` (s) on, as its own trajectory (time 0 at ``t0``)."""

    def __init__(self, trajectory, t0):
        self.trajectory, self.t0 = trajectory, t0
        self.duration = max(0.0, trajectory.duration - t0)

    def sample(self, t):
        return self.trajectory.sample(np.asarray(t, float) + self.t0)


__all__ = ['GoalRunner', 'Port', 'State']

