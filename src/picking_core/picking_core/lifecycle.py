"""The life of a planner goal once its plan is sent, with no ROS in it.

Every plan goes to the controller as a ``follow_joint_trajectory`` goal. The controller's goal
response says whether it took the plan (**accepted**), its first feedback that the plan runs
(**executing**), and its result how it ended: **succeeded**, **aborted** (a tolerance, lost
feedback), **superseded** (our newer plan took over), **canceled**, or **refused** (it never ran:
the controller refused the plan). A result that says the plan came too late is planned again
(see :meth:`GoalPolicy.late`). A controller that does not answer in time ends the goal as aborted
with the reason: no goal stays accepted forever.

Times: ``wall`` is ``time.monotonic()``; plan times are on the controller's clock (ROS time).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

#: s the controller has to answer a plan (accept it or not) before the goal is aborted; a plan that
#: starts later than that (a long harvest, planned well ahead) may be answered until its start: a
#: long goal takes long to deliver on a busy machine, and answered later it is refused as late.
#: Generous: a controller sharing two saturated cores with another arm's stack and perception has
#: answered after more than 3 s, and a late answer costs a re-plan where an abort costs the goal.
RESPONSE_LIMIT = 10.0
#: s after a plan's end that its result may take (the controller's goal time tolerance and
#: settling included) before the goal is aborted.
RESULT_MARGIN = 5.0

#: FollowJointTrajectory result codes this module reads.
INVALID_GOAL = -1
INVALID_JOINTS = -2
OLD_HEADER_TIMESTAMP = -3


class Outcome(enum.IntEnum):
    """How a goal ended (the ``outcome`` of the MoveToPose, FollowPath and Pick results)."""

    SUCCEEDED = 0
    REFUSED = 1
    ABORTED = 2
    SUPERSEDED = 3
    CANCELED = 4

    @property
    def word(self):
        return self.name.lower()


@dataclass
class Flight:
    """A goal whose plan was sent to the controller, until its result."""

    goal: object                  # goal_policy.Goal
    start: float                  # the plan's start, controller clock, s
    duration: float               # s
    segments: list                # [(label, start, end)] in s from the plan's start
    sent: float                   # wall s
    trajectory: str = ''          # the plan's stamp, as the controller names it
    state: str = 'sent'           # sent -> accepted -> executing
    superseded: bool = False      # a newer plan of ours was sent after it
    overtaken: bool = False       # ... and the controller accepted that one (it takes over from this)
    tracking_error: float = 0.0   # rad, the controller's newest feedback
    handle: object = None         # the controller's goal handle, once accepted
    cancel: bool = False          # its client asked to cancel it
    extra: dict = field(default_factory=dict)
    plan: object = None           # the plan's trajectory (time 0 at ``start``), to check its rest again
    regions: tuple = ()           # where touching is allowed along it (its apples)
    stopped: str = ''             # why the planner stopped it at the controller (the world changed)
    replaces: object = None       # the same goal's plan still running that this one takes over from (a
                                  # harvest planned again around a changed world): stopped if this one fails

    def phase(self, now):
        """``(phase, time_left)`` at controller time ``now``: the segment the plan is in ('sent' or
        'accepted' before it runs, 'starting' while the controller holds until its start time,
        'settling' after its end)."""
        elapsed = now - self.start
        left = max(self.duration - elapsed, 0.0)
        if self.state != 'executing':
            return self.state, left
        if elapsed < 0.0:
            return 'starting', left
        for label, begin, end in self.segments:
            if begin <= elapsed < end:
                return label, left
        return 'settling', left


@dataclass(frozen=True)
class Ending:
    """What a controller's answer means for a goal: plan it again (``late``), or end it with
    ``outcome`` and ``message``; ``code`` is the controller's error code."""

    outcome: Outcome | None
    message: str
    code: int = 0
    late: bool = False


