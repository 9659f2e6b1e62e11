"""The controller's logic without ROS: splicing, tolerances, goal, watchdog, refusals."""

import numpy as np
import pytest

from picking_controller.core import ControllerCore, Tolerances
from picking_core.trajectory import PiecewisePolynomial

NAMES = ['a', 'b', 'gripper']
INF = np.inf


def core(**tol):
    c = ControllerCore(NAMES, [-3, -3, 0], [3, 3, 0.1], [2, 2, 0.3], [10, 10, 3], Tolerances(**tol),
                       optional=['gripper'])
    c.on_state([0.0, 0.0, 0.05], [0.0, 0.0, 0.0], 0.0, now=0.0)
    return c


def test_waits_for_feedback_then_holds_the_measured_position():
    c = ControllerCore(NAMES, [-3] * 3, [3] * 3, [2] * 3, [10] * 3)
    assert c.reference(0.0) is None
    event = c.load(NAMES, [1.0], [[1, 1, 0]], [], [], 0.0, now=0.0)
    assert event.level == 'ERROR' and 'no joint_states' in event.message
    events = c.on_state([0.2, -0.1, 0.0], None, 0.0, now=0.0)
    assert 'feedback received' in events[0].message
    q, qd, _ = c.reference(0.5)
    assert q == pytest.approx([0.2, -0.1, 0.0]) and np.all(qd == 0)


def test_trajectory_runs_and_the_goal_is_reported():
    c = core()
    ev = c.load(['b', 'a'], [1.0], [[0.5, 1.0]], [], [], 0.0, now=0.0)
    assert ev.level == 'OK', ev.message
    q, _, _ = c.reference(1.0)
    assert q == pytest.approx([1.0, 0.5, 0.05])          # reordered; gripper held
    events = c.on_state([1.0, 0.5, 0.05], [0, 0, 0], 1.1, now=1.1)
    assert events and events[0].message == 'goal reached'


def test_new_trajectory_splices_on_without_a_velocity_jump():
    c = core()
    c.load(['a', 'b'], [2.0], [[1.0, 0.0]], [[0.0, 0.0]], [], 0.0, now=0.0)
    now = 1.0
    before = c.reference(now)
    c.load(['a', 'b'], [0.5, 1.5], [[0.8, 0.0], [-0.5, 0.3]], [], [], 0.0, now=now)
    after = c.reference(now)
    assert after[0] == pytest.approx(before[0]) and after[1] == pytest.approx(before[1])
    t = now + np.linspace(0, 0.1, 101)
    v = np.array([c.reference(x)[1] for x in t])
    assert np.abs(np.diff(v, axis=0)).max() < 0.05


def test_a_prepared_trajectory_takes_over_at_its_splice_time_without_a_jump():
    c = core()
    c.load(['a', 'b'], [2.0], [[1.0, 0.0]], [[0.0, 0.0]], [], 0.0, now=0.0)
    prepared = c.prepare(['a', 'b'], [0.5, 1.5], [[0.8, 0.0], [0.2, 0.3]], [], [], 0.0, now=1.0,
                         splice_delay=0.02)
    old = c.reference(1.01)                               # the old trajectory runs until the splice
    assert c.commit(prepared, now=1.01).level == 'OK'
    assert c.reference(1.015)[0] == pytest.approx(c._reference_at(1.015)[0])
    t = 1.01 + np.linspace(0.0, 0.05, 501)
    q = np.array([c.reference(x)[0] for x in t])
    v = np.array([c.reference(x)[1] for x in t])
    assert q[0] == pytest.approx(old[0])
    assert np.abs(np.diff(v, axis=0)).max() < 0.01          # no velocity step at 1.02 s
    assert c.traj is prepared.traj and c.t0 == pytest.approx(1.02)


