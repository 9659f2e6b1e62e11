"""The life of a planner goal once its plan is sent (pure core).

Every plan goes to the controller as a ``follow_joint_trajectory`` goal. The controller's goal response
says whether it took the plan (**accepted**), its first feedback that the plan runs (**executing**), and
its result how it ended: **succeeded**, **aborted** (a tolerance, lost feedback), **superseded** (our
newer plan took over), **canceled**, or **refused** (it never ran). A plan refused as late (its stamp
already past when it arrived) is planned again, and so is one the controller has not answered by its
start: it can no longer run as planned, and its answer may be lost (a DDS service drops a response while
the server has not yet discovered the client's reader). A controller that sends no result in time ends
the goal as aborted with the reason: no goal stays accepted forever.

Times: ``wall`` is ``time.monotonic()``; plan times are on the controller's schedule.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

#: s after a plan's start that its goal response may still come (the controller took it just in time and
#: its answer is on the way) before the plan is taken as not delivered and planned again.
ANSWER_GRACE = 1.0
#: s the controller has to answer a plan stamped 0 (it starts where the controller puts it) before it is
#: taken as not delivered and planned again. Generous: a controller sharing a saturated machine has
#: answered after seconds.
RESPONSE_LIMIT = 10.0
#: s after a plan's end that its result may take (the goal time tolerance and settling) before the goal
#: is aborted.
RESULT_MARGIN = 5.0
#: s between two requests for a result overdue after the plan's end: a DDS service drops a response while the server
#: has not yet discovered the client's reader, and a request made later is answered then.
RESULT_RETRY = 1.0
#: s a plan stamped 0 (where the controller puts it) may start after it was sent: the controller's bridge to it.
BRIDGE_ALLOWANCE = 2.0
#: Times a goal is planned again when the controller refused its plan as late, each time further ahead.
LATE_REPLANS = 2

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


class State(str, enum.Enum):
    """Where a sent plan is: sent (no answer yet), accepted, executing (its feedback came)."""

    SENT = 'sent'
    ACCEPTED = 'accepted'
    EXECUTING = 'executing'


@dataclass
class Flight:
    """A goal's plan sent to the controller, until its result.

    ``start`` is the schedule time the plan takes over: its stamp, or (stamped 0, from the controller's
    reference) learnt from the controller's first feedback; None until then.
    """

    goal: object                  # requests.Goal
    planned: object               # planning.Planned
    start: float | None
    names: tuple
    sent: float                   # wall s
    trajectory: str = ''          # the plan's stamp, as the controller names it
    state: State = State.SENT
    superseded: bool = False      # a newer plan of ours was sent after it
    overtaken: bool = False       # ... and the controller accepted that one (it takes over from this)
    tracking_error: float = 0.0   # rad, the controller's newest feedback
    asked: float = -1e9           # wall s its result was last asked for again
    elapsed: float | None = None  # s into the plan's points, the controller's newest feedback
    handle: object = None         # the controller's goal handle, once accepted
    scheduled: bool = False       # the controller's feedback says its schedule has the plan (it will run)
    cancel: bool = False          # its client asked to cancel it
    stopped: str = ''             # why the planner stopped it at the controller (the world changed)
    extra: dict = field(default_factory=dict)
    serial: int = 0               # the planner's count of the plans it sent
    # The rest of a harvest: the flight whose plan it takes over from, and what the planner knew of the harvest
    # under way when it was sent (that one's HarvestRun and the controller's Running): theirs again if it never runs.
    replaces: object = None
    displaced: tuple = (None, None)

    @property
    def duration(self):
        return self.planned.plan.duration

    def phase(self):
        """``(phase, time_left)`` by the controller's newest word on where the plan is: 'sent' or 'accepted'
        before it runs, 'starting' before its first point, the segment it is in (a joint move with its method:
        'move (lspb)'), 'settling' after its end. Time
        left never rises: it counts the plan's own time, which a stall of the controller delays."""
        elapsed = self.elapsed
        if self.state != State.EXECUTING or elapsed is None:
            return self.state.value, self.duration
        left = max(self.duration - elapsed, 0.0)
        if elapsed < 0.0:
            return 'starting', left
        for seg in self.planned.plan.segments:
            if seg.start <= elapsed < seg.start + seg.duration:
                return (f'move ({seg.method})' if seg.label == 'move' else seg.label), left
        return 'settling', left


@dataclass(frozen=True)
class Ending:
    """What a controller's answer means for a goal: plan it again (``late``), or end it with ``outcome`` and
    ``message``; ``code`` is the controller's error code."""

    outcome: Outcome | None
    message: str
    code: int = 0
    late: bool = False


