"""The planner's goal lifecycle without ROS: how the controller's answers end a goal."""

from picking_core.goal_policy import Goal
from picking_core.lifecycle import RESPONSE_LIMIT, RESULT_MARGIN, Flight, Lifecycle, Outcome

OLD_HEADER_TIMESTAMP, INVALID_GOAL, PATH_TOLERANCE_VIOLATED = -3, -1, -4


def flight(key, start=100.0, duration=2.0, sent=10.0):
    return Flight(Goal('pick', key, None), start, duration, [('approach', 0.0, 1.0), ('grasp', 1.0, 2.0)], sent)


def test_a_goal_goes_accepted_executing_then_ends_with_the_controllers_result():
    life = Lifecycle()
    f = life.sent(flight('a'))
    assert f.phase(99.0) == ('sent', 3.0)
    assert life.response('a', True, 10.2) is None and f.state == 'accepted'
    assert life.feedback('a', 0.01) is True and life.feedback('a', 0.02) is False
    assert f.phase(99.9)[0] == 'starting' and f.phase(100.5) == ('approach', 1.5) and f.phase(101.5) == ('grasp', 0.5)
    assert f.phase(102.5) == ('settling', 0.0) and f.tracking_error == 0.02
    ending = life.result('a', 'succeeded', 0, '')
    assert ending.outcome == Outcome.SUCCEEDED and not life.flights


def test_the_controllers_verdicts_map_to_outcomes():
    life = Lifecycle()
    life.sent(flight('r'))
    assert life.response('r', False, 10.1).outcome == Outcome.REFUSED
    life.sent(flight('i'))
    life.response('i', True, 10.1)
    assert life.result('i', 'aborted', INVALID_GOAL, 'point 0: beyond').outcome == Outcome.REFUSED
    life.sent(flight('p'))
    life.response('p', True, 10.1)
    life.feedback('p', 0.2)
    ending = life.result('p', 'aborted', PATH_TOLERANCE_VIOLATED, 'path tolerance violated')
    assert ending.outcome == Outcome.ABORTED and 'path tolerance' in ending.message and ending.code == -4
    life.sent(flight('c'))
    assert life.result('c', 'canceled', 0, 'braked').outcome == Outcome.CANCELED
    life.sent(flight('l'))
    assert life.result('l', 'aborted', OLD_HEADER_TIMESTAMP, 'ends in the past').late


def test_a_plan_preempted_by_our_newer_plan_is_superseded():
    life = Lifecycle()
    life.sent(flight('old'))
    life.response('old', True, 10.1)
    life.sent(flight('new'))
    assert life.result('old', 'aborted', INVALID_GOAL, 'preempted').outcome == Outcome.SUPERSEDED
    # Late because the newer one took over first: superseded too, not planned again.
    life.sent(flight('newest'))
    assert life.result('new', 'aborted', OLD_HEADER_TIMESTAMP, 'late').outcome == Outcome.SUPERSEDED


def test_an_unanswered_plan_ends_aborted_with_the_reason():
    life = Lifecycle()
    life.sent(flight('quiet', sent=10.0))
    life.sent(flight('stuck', start=100.0, duration=2.0, sent=10.0)).state = 'executing'
    assert life.overdue(10.0 + RESPONSE_LIMIT / 2, 101.0) == []
    ended = life.overdue(10.0 + RESPONSE_LIMIT + 0.1, 101.0)
    assert [(f.goal.key, e.outcome) for f, e in ended] == [('quiet', Outcome.ABORTED)]
    assert 'did not answer' in ended[0][1].message
    ended = life.overdue(20.0, 102.0 + RESULT_MARGIN + 0.1)
    assert [f.goal.key for f, _ in ended] == ['stuck'] and 'no result' in ended[0][1].message
    assert not life.flights
    # A plan that starts later than the limit may be answered until its start.
    life.sent(flight('ahead', start=120.0, sent=10.0))
    assert life.overdue(10.0 + RESPONSE_LIMIT + 5.0, 115.0) == []
    assert [f.goal.key for f, _ in life.overdue(10.0 + RESPONSE_LIMIT + 11.0, 120.5)] == ['ahead']


def test_a_plan_left_without_a_result_after_a_newer_one_was_accepted_ends_superseded():
    life = Lifecycle()
    life.sent(flight('old', sent=10.0)).state = 'executing'
    life.sent(flight('refused', sent=10.5))
    life.response('refused', False, 10.6)                      # not taken: the old one may still run
    life.sent(flight('new', start=101.0, sent=11.0))
    assert not life.flights['old'].overtaken
    life.response('new', True, 11.2)                           # taken: it took over from the old one
    ended = life.overdue(20.0, 102.0 + RESULT_MARGIN + 0.1)
    assert [(f.goal.key, e.outcome) for f, e in ended] == [('old', Outcome.SUPERSEDED)]
    assert 'no result' in ended[0][1].message and list(life.flights) == ['new']


def test_one_plan_at_a_time_waits_for_the_controllers_answer():
    life = Lifecycle()
    assert not life.unanswered()
    life.sent(flight('a'))
    assert life.unanswered()
    life.response('a', True, 10.4)
    assert not life.unanswered() and abs(life.latency - 0.4) < 1e-9     # delivery takes this long now


def test_a_plan_the_planner_stopped_because_the_world_changed_ends_aborted_with_why():
    life = Lifecycle()
    f = life.sent(flight('run'))
    life.response('run', True, 10.2)
    f.stopped = 'the world changed while it ran: wrist_3_link 1.0 cm into the canopy'
    ending = life.result('run', 'canceled', 0, 'canceled on request')
    assert ending.outcome == Outcome.ABORTED and ending.message.startswith('stopped: the world changed')
    other = life.sent(flight('asked'))
    life.response('asked', True, 10.2)
    assert life.result('asked', 'canceled', 0, '').outcome == Outcome.CANCELED and not other.stopped


def test_a_goal_planned_again_answers_through_its_newest_plan_only():
    """A harvest planned again around a changed world: the plan it replaces runs on until the new one takes
    over, and the controller's answers about it (its feedback, its result when replaced) end nothing."""
    life = Lifecycle()
    old = life.sent(flight('h'))
    life.response('h', True, 10.1, old)
    new = life.sent(flight('h', start=101.0, duration=5.0, sent=11.0))
    assert life.flights['h'] is new
    assert life.feedback('h', 0.01, old) is False and new.state == 'sent'
    assert life.result('h', 'aborted', INVALID_GOAL, 'replaced', old) is None and life.flights['h'] is new
    assert life.response('h', True, 11.1, new) is None and new.state == 'accepted'
    assert life.result('h', 'succeeded', 0, '', new).outcome == Outcome.SUCCEEDED and not life.flights