def test_a_trajectory_that_replaces_a_scheduled_one_splices_onto_the_reference_that_runs():
    """A trajectory scheduled for 1.05 s is replaced, before then, by one that takes over at 1.1 s: the
    first never runs, so the second leads in from the trajectory that does (spliced onto the
    scheduled one, it jumped)."""
    c = core()
    c.load(['a', 'b'], [2.0], [[1.0, 0.0]], [[0.0, 0.0]], [], 0.0, now=0.0)
    first = c.prepare(['a', 'b'], [0.6], [[0.3, 0.4]], [[0.0, 0.0]], [], 0.0, now=1.0, splice_delay=0.05)
    assert c.commit(first, now=1.0).level == 'OK'
    second = c.prepare(['a', 'b'], [0.8], [[1.0, -0.2]], [[0.0, 0.0]], [], 0.0, now=1.0, splice_delay=0.1)
    assert c.commit(second, now=1.01).level == 'OK'
    reports, sent = [], []
    for now in np.arange(0.0, 1.0, 1e-3):
        c.command(now)
    for now in np.arange(1.0, 1.7, 1e-3):
        (q, qd, _), events = c.command(now)
        sent.append((q, qd))
        reports += events
    assert c.traj is second.traj
    assert not [e for e in reports if 'command limited' in e.message], [e.message for e in reports]
    q = np.array([s[0] for s in sent])
    assert np.abs(np.diff(q, axis=0)).max() < 2.0 * 1e-3       # no step beyond the speed limit's per tick


def test_a_prepared_trajectory_is_refused_when_the_state_changed_or_it_came_too_late():
    c = core(path=0.05)
    c.load(['a', 'b'], [2.0], [[1.0, 0.0]], [], [], 0.0, now=0.0)
    prepared = c.prepare(['a', 'b'], [1.0], [[0.5, 0.5]], [], [], 0.0, now=0.5, splice_delay=0.02)
    assert c.commit(prepared, now=0.6) is None                # too late: prepare again
    prepared = c.prepare(['a', 'b'], [1.0], [[0.5, 0.5]], [], [], 0.0, now=0.5, splice_delay=0.02)
    c.on_state([0.3, 0.0, 0.05], None, 0.5, now=0.5)          # a fault brakes meanwhile
    assert c.mode == 'fault'
    assert c.commit(prepared, now=0.51) is None
    with pytest.raises(ValueError, match='unknown joints'):
        c.prepare(['a', 'x'], [1.0], [[0.5, 0.5]], [], [], 0.0, now=0.5)


def test_a_trajectory_that_ends_before_it_could_start_is_rejected_as_late_and_only_that_one():
    """Its sender may plan a late trajectory again; a bad one it must not."""
    c = core()
    late = c.load(['a', 'b'], [0.5, 1.0], [[0.2, 0.0], [0.4, 0.0]], [], [], start=10.0, now=11.01)
    assert late.level == 'ERROR' and 'ends in the past' in late.message and late.values['late'] is True
    bad = c.load(['a', 'x'], [1.0], [[0.5, 0.5]], [], [], start=0.0, now=11.0)
    assert bad.level == 'ERROR' and 'unknown joints' in bad.message and bad.values['late'] is False
    # Points already due, far from where the arm is: late as well.
    behind = c.load(['a', 'b'], [0.5, 1.0], [[0.2, 0.0], [0.4, 0.0]], [], [], start=10.0, now=10.6)
    assert behind.level == 'ERROR' and 'due at' in behind.message and behind.values['late'] is True
    # Due points near the reference: the part still ahead runs.
    caught_up = c.load(['a', 'b'], [0.5, 1.0], [[0.001, 0.0], [0.1, 0.0]], [], [], start=10.0, now=10.6)
    assert caught_up.level == 'OK', caught_up.message


def test_path_tolerance_violation_brakes_and_holds():
    c = core(path=0.05)
    c.load(['a', 'b'], [2.0], [[1.0, 0.0]], [], [], 0.0, now=0.0)
    events = c.on_state([0.3, 0.0, 0.05], None, 0.5, now=0.5)
    assert events[0].level == 'ERROR' and 'path tolerance' in events[0].message
    assert c.mode == 'fault'
    q_end = c.reference(10.0)
    assert np.all(q_end[1] == 0)                          # at rest
    assert abs(q_end[0][0] - c.reference(0.5)[0][0]) < 0.5


def test_watchdog_reports_feedback_lost_and_refuses_to_move_blind():
    c = core(state_timeout=0.2)
    assert c.tick(0.1) == []
    events = c.tick(0.3)
    assert events[0].level == 'ERROR' and 'feedback lost' in events[0].message
    ev = c.load(['a', 'b'], [1.0], [[1.0, 0.0]], [], [], 0.0, now=0.4)
    assert ev.level == 'ERROR' and 'feedback lost' in ev.message
    events = c.on_state([0.0, 0.0, 0.05], None, 0.5, now=0.5)
    assert 'feedback restored' in events[0].message


