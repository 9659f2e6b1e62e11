"""A goal's life once its plan is sent, without ROS: the controller's answers mapped to outcomes, the phases and
time left by the controller's word, and the bounds on a controller that does not answer."""

from types import SimpleNamespace

import pytest

from picking_core.goals.lifecycle import (
    ANSWER_GRACE,
    INVALID_GOAL,
    INVALID_JOINTS,
    OLD_HEADER_TIMESTAMP,
    RESPONSE_LIMIT,
    RESULT_MARGIN,
    Flight,
    Lifecycle,
    Outcome,
    State,
)
from picking_core.planning import Segment


def flight(key, sent=0.0, start=10.0, duration=2.0):
    plan = SimpleNamespace(duration=duration, segments=[Segment('P1 approach', 'optimal', 0.0, 1.0),
                                                        Segment('grasp', 'dwell', 1.0, 1.0)])
    return Flight(SimpleNamespace(key=key), SimpleNamespace(plan=plan), start, ('a',), sent)


def test_a_goal_goes_accepted_executing_then_ends_with_the_controllers_result():
    life = Lifecycle()
    f = life.sent(flight('g'))
    assert life.unanswered()
    assert life.response(f, True) is None and f.state == State.ACCEPTED
    assert life.unanswered()                  # accepted, but not yet on the controller's schedule: it may be late
    assert life.feedback(f, 0.2, 0.001) and not life.feedback(f, 0.3, 0.001)
    assert f.scheduled and not life.unanswered()
    assert f.phase() == ('P1 approach', pytest.approx(1.7))
    assert life.result(f, 'succeeded', 0, '').outcome == Outcome.SUCCEEDED and 'g' not in life.flights


def test_a_joint_move_names_its_method_as_its_phase():
    f = flight('g')
    f.planned.plan.segments = [Segment('move', 'lspb', 0.0, 2.0)]
    life = Lifecycle()
    life.sent(f)
    life.response(f, True)
    life.feedback(f, 0.5, 0.001)
    assert f.phase() == ('move (lspb)', pytest.approx(1.5))


@pytest.mark.parametrize('status, code, executing, why, outcome', [
    ('canceled', 0, True, 'why', Outcome.CANCELED),
    ('aborted', -4, True, 'why', Outcome.ABORTED),
    ('aborted', INVALID_GOAL, False, 'why', Outcome.REFUSED),
    ('aborted', INVALID_JOINTS, False, 'why', Outcome.REFUSED),
    ('aborted', INVALID_GOAL, True, 'why', Outcome.ABORTED),
    # Taken, then dropped before it ran: not refused for being wrong.
    ('aborted', INVALID_GOAL, False, 'preempted: the goal it was spliced onto was canceled', Outcome.ABORTED),
])
def test_the_controllers_verdicts_map_to_outcomes(status, code, executing, why, outcome):
    life = Lifecycle()
    f = life.sent(flight('g'))
    life.response(f, True)
    if executing:
        life.feedback(f, 0.1, 0.0)
    assert life.result(f, status, code, why).outcome == outcome


def test_a_plan_refused_as_late_is_to_be_planned_again_and_one_a_newer_plan_of_ours_replaced_is_superseded():
    life = Lifecycle()
    f = life.sent(flight('g'))
    life.response(f, True)
    assert life.result(f, 'aborted', OLD_HEADER_TIMESTAMP, 'it starts 0.1 s in the past').late
    old = life.sent(flight('a'))
    life.response(old, True)
    life.sent(flight('b', sent=1.0))
    assert life.result(old, 'aborted', INVALID_GOAL, 'preempted').outcome == Outcome.SUPERSEDED


def test_time_left_stands_still_while_the_controller_is_silent_on_where_the_plan_is():
    """A stall of the controller delays the plan: its feedback's time in the plan stands still, and so does the
    time left; a feedback that cannot say where the plan is (braking) leaves the last word standing."""
    life = Lifecycle()
    f = life.sent(flight('g'))
    life.response(f, True)
    lefts = []
    for elapsed in (0.1, 0.5, 0.5, 0.5, None, 0.9):
        life.feedback(f, elapsed, 0.0)
        lefts.append(f.phase()[1])
    assert lefts == sorted(lefts, reverse=True) and lefts[1:5] == [pytest.approx(1.5)] * 4


def test_a_plan_unanswered_by_its_start_is_to_be_planned_again_and_one_without_a_result_ends():
    life = Lifecycle()
    silent = life.sent(flight('s', sent=0.0, start=1.0))
    assert life.overdue(0.5, 1.0 + ANSWER_GRACE - 0.1) == []
    (gone, ending), = life.overdue(0.5, 1.0 + ANSWER_GRACE + 0.1)
    assert gone is silent and ending.late and 'did not answer the plan by its start' in ending.message
    assert not life.unanswered()                       # the plan again may go
    unstamped = life.sent(flight('u', sent=0.0, start=None))
    assert life.overdue(RESPONSE_LIMIT - 0.1, 50.0) == []
    (gone, ending), = life.overdue(RESPONSE_LIMIT + 0.1, 50.0)
    assert gone is unstamped and ending.late
    first = life.sent(flight('a', sent=20.0, start=21.0, duration=1.0))
    life.response(first, True)
    newer = life.sent(flight('b', sent=21.0, start=22.0, duration=1.0))
    life.response(newer, True)
    ended = dict((f.goal.key, e) for f, e in life.overdue(30.0, 22.0 + RESULT_MARGIN + 0.1))
    assert ended['a'].outcome == Outcome.SUPERSEDED and 'no result' in ended['a'].message
    assert 'b' not in ended


def test_a_goal_planned_again_answers_through_its_newest_plan_only():
    life = Lifecycle()
    old = life.sent(flight('g'))
    life.response(old, True)
    new = life.sent(flight('g', sent=1.0))
    assert life.result(old, 'aborted', INVALID_GOAL, 'preempted') is None
    life.response(new, True)
    assert life.result(new, 'succeeded', 0, '').outcome == Outcome.SUCCEEDED