class Lifecycle:
    """The goals in flight to the controller, by goal key (a goal planned again keeps one flight: its newest)."""

    def __init__(self):
        self.flights = {}

    def sent(self, flight):
        """A plan went out: every goal before it that the controller still has is superseded by it."""
        for other in self.flights.values():
            other.superseded = True
        self.flights[flight.goal.key] = flight
        return flight

    def unanswered(self):
        """True while a plan waits for the controller's word that its schedule has it (a goal accepted may still
        be refused, as late): the next plan waits too, so that it never starts from a plan that will not run, and
        a burst of goals never queues up plans at the controller (one in flight at a time)."""
        return any(f.state == State.SENT or not f.scheduled for f in self.flights.values())

    def scheduled(self, flight):
        """The controller's word that its schedule has ``flight``'s plan: True the first time."""
        first = not flight.scheduled
        flight.scheduled = True
        return first

    def current(self, flight):
        """True while ``flight`` is its goal's newest plan."""
        return self.flights.get(flight.goal.key) is flight

    def response(self, flight, accepted):
        """The controller's goal response to ``flight``: an Ending when it did not take the plan."""
        if not self.current(flight):
            return None
        if not accepted:
            del self.flights[flight.goal.key]
            return Ending(Outcome.REFUSED, 'the controller did not accept the plan (its goal was rejected)')
        flight.state = State.ACCEPTED
        for other in self.flights.values():
            if other is not flight and other.sent <= flight.sent:
                other.overtaken = True
        return None

    def feedback(self, flight, elapsed, tracking_error):
        """The controller's feedback on ``flight``: True the first time (the plan now runs)."""
        if not self.current(flight):
            return False
        flight.tracking_error = tracking_error
        self.scheduled(flight)
        if elapsed is not None:                   # (unknown while the controller brakes: the last word stands)
            flight.elapsed = elapsed
        first = flight.state != State.EXECUTING
        flight.state = State.EXECUTING
        return first

    def result(self, flight, status, code, text):
        """The controller's result (``status``: 'succeeded', 'canceled' or 'aborted') for ``flight``: an Ending;
        None for a plan the same goal was planned again after (its newer plan answers for the goal)."""
        if not self.current(flight):
            return None
        del self.flights[flight.goal.key]
        if status == 'succeeded':
            return Ending(Outcome.SUCCEEDED, 'the arm is at rest at the goal', code)
        if status == 'canceled' and flight.stopped:
            return Ending(Outcome.ABORTED, f'stopped: {flight.stopped}', code)
        if status == 'canceled':
            return Ending(Outcome.CANCELED, text or 'canceled', code)
        if flight.superseded and code in (INVALID_GOAL, OLD_HEADER_TIMESTAMP):
            return Ending(Outcome.SUPERSEDED, 'superseded: a newer goal took the arm over', code)
        if code == OLD_HEADER_TIMESTAMP:
            return Ending(None, text, code, late=True)
        # A plan preempted before it ran was taken, then dropped (the goal it was spliced onto was canceled):
        # aborted, not refused for being wrong.
        if flight.state == State.EXECUTING or code not in (INVALID_GOAL, INVALID_JOINTS) or text.startswith('preempted'):
            return Ending(Outcome.ABORTED, f'the controller aborted it: {text}', code)
        return Ending(Outcome.REFUSED, f'the controller refused the plan: {text}', code)

    def results_to_ask(self, wall, schedule_now):
        """Flights the controller took whose result is overdue (past the plan's end), to ask for once more: each
        every RESULT_RETRY s until it comes or :meth:`overdue` ends it."""
        out = []
        for flight in self.flights.values():
            if flight.state == State.SENT or wall - flight.asked < RESULT_RETRY:
                continue
            if flight.start is not None:
                due = schedule_now > flight.start + flight.duration + RESULT_RETRY
            else:
                due = wall - flight.sent > flight.duration + BRIDGE_ALLOWANCE + RESULT_RETRY
            if due:
                flight.asked = wall
                out.append(flight)
        return out

    def overdue(self, wall, schedule_now):
        """Flights the controller left unanswered too long, removed, with an Ending each. Not answered by the
        plan's start (and ANSWER_GRACE s; stamped 0: RESPONSE_LIMIT s after sending): ``late``, to be planned
        again (an answer that comes later is for a plan no longer ours). No result RESULT_MARGIN s after the
        plan's end (schedule time ``schedule_now``): aborted, or superseded when the controller accepted a newer
        plan of ours after it."""
        ended = []
        for key, flight in list(self.flights.items()):
            if flight.state == State.SENT:
                if flight.start is not None and schedule_now > flight.start + ANSWER_GRACE:
                    why = f'the controller did not answer the plan by its start (and {ANSWER_GRACE:g} s)'
                elif flight.start is None and wall - flight.sent > RESPONSE_LIMIT:
                    why = f'the controller did not answer the plan within {RESPONSE_LIMIT:g} s'
                else:
                    continue
                del self.flights[key]
                ended.append((flight, Ending(None, why, late=True)))
                continue
            if flight.start is not None and schedule_now > flight.start + flight.duration + RESULT_MARGIN:
                why = f"no result from the controller {RESULT_MARGIN:g} s after the plan's end"
            elif flight.start is None and wall - flight.sent > flight.duration + BRIDGE_ALLOWANCE + RESULT_MARGIN:
                why = f"no result from the controller {RESULT_MARGIN:g} s after the plan's end"
            else:
                continue
            del self.flights[key]
            if flight.overtaken:
                ended.append((flight, Ending(Outcome.SUPERSEDED, f'superseded: a newer goal took the arm over ({why})')))
            else:
                ended.append((flight, Ending(Outcome.ABORTED, why)))
        return ended
