"""Where a goal's plan starts: a state the planner knows, never a guess (pure core).

The controller owns the arm's future: it splices each trajectory onto its schedule at the
trajectory's stamp. So a plan starts from

1. the state of the planner's own newest accepted plan at a time ``t_s`` no earlier than that plan's
   start, and is stamped ``t_s``: the controller runs it from there exactly (the first point is its
   reference then); the planner knows that state because the controller runs that plan as sent;
2. else (no plan of ours is known to run: after a fault, a cancel, another client's trajectory, at
   start-up) the controller's current reference: at rest, stamped ``t_s`` as in 1 (a reference at rest
   stays there); moving, stamped 0 ("from your reference, now"): the controller bridges from where its
   reference is then to the plan's first point within the limits;
3. else (no controller reference) the measured state, at rest, stamped 0.

Times are on the controller's schedule (its clock less the delay its stalls added to the motion
under way; see :class:`Timing`), in s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: s: a planning kind's first goal is expected to take this long to plan (later: what the last took).
FIRST_PLANNING = {'pose': 0.05, 'path': 0.1, 'pick': 0.4, 'harvest': 2.0}
#: s: a kind's first plan is expected to take this long to reach the controller and be checked there.
FIRST_DELIVERY = 0.05
#: How much of the longest delivery seen is forgotten at each plan delivered in time.
DELIVERY_DECAY = 0.9
#: rad: a reference this close to a plan's state is that plan's state.
SAME_STATE = 1e-6


@dataclass(frozen=True)
class Start:
    """Where a plan starts: ``state`` ``(q, qd, qdd)`` of the arm's joints, the gripper's opening (m, None where
    unknown), ``time`` the schedule time it starts (0.0: now, from the controller's reference) and ``source``:
    ``'plan'`` (our accepted plan then), ``'reference'`` (the controller's) or ``'measured'``."""

    state: tuple
    gripper: float | None
    time: float
    source: str

    def words(self):
        return {'plan': 'the plan running then', 'reference': "the controller's reference",
                'measured': 'the measured state'}[self.source]


@dataclass(frozen=True)
class Running:
    """The newest plan the controller accepted from this planner: its trajectory (time 0 at ``start``, the
    schedule time it was stamped with), the joint ``names`` of its columns, its goal's ``key``; ``ended``
    once its goal ended: 'succeeded' (the arm holds its end) or how else (it no longer says where the arm is)."""

    trajectory: object
    names: tuple
    start: float
    key: str
    dof: int
    ended: str = ''

    @property
    def end(self):
        return self.start + self.trajectory.duration

    def state_at(self, t):
        """``((q, qd, qdd) of the arm's joints, gripper or None)`` at schedule time ``t`` (at or after its start)."""
        return self.at_plan_time(max(t - self.start, 0.0))

    def at_plan_time(self, elapsed):
        """As :meth:`state_at`, ``elapsed`` s into the plan (exact where the plan itself names the time)."""
        q, qd, qdd = self.trajectory.state_at(elapsed)
        gripper = float(q[self.dof]) if len(self.names) > self.dof else None
        return (q[:self.dof].copy(), qd[:self.dof].copy(), qdd[:self.dof].copy()), gripper

    @property
    def usable(self):
        """True while the controller runs it or holds its end, where it is known to run."""
        return self.start is not None and self.ended in ('', 'succeeded')


def choose_start(running, t_earliest, reference, measured):
    """The :class:`Start` of a plan to take over no earlier than schedule time ``t_earliest``.

    ``running``: our newest accepted plan (:class:`Running`, or None); ``reference``: the controller's newest
    reference ``((q, qd, qdd), gripper)`` or None; ``measured``: ``(q, gripper)`` or None. A plan that ended
    and holds its end is checked against the reference (another client may have moved the arm since)."""
    if running is not None and running.usable:
        t = max(t_earliest, running.start)
        state, gripper = running.state_at(t)
        if not (running.ended and reference is not None and _apart(reference[0], state)):
            return Start(state, gripper, t, 'plan')
    if reference is not None:
        state, gripper = reference
        state = tuple(np.asarray(x, float).copy() for x in state)
        # At rest the reference stays where it is: the plan is stamped like any other and carries on from it.
        at_rest = not np.abs(state[1]).any() and not np.abs(state[2]).any()
        return Start(state, gripper, t_earliest if at_rest else 0.0, 'reference')
    if measured is None:
        raise ValueError('no joint_states received yet: the planner does not know where the arm is')
    q, gripper = measured
    q = np.asarray(q, float)
    return Start((q.copy(), np.zeros_like(q), np.zeros_like(q)), gripper, 0.0, 'measured')


def _apart(a, b):
    return any(np.abs(np.asarray(x) - np.asarray(y)).max() > SAME_STATE for x, y in zip(a, b))


class Timing:
    """When a plan is to take over: ``lead`` s after planning is expected to end (delivery and the controller's
    checks; doubled at each late re-plan), on the controller's schedule.

    ``delay``: s the controller's schedule runs behind its clock (its stalls during the motion under way), as
    its feedback says; 0 once the arm holds with nothing scheduled.
    """

    def __init__(self, lead=0.05):
        self.lead = float(lead)
        self.planning, self.delivery = {}, {}
        self.delay = 0.0

    def expected(self, kind):
        """s planning a goal of ``kind`` is expected to take."""
        return self.planning.get(kind, FIRST_PLANNING[kind])

    def earliest(self, kind, attempt, now):
        """The earliest schedule time a plan for a goal of ``kind`` (planned ``attempt`` times again after a late
        verdict) can take over when planning starts at clock time ``now``: its planning and its delivery as the
        last of its kind took (the longest delivery seen, slowly forgotten), with room to spare."""
        return now - self.delay + self.lead * 2 ** attempt + 1.5 * (self.expected(kind) + self.delivery.get(
            kind, FIRST_DELIVERY))

    def planned(self, kind, seconds):
        self.planning[kind] = float(seconds)

    def delivered(self, kind, seconds, late=False):
        """A plan of ``kind`` took ``seconds`` from sending to the controller's word on it (``late``: it came after
        its start, so delivery takes at least that long)."""
        known = self.delivery.get(kind, FIRST_DELIVERY)
        self.delivery[kind] = max(float(seconds), known if late else DELIVERY_DECAY * known)

    def heard(self, now, stamp, elapsed):
        """The controller's feedback: at clock time ``now`` its reference is ``elapsed`` s into the points of a
        trajectory stamped ``stamp``; what it says of the schedule's delay."""
        if stamp > 0 and elapsed is not None:
            self.delay = max(0.0, now - stamp - elapsed)