def test_the_watchdog_counts_only_while_the_loop_runs():
    """A loop stalled longer than state_timeout could read no states meanwhile: the feedback
    is lost only if none comes within state_timeout after the stall."""
    c = core(state_timeout=0.2)
    c.advance(0.0)
    assert c.advance(0.5) == [] and c.tick(0.5) == []         # stalled 0.5 s (holding: no delay to report)
    assert c.tick(0.65) == []
    assert 'feedback lost' in c.tick(0.71)[0].message


def test_restored_feedback_from_a_moved_arm_is_held_where_it_is_not_driven_back():
    c = core(state_timeout=0.2)
    c.tick(0.3)                                               # feedback lost, holding at 0
    c.on_state([0.7, -0.4, 0.05], None, 0.5, now=0.5)        # a restarted driver reports elsewhere
    (q, qd, _), _ = c.command(0.501)
    assert q == pytest.approx([0.7, -0.4, 0.05]) and np.all(qd == 0)       # no step back to 0


def test_future_start_stamp_waits_then_moves():
    c = core()
    ev = c.load(['a', 'b'], [0.0, 1.0], [[0.0, 0.0], [1.0, 0.0]], [], [], 5.0, now=4.0)
    assert ev.level == 'OK'
    assert abs(c.reference(4.5)[0][0]) < 1e-9           # waits at its place until the start
    assert c.reference(5.0)[0][0] == pytest.approx(0.0)
    assert c.reference(6.0)[0][0] == pytest.approx(1.0)


@pytest.mark.parametrize('names, times, pos, reason', [
    (['a', 'x'], [1.0], [[0, 0]], 'unknown joints'),
    (['a'], [1.0], [[0]], 'missing joints'),
    (['a', 'a'], [1.0], [[0, 0]], 'repeat'),
    (['a', 'b'], [], [], 'no points'),
    (['a', 'b'], [1.0, 0.5], [[0, 0], [1, 1]], 'increase strictly'),
    (['a', 'b'], [1.0], [[np.nan, 0]], 'finite'),
    (['a', 'b'], [1.0], [[3.5, 0]], 'beyond its limit'),
    (['a', 'b'], [0.2], [[2.0, 0]], 'between the points'),      # 10 rad/s there
    (['a', 'b'], [1.0], [[0, 0, 0]], 'every point needs 2 positions'),
])
@pytest.mark.parametrize('arrays', [False, True])
def test_bad_trajectories_are_refused_and_the_reference_stays(names, times, pos, reason, arrays):
    c = core()
    before = c.reference(0.0)
    rest = [], []
    if arrays:                # as the node reads them from the message's bytes: one row per point
        pos = np.array(pos, float).reshape(len(times), -1) if len(times) else np.zeros((0, len(names)))
        times, rest = np.array(times, float), (np.zeros((len(times), 0)), np.zeros((len(times), 0)))
    ev = c.load(names, times, pos, *rest, 0.0, now=0.0)
    assert ev.level == 'ERROR' and reason in ev.message, ev.message
    assert c.reference(0.0)[0] == pytest.approx(before[0])
    assert c.mode == 'holding'


def test_a_trajectory_given_as_arrays_runs_as_the_same_one_given_as_lists():
    times, pos = [0.5, 1.0, 1.5], [[0.2, 0.1], [0.6, 0.3], [1.0, 0.4]]
    vel, acc = [[0.8, 0.2], [0.8, 0.2], [0.0, 0.0]], [[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]]
    refs = []
    for form in (lambda x: x, lambda x: np.array(x, float)):
        c = core()
        assert c.load(['a', 'b'], form(times), form(pos), form(vel), form(acc), 0.0, now=0.0).level == 'OK'
        refs.append(np.array([np.concatenate(c.reference(t)) for t in np.linspace(0.0, 2.0, 41)]))
    assert np.array_equal(refs[0], refs[1])