class Lifecycle:
    """The goals in flight to the controller, by goal key."""

    def __init__(self):
        self.flights = {}
        #: s from sending the newest answered plan to the controller's goal response: how long
        #: delivery takes now (a loaded machine takes far longer), which a plan's start must allow.
        self.latency = 0.0

    def sent(self, flight):
        """A plan went out: every goal before it that the controller still has is superseded by it."""
        for other in self.flights.values():
            other.superseded = True
        self.flights[flight.goal.key] = flight
        return flight

    def unanswered(self):
        """True while a plan waits for the controller's goal response: the next plan waits too, so
        that a burst of goals never queues up plans at the controller (one in flight at a time)."""
        return any(f.state == 'sent' for f in self.flights.values())

    def response(self, key, accepted, wall, sent=None):
        """The controller's goal response (at ``wall``) to the plan ``sent`` (a Flight; None: the goal's
        newest); an Ending when it did not take the plan."""
        flight = self.flights.get(key)
        if flight is None or not _newest(flight, sent):
            return None
        self.latency = max(wall - flight.sent, 0.0)
        if not accepted:
            self.flights.pop(key)
            return Ending(Outcome.REFUSED, 'the controller did not accept the plan (its goal was rejected)')
        flight.state = 'accepted'
        for other in self.flights.values():
            if other is not flight and other.sent <= flight.sent:
                other.overtaken = True
        return None

    def feedback(self, key, tracking_error, sent=None):
        """The controller's feedback on the plan ``sent`` (None: the goal's newest): True the first time
        (the plan now runs)."""
        flight = self.flights.get(key)
        if flight is None or not _newest(flight, sent):
            return False
        flight.tracking_error = tracking_error
        first = flight.state != 'executing'
        flight.state = 'executing'
        return first

    def result(self, key, status, code, text, sent=None):
        """The controller's result (``status``: 'succeeded', 'canceled' or 'aborted') for the plan ``sent``
        (None: the goal's newest): an Ending; None for a plan the same goal planned again after it (a
        harvest around a changed world: the newer plan answers for the goal)."""
        flight = self.flights.get(key)
        if flight is None or not _newest(flight, sent):
            return None
        del self.flights[key]
        if status == 'succeeded':
            return Ending(Outcome.SUCCEEDED, 'the arm is at rest at the goal', code)
        if status == 'canceled' and flight.stopped:
            return Ending(Outcome.ABORTED, f'stopped: {flight.stopped}', code)
        if status == 'canceled':
            return Ending(Outcome.CANCELED, f'canceled: {text}' if text else 'canceled', code)
        if flight.superseded and code in (INVALID_GOAL, OLD_HEADER_TIMESTAMP):
            return Ending(Outcome.SUPERSEDED, 'superseded: a newer goal took the arm over', code)
        if code == OLD_HEADER_TIMESTAMP:
            return Ending(None, text, code, late=True)
        if flight.state == 'executing' or code not in (INVALID_GOAL, INVALID_JOINTS):
            return Ending(Outcome.ABORTED, f'the controller aborted it: {text}', code)
        return Ending(Outcome.REFUSED, f'the controller refused the plan: {text}', code)

    def cancel(self, key):
        """The flight of goal ``key`` (to cancel at the controller), or None."""
        return self.flights.get(key)

    def overdue(self, wall, now):
        """Flights the controller left unanswered too long, removed, with an Ending each: no
        goal response RESPONSE_LIMIT s after sending and by the plan's start, or no result
        RESULT_MARGIN s after the plan's end (controller time ``now``): aborted, or superseded when
        the controller accepted a newer plan of ours after it."""
        ended = []
        for key, flight in list(self.flights.items()):
            if flight.state == 'sent' and wall - flight.sent > RESPONSE_LIMIT and now > flight.start:
                why = (f'the controller did not answer the plan within {wall - flight.sent:.1f} s (by its start, '
                       f'and at least {RESPONSE_LIMIT:g} s)')
            elif flight.state != 'sent' and now > flight.start + flight.duration + RESULT_MARGIN:
                why = f'no result from the controller {RESULT_MARGIN:g} s after the plan\'s end'
            else:
                continue
            del self.flights[key]
            if flight.overtaken:
                # (A controller flooded with goals may never answer one a newer accepted plan took over from.)
                why = f'superseded: a newer goal took the arm over ({why})'
                ended.append((flight, Ending(Outcome.SUPERSEDED, why)))
            else:
                ended.append((flight, Ending(Outcome.ABORTED, why)))
        return ended


def _newest(flight, sent):
    """Whether an answer about the plan ``sent`` (None: any) is about ``flight``, the goal's newest."""
    return sent is None or sent is flight
