"""The planner's goal policy, with no ROS in it: where a plan starts, what it carries on from,
when a goal waits or is planned again, and which goals are resends of one already taken.

The planner node feeds it the clock, the controller's reference, the measured state and the
controller's verdicts, and does what it answers. Times are seconds on the controller's clock
(the ROS clock) unless named ``wall`` (``time.monotonic()``).
"""

from __future__ import annotations

from collections import OrderedDict, deque
from dataclasses import dataclass
from typing import Callable, NamedTuple

import numpy as np

from .approaches import BrakeBlocked
from .planning import feasible_start
from .sent_plans import SentPlan, carried_points, carry_start, forget_before, plan_active, predict_reference

#: s a plan must leave between the end of planning and its start: sending it, and the
#: controller's checks.
DELIVERY = 0.08
#: s a first goal of a kind is expected to take to plan (later ones: what the last took). A plan
#: that ends too late to start on time is planned again further ahead, so a guess too short
#: costs a second planning.
FIRST_PLANNING = {'pose': 0.05, 'path': 0.1, 'pick': 0.4, 'harvest': 2.0}
#: rad: the controller's reference is following our last plan when within this of it.
FOLLOWING = 1e-3
#: s: a plan found to run later than known by less than this is not moved (stamps' rounding).
DELAY_RESOLUTION = 1e-5
#: s: a moving reference off a running plan is extrapolated at most this far ahead (its acceleration
#: brought to zero over it); a start further ahead waits for the controller to say where its plan runs.
EXTRAPOLATION_LIMIT = 0.5
#: Plans remembered to tell whether the controller's reference follows them: those that may still
#: run (a goal flood sends one every few ms, each to start start_delay or more ahead), at most this many.
SENT_KEPT = 2000
GOALS_KEPT = 1000     # goals remembered (with their answers) to know one sent again
REPEAT_WINDOW = 30.0  # s after a goal in which the same goal again is a resend, not a new goal
#: Times a goal is planned again when the controller refused its plan as late (it reached the
#: controller too late to run, after a stall in transport or in a process on a loaded machine; or
#: it was planned from a reference the controller no longer follows), each time further ahead.
LATE_REPLANS = 2
#: s a goal waits for the first joint_states, or for a controller to subscribe, before it is refused.
WAIT_LIMIT = 5.0
ZERO_KEY = '0.000000000'


class Unsettled(ValueError):
    """Where a plan would start cannot be told yet (see :meth:`GoalPolicy.start_state`): the goal waits."""


class Start(NamedTuple):
    """Where a plan starts (see :meth:`GoalPolicy.start_state`)."""

    state: tuple                  # (q, qd, qdd)
    source: str                   # 'reference' (the controller's) or 'measured'
    time: float                   # on the controller's clock, s
    carry_from: float | None = None   # where the points carry the sent plans from (None: nothing to carry)
    carries_on: bool = False      # from a sent plan the reference follows, at ``time``

    @property
    def guessed(self):
        """True for the controller's reference extrapolated: neither a plan of ours it follows nor the arm measured."""
        return self.source == 'reference' and not self.carries_on

    def words(self):
        """What the plan started from, in words (for a refusal)."""
        if self.carries_on:
            return 'the plan running then'
        return "the controller's reference, extrapolated" if self.guessed else 'the measured state'


@dataclass
class Goal:
    """A goal as the node took it: its kind (``'pose'``, ``'path'``, ``'pick'``), its key (the
    header stamp as text, or the action goal's id), ``plan(start_state, gripper)`` that plans it,
    and when it came (wall s). An action goal also has ``finish(outcome, message, code, duration)``,
    called once when it ends, and ``feedback(phase, time_left, tracking_error)``."""

    kind: str
    key: str
    plan: Callable
    came: float = 0.0
    attempt: int = 0              # how many times it was planned again after a late verdict
    finish: Callable | None = None
    feedback: Callable | None = None
    stamp: str = ''               # a topic goal's header stamp as text (its statuses carry it: its sender's name for it)


@dataclass
class Late:
    """What to do about a goal whose plan the controller refused as late: plan ``goal`` again
    (``again`` True, its ``attempt`` counted up), or answer it as not run."""

    goal: Goal
    again: bool