def test_commands_never_leave_the_limits_nor_jump_and_say_so_once():
    from picking_core.trajectory import hold
    c = core()
    (q, qd, qdd), events = c.command(0.0)
    assert q == pytest.approx([0.0, 0.0, 0.05]) and not events
    # A reference beyond a position limit and far away (as a bug would make): limited and reported once.
    c._set(hold(np.array([5.0, -1.0, 0.05]), 1.0), 0.0)
    sent, reports = [], []
    for k in range(1, 2001):
        (q, qd, qdd), events = c.command(k * 1e-3)
        sent.append(q)
        reports += events
    sent = np.array(sent)
    assert np.all(sent[:, 0] <= 3.0) and sent[-1] == pytest.approx([3.0, -1.0, 0.05])
    steps = np.abs(np.diff(np.vstack([[0.0, 0.0, 0.05], sent]), axis=0))
    assert np.all(steps <= np.array([2, 2, 0.3]) * 1e-3 * 1.02)             # never faster than the limit
    assert len(reports) == 1 and reports[0].level == 'WARN' and 'command limited' in reports[0].message
    assert "reference of a: its position 5 is beyond [-3, 3]" in reports[0].message
    assert c.limited > 0


def _the_one_limited_acceleration_report(c, until):
    """Command every ms until ``until`` s: every acceleration sent within the limits, and one
    report, of joint a's acceleration (returned)."""
    reports = []
    for now in np.arange(0.0, until, 1e-3):
        (_, _, sent_qdd), events = c.command(now)
        assert np.all(np.abs(sent_qdd) <= [10, 10, 3])
        reports += events
    assert len(reports) == 1, [r.message for r in reports]
    assert 'reference of a: its acceleration' in reports[0].message
    return reports[0]


def test_an_acceleration_step_between_the_points_is_limited_and_named_as_such():
    """An LSPB sampled every 10 ms: its acceleration steps between two points, where the spline
    through them overshoots the limit (the points themselves keep it). It starts 55 ms after its
    first point, at rest until then, so that the lead-in to its first point run keeps the limit."""
    from picking_core import trajectory
    c = core()
    plan = trajectory.lspb([0.0, 0.0], [0.3, 0.0], 0.6, 9.8)        # 9.8 of the 10 rad/s^2 limit
    t = np.arange(0.0, 0.66 + 1e-9, 0.01)
    q, qd, qdd = plan.sample(t - 0.055)
    assert (0.055 + plan.blend_time[0]) % 0.01 > 1e-3               # the steps fall between two points
    assert c.load(['a', 'b'], t, q, qd, qdd, 0.0, now=0.0).level == 'OK'
    report = _the_one_limited_acceleration_report(c, until=0.7)
    assert 'beyond the limit 10' in report.message and float(report.values['acceleration']) > 10
    assert 'between the points' in report.message


def test_a_trajectory_planned_from_another_reference_is_refused_as_stale_and_a_bad_one_is_not():
    """A plan whose lead-in breaks a limit only because it starts away from where the reference
    will be (made for a plan this controller did not run) may be planned again: refused as late.
    One that starts there and breaks the limit by itself is at fault: not late."""
    c = core()                                                # holding [0, 0] at rest
    stale = c.load(['a', 'b'], [0.1, 0.5], [[0.5, 0.0], [0.6, 0.0]], [], [], start=0.0, now=1.0)
    assert stale.level == 'ERROR' and 'not where the current reference will be' in stale.message
    assert stale.values['late'] is True
    bad = c.load(['a', 'b'], [0.1, 0.2], [[0.0, 0.0], [1.0, 0.0]], [[0.0, 0.0], [0.0, 0.0]], [], start=0.0, now=1.0)
    assert bad.level == 'ERROR' and 'beyond' in bad.message and bad.values['late'] is False, bad.message
    # Malformed, away from the reference as well: at fault, not stale.
    twice = c.load(['a', 'b'], [0.5, 0.5], [[0.5, 0.0], [0.6, 0.0]], [], [], start=0.0, now=1.0)
    assert twice.level == 'ERROR' and 'increase strictly' in twice.message and twice.values['late'] is False


def test_a_late_trajectory_catches_up_over_a_longer_lead_in_within_the_limits():
    c = core(path=0.3)
    # Planned to start 40 ms ago from where the arm holds, at 0.3 rad/s: a 20 ms lead-in would need
    # more than the 10 rad/s^2 limit to catch up; a longer one does not.
    t = np.arange(0.0, 1.01, 0.01)
    q = np.column_stack([0.3 * t, np.zeros_like(t)])
    v = np.column_stack([np.full_like(t, 0.3), np.zeros_like(t)])
    v[-1] = 0.0
    event = c.load(['a', 'b'], t, q, v, [], start=9.96, now=10.0)
    assert event.level == 'OK', event.message
    assert c.next is None and c.lead_in_end - 10.0 > 0.02          # over a longer lead-in
    sent = [c.command(10.0 + k * 1e-3) for k in range(300)]
    assert max(abs(ref[1][0]) for ref, _ in sent) <= 2.0 + 1e-9
    assert max(abs(ref[2][0]) for ref, _ in sent) <= 10.0 + 1e-9
    assert not any(events for _, events in sent)                   # nothing limited


def test_a_stalled_tick_delays_the_trajectory_instead_of_jumping_ahead():
    c = core()
    c.load(['a', 'b'], [2.0], [[1.0, 0.0]], [[0.0, 0.0]], [], 0.0, now=0.0)
    scheduled = c.prepare(['a', 'b'], [1.0], [[0.0, 0.0]], [], [], 0.0, now=1.2)
    assert c.commit(scheduled, now=1.0).level == 'OK'         # takes over at 1.2 s
    for t in np.arange(0.0, 0.5, 0.001):
        assert c.advance(t) == []
        c.command(t)
    before = c.reference(0.499)[0]
    events = c.advance(0.799)                                 # 300 ms without a tick
    assert len(events) == 1 and 'stalled for 0.300 s' in events[0].message
    assert events[0].values['delay'] == pytest.approx(0.25)   # the first 50 ms (stall_limit) still count
    after = c.reference(0.799)[0]
    assert after == pytest.approx(c.traj.state_at(0.549)[0])
    assert np.abs(after - before).max() < 2.0 * 0.051          # within vmax of the last command, no jump
    (q, _, _), limited = c.command(0.799)
    assert limited == [] and q == pytest.approx(after)
    assert c.next.t_splice == pytest.approx(1.45)              # the scheduled one moved with it
    assert c.next.origin == pytest.approx(1.45)
    assert c.advance(0.8) == []
    assert c.advance(1.2) == []                                # reported at most once a second ...
    assert c.delayed == pytest.approx(0.25 + 0.35)            # ... but every delay counts
    assert c.advance(2.5)[0].values['delay'] == pytest.approx(1.25)


def test_the_trajectory_time_counts_from_the_stamp_less_the_stalls_delays():
    """What feedback reports as the reference's time_from_start: its sender learns how late its
    plan runs. A trajectory counts from its stamp (carried on or led in), and each stall's delay
    is taken off (the scheduled one's too: see the test above)."""
    c = core()
    assert c.load(['a', 'b'], [0.5, 2.0], [[0.0, 0.0], [1.0, 0.0]], [], [], 10.0, now=10.0).level == 'OK'
    assert c.trajectory_time(10.3) == pytest.approx(0.3)
    for t in np.arange(10.0, 10.5, 0.001):
        c.advance(t)
        c.command(t)
    c.advance(10.799)                                         # stalled 0.3 s: 0.25 s of delay
    assert c.trajectory_time(10.799) == pytest.approx(0.549)
    assert c.reference(10.799)[0] == pytest.approx(c.traj.state_at(10.799 - 10.25)[0])
    # A trajectory that comes after the stall counts from its own stamp, led in from the reference.
    assert c.load(['a', 'b'], [1.0, 2.0], [[0.0, 0.0], [0.0, 0.1]], [], [], 11.0, now=10.8, goal='g').level == 'OK'
    assert c.trajectory_time(11.5) == pytest.approx(0.5)
    assert c.cancel('g', 11.6)[0]                             # braking: no points of its own run
    assert c.trajectory_time(11.7) is None


def test_a_tracking_check_after_a_stall_compares_with_the_delayed_reference():
    c = core(path=0.05)
    c.load(['a', 'b'], [2.0], [[1.0, 0.0]], [[0.0, 0.0]], [], 0.0, now=0.0)
    c.advance(0.5)
    c.advance(1.0)                                            # stalled: 0.45 s later
    held = c.traj.state_at(0.55)[0]                           # where the drive held the arm
    assert c.on_state(held, [0, 0, 0], 1.0, now=1.0) == []
    assert c.mode == 'moving'