class GoalPolicy:
    """The bookkeeping of one planner's goals and the plans it sent.

    ``arm`` gives the limits a predicted start is held within; ``start_delay`` (s) is how far
    ahead of the end of planning a plan starts, doubled at each late replan.
    """

    def __init__(self, arm, start_delay=0.1):
        self.arm = arm
        self.start_delay = float(start_delay)
        self.sent = deque(maxlen=SENT_KEPT)      # SentPlan: the plans sent that may still run
        self.planning_time = {}                  # kind of goal -> s its last planning took
        self.newest = None                       # (trajectory key, Goal, SentPlan) of the newest plan sent
        self.goals = OrderedDict()               # goal key -> [its bytes, its answer, when it came (wall)]
        self.waiting = None                      # the newest Goal that waits for joint_states or a controller

    # -- when a goal comes ------------------------------------------------------------------
    def repeat(self, key, data, wall):
        """``(True, answer)`` when the goal ``key`` with content ``data`` (equal to it) was taken
        already: the answer (None while it is still planned or waits) is to be sent again and the
        goal not planned twice. ``(False, None)`` for a new goal, which is remembered.

        A sender that hears no answer sends its goal again: a message published just as
        discovery completes can be lost. A zero stamp gives a goal no identity, and the same
        goal more than REPEAT_WINDOW s after the first is a new one.
        """
        if key == ZERO_KEY:
            return False, None
        seen = self.goals.get(key)
        if seen is not None and seen[0] == data and wall - seen[2] < REPEAT_WINDOW:
            return True, seen[1]
        self.goals[key] = [data, None, wall]
        self.goals.move_to_end(key)
        while len(self.goals) > GOALS_KEPT:
            self.goals.popitem(last=False)
        return False, None

    def answered(self, key, answer):
        """Keep the answer to goal ``key``, should the goal come again."""
        seen = self.goals.get(key)
        if seen is not None:
            seen[1] = answer

    def wait(self, goal):
        """Let ``goal`` wait (the arm's state or a controller is not known yet); returns the goal
        that waited before, now superseded, or None. Only the newest goal waits."""
        old, self.waiting = self.waiting, goal
        return old

    def waited(self, ready, wall):
        """``(goal to plan now, goal to refuse)``, either None: the waiting goal once ``ready``,
        or, after WAIT_LIMIT s not ready, refused."""
        goal = self.waiting
        if goal is None:
            return None, None
        if ready:
            self.waiting = None
            return goal, None
        if wall - goal.came > WAIT_LIMIT:
            self.waiting = None
            return None, goal
        return None, None

    # -- planning -----------------------------------------------------------------------------
    def delay(self, goal):
        """s from now to the plan's start: start_delay (doubled at each replan) after planning is
        expected to end (this kind of goal took that long last time)."""
        return (self.start_delay * 2 ** goal.attempt
                + 1.5 * self.planning_time.get(goal.kind, FIRST_PLANNING[goal.kind]))

    def start_state(self, t_start, reference, measured_q, exact=False):
        """Where a plan starting at ``t_start`` starts: a :class:`Start`.

        The plan is stamped to start at ``t_start``, so planning and delivery time never make
        the arm jump and the plan's clock is the controller's. While the controller publishes a
        fresh ``reference`` ``(q, qd, qdd, stamp)``, the start state is where that reference will
        be then. When the reference follows the plans sent (each spliced onto the one before at
        its start time, so the reference at its stamp lies on the plan active then, perhaps one
        that a newer plan, not started yet, will take over from), the exact state of the plan
        active at the start time, even across its end. Else the reference extrapolated from its
        stamp (:func:`predict_reference`: another client's trajectory, a catch-up lead-in, a
        stalled controller), held within the limits; :class:`Unsettled` when that reference moves
        while one of our plans runs and ``t_start`` lies more than EXTRAPOLATION_LIMIT ahead, or
        at all when the start must be ``exact`` (a replacing harvest's, in the box after the apple
        in hand): a controller that stalled runs the plan late, and says by how much in its
        feedback (see :meth:`runs_late`). Without a reference, ``measured_q`` at rest.
        ``carry_from``: when the plan carries on from plans that start after the reference's
        stamp (the controller may not run them: see :func:`carried_points`), where to carry them
        from (:func:`carry_start`); else None.
        """
        if reference is not None:
            q, qd, qdd, stamp = reference
            then = forget_before(self.sent, stamp) if stamp > 0 else None
            n = q.size
            if then is not None and np.abs(then.trajectory.state_at(stamp - then.start)[0][:n] - q).max() < FOLLOWING:
                plan = plan_active(self.sent, t_start) or then
                return Start(tuple(x[:n].copy() for x in plan.trajectory.state_at(t_start - plan.start)),
                             'reference', t_start, carry_start(self.sent, stamp, t_start), carries_on=True)
            dt = max(0.0, t_start - stamp) if stamp > 0 else 0.0
            if ((exact or dt > EXTRAPOLATION_LIMIT) and then is not None
                    and stamp - then.start < then.trajectory.duration
                    and (np.abs(qd).max() > 1e-6 or np.abs(qdd).max() > 1e-6)):
                raise Unsettled(f"the controller's reference is off the plan it runs (delayed by a stall it has not "
                                f"reported yet?): where the arm is {dt:.2f} s ahead is unknown")
            return Start(feasible_start(self.arm, *predict_reference(q, qd, qdd, dt)), 'reference', t_start)
        if measured_q is None:
            raise ValueError('no joint_states received yet: the planner does not know where the arm is')
        q = np.asarray(measured_q, float)
        return Start((q, np.zeros_like(q), np.zeros_like(q)), 'measured', t_start)

    @staticmethod
    def plan(goal, start, gripper):
        """``goal``'s plan from ``start`` with the gripper at ``gripper``. A plan whose arm would hit
        something while it brakes from ``start`` waits (:class:`Unsettled`) when ``start`` is only the
        controller's reference extrapolated: that guess is no ground to refuse the goal (the
        controller of a loaded machine leads into late plans its own way, and its reference can be
        extrapolated far from where the arm goes); from a start known, the goal is refused."""
        try:
            return goal.plan(start.state, gripper)
        except BrakeBlocked as exc:
            if start.guessed:
                raise Unsettled(f"{exc}, from the controller's reference extrapolated: waiting for it to "
                                'settle') from exc
            raise

    def planned_joint(self, t, name):
        """The position of joint ``name`` in the sent plan that runs at ``t`` (the gripper, which the
        controller's reference of the arm does not carry), or None."""
        plan = plan_active(self.sent, t)
        if plan is None or name not in plan.names:
            return None
        return float(plan.trajectory.state_at(t - plan.start)[0][plan.names.index(name)])

    def postponed(self, start, t):
        """``start`` moved to the later time ``t`` when the arm rests there from ``start.time`` on (at rest,
        no sent plan running after it, nothing to carry): a plan that took too long to make can then start
        later as it is, instead of being planned again. None otherwise."""
        if start.carry_from is not None or np.abs(start.state[1]).max() > 1e-9 or np.abs(start.state[2]).max() > 1e-9:
            return None
        if any(plan.start + plan.trajectory.duration > start.time for plan in self.sent):
            return None
        return start._replace(time=t)

    @staticmethod
    def on_time(now, start):
        """True when a plan finished planning at ``now`` still reaches the controller before ``start``."""
        return now < start.time - DELIVERY

    def planned(self, goal, seconds):
        """Planning ``goal`` took ``seconds``: the next goal of its kind expects as much."""
        self.planning_time[goal.kind] = seconds

    def points(self, own, start, period, names):
        """``(points, stamp)`` to send for a plan whose samples ``own`` = ``(t, q, qd, qdd)`` start at
        ``start``: the plan's own points stamped at its start, or, when it carries on from sent
        plans the controller may not have, those plans' points first, stamped where they begin."""
        carried = (None if start.carry_from is None
                   else carried_points(self.sent, start.carry_from, start.time, period, names))
        if carried is None:
            return own, start.time
        points = (np.concatenate([carried[0], own[0] + (start.time - start.carry_from)]),
                  *(np.concatenate([c, o]) for c, o in zip(carried[1:], own[1:])))
        return points, start.carry_from

    def sent_plan(self, goal, trajectory, start, names, trajectory_key, now, reference_timeout, stamp=None):
        """A plan for ``goal`` was sent as the trajectory named ``trajectory_key``, stamped ``stamp``
        (default: its start). The plans no fresh reference can be on any more are forgotten
        (memory stays small)."""
        forget_before(self.sent, now - reference_timeout)
        self.sent.append(SentPlan(trajectory, start.time, names, start.carries_on, trajectory_key,
                                  start.time if stamp is None else stamp))
        self.newest = (trajectory_key, goal, self.sent[-1])

    def runs_late(self, trajectory_key, now, elapsed, names, desired):
        """The controller's feedback on the trajectory ``trajectory_key``: at ``now`` its reference is
        ``elapsed`` s into the trajectory's points, at positions ``desired`` of the joints ``names``.

        A controller whose loop stalled runs its trajectories later than their stamps say (it delays
        them instead of jumping ahead). The plan is then moved to where it really runs, so that
        the starts predicted from it (a replacing harvest's, seconds ahead) stay on it. Checked
        first: the plan, so moved, must be at ``desired`` then. Returns how much later than
        known before it runs (s), 0.0 when no later."""
        i = next((i for i, p in enumerate(self.sent) if p.key == trajectory_key), None)
        if i is None or not elapsed > 0:
            return 0.0
        plan = self.sent[i]
        delay = now - plan.stamp - elapsed
        later = delay - plan.delay
        if not later > DELAY_RESOLUTION:
            return 0.0
        t = now - (plan.start + later)
        if t < 0.0:                      # still in what it carries of older plans, or its lead-in
            return 0.0
        given = [k for k, n in enumerate(names) if n in plan.names]
        cols = [plan.names.index(names[k]) for k in given]
        q = plan.trajectory.state_at(t)[0]
        if not given or np.abs(q[cols] - np.asarray(desired, float)[given]).max() > FOLLOWING:
            return 0.0
        self.sent[i] = plan._replace(start=plan.start + later, delay=delay)
        if self.newest is not None and self.newest[2] is plan:
            self.newest = (*self.newest[:2], self.sent[i])
        return later

    # -- the controller's verdict ------------------------------------------------------------
    def late(self, trajectory_key):
        """The controller refused the trajectory ``trajectory_key`` as late. A :class:`Late` for the
        newest plan's goal (plan it again, from where the arm is then, further ahead, up to
        LATE_REPLANS times; then answer it as not run), or None for any other trajectory."""
        if self.newest is None or self.newest[0] != trajectory_key:
            return None
        _, goal, sent = self.newest
        self.newest = None
        if sent in self.sent:                    # the controller never ran it: no later plan carries on from it
            self.sent.remove(sent)
        if goal.attempt >= LATE_REPLANS:
            return Late(goal, again=False)
        goal.attempt += 1
        return Late(goal, again=True)