def test_a_state_measured_during_a_stall_is_not_checked_against_the_rewritten_reference():
    """A whole machine stalled: the simulator catches up and sends states stamped inside the
    stall, after this loop has delayed its trajectory; those are not compared (a state stamped
    after the stall is)."""
    c = core(path=0.05)
    c.load(['a', 'b'], [2.0], [[1.0, 0.0]], [[0.0, 0.0]], [], 0.0, now=0.0)
    c.advance(0.5)
    c.advance(1.0)                                            # stalled: the trajectory goes on 0.45 s later
    inside = c.traj.state_at(0.9)[0]                          # where a drive following on would be at 0.9 s
    assert c.on_state(inside, [0, 0, 0], 0.9, now=1.001) == []
    events = c.on_state(inside, [0, 0, 0], 1.001, now=1.002)
    assert events and events[0].level == 'ERROR' and 'path tolerance' in events[0].message


@pytest.mark.parametrize('limit', [0.0, -1.0, np.nan])
def test_stall_limit_must_be_positive(limit):
    with pytest.raises(ValueError, match='stall_limit'):
        ControllerCore(NAMES, [-3] * 3, [3] * 3, [2] * 3, [10] * 3, stall_limit=limit)



def test_a_reference_left_beyond_a_limit_still_takes_a_new_trajectory():
    """A lead-in led in too hard once left the reference a little beyond the speed limit (the command
    was limited): a new trajectory is spliced onto the state commanded, within the limits, instead of
    being refused for a lead-in that starts beyond the limit."""
    c = core()
    coeffs = np.zeros((1, 6, 3))
    coeffs[0, 1, 0], coeffs[0, 2, 0] = 2.05, 0.5          # a at 2.05 rad/s (limit 2), still speeding up
    coeffs[0, 0, 2] = 0.05
    c._set(PiecewisePolynomial([0.0, 3.0], coeffs), 0.0)
    c.mode = 'moving'
    now = 0.5
    q0 = c.reference(now)[0][0]
    times = np.arange(0.1, 0.6, 0.01)
    speed = 1.9
    pos = np.stack([q0 + 0.195 + speed * (times - 0.1), np.zeros_like(times)], axis=1)
    vel = np.stack([np.full_like(times, speed), np.zeros_like(times)], axis=1)
    ev = c.load(['a', 'b'], times, pos, vel, np.zeros_like(pos), 0.0, now=now)
    assert ev.level == 'OK', ev.message
    v = np.array([c.reference(now + k * 1e-3)[1][0] for k in range(200)])
    assert v.max() <= 2.0 + 1e-3


def test_a_lead_in_too_short_for_the_acceleration_limit_is_refused_not_limited():
    """A first point 0.05 s ahead and 0.02 rad away: the lead-in from rest needs more than the
    10 rad/s^2 limit. Refused with the reason (the trajectory itself is at fault: it starts where
    the reference is not, but on time), never run with its commands limited."""
    c = core()
    event = c.load(['a', 'b'], [0.05, 1.0], [[0.02, 0.0], [0.1, 0.0]], [], [], 0.0, now=0.0)
    assert event.level == 'ERROR' and 'lead-in from the current reference' in event.message
    assert 'beyond its limit 10' in event.message
    assert c.mode == 'holding' and c.command(0.01)[1] == []
    # The same trajectory late, from a reference it was not planned from: late, to be planned again.
    late = c.load(['a', 'b'], [0.05, 1.0], [[0.02, 0.0], [0.1, 0.0]], [], [], start=-0.02, now=0.0)
    assert late.values['late'] is True and late.outcome.code == -3


def test_running_a_trajectory_of_many_points_never_imports_numba():
    """The planner's compiled samplers are the planner's: a controller that loads, checks and
    runs a trajectory of 40 points (its spline sampled at hundreds of times) must not stall its
    loop for numba's import (a second or more on a cold cache)."""
    import subprocess
    import sys
    script = '''
import sys
import numpy as np
from picking_controller.core import ControllerCore, Tolerances
c = ControllerCore(['a', 'b'], [-3, -3], [3, 3], [2, 2], [10, 10], Tolerances())
c.on_state([0.0, 0.0], [0.0, 0.0], 0.0, now=0.0)
times = np.linspace(0.5, 4.0, 40)
pos = np.stack([0.5 * np.sin(times), 0.3 * (1.0 - np.cos(times))], axis=1)
event = c.load(['a', 'b'], times, pos, [], [], 0.0, now=0.0)
assert event.level == 'OK', event.message
for t in np.linspace(0.0, 4.5, 451):
    c.reference(t)
    c.on_state(c.reference(t)[0], None, t, now=t)
print('numba' in sys.modules)
'''
    out = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == 'False'
