"""The controller's logic without ROS: the schedule spliced at the stamp, bridges, tolerances judged at the
measurement's instant, stalls, the watchdog, refusals."""

import numpy as np
import pytest

from picking_controller.core import ControllerCore, Tolerances
from picking_controller.schedule import Entry
from picking_core.trajectory import PiecewisePolynomial, hold, quintic

NAMES = ['a', 'b', 'gripper']
LIMITS = dict(vmax=[2, 2, 0.3], amax=[10, 10, 3])


def core(**tol):
    c = ControllerCore(NAMES, [-3, -3, 0], [3, 3, 0.1], LIMITS['vmax'], LIMITS['amax'], Tolerances(**tol),
                       optional=['gripper'], max_jerk=[100, 100, 30])
    c.on_state([0.0, 0.0, 0.05], [0.0, 0.0, 0.0], 0.0, now=0.0)
    return c


def run(c, t0, t1, dt=1e-3):
    """Command every ``dt`` from ``t0`` to ``t1``: the commands (t, q, qd, qdd) and every event."""
    out, events = [], []
    for t in np.arange(t0, t1, dt):
        c.advance(t)
        (q, qd, qdd), ev = c.command(t)
        out.append((t, q.copy(), qd.copy(), qdd.copy()))
        events += ev
    return out, events


def within_limits(commands):
    q = np.array([c[1] for c in commands])
    qd = np.array([c[2] for c in commands])
    qdd = np.array([c[3] for c in commands])
    assert np.all(np.abs(qd) <= np.array(LIMITS['vmax']) + 1e-9)
    assert np.all(np.abs(qdd) <= np.array(LIMITS['amax']) + 1e-6)
    steps = np.abs(np.diff(q, axis=0))
    assert np.all(steps <= np.array(LIMITS['vmax']) * 1e-3 * 1.01 + 1e-9)


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
    ev = c.load(['b', 'a'], [1.0], [[0.5, 1.0]], [], [], 0.0, now=0.0, goal='g')
    assert ev.level == 'OK', ev.message
    q, _, _ = c.reference(1.0)
    assert q == pytest.approx([1.0, 0.5, 0.05])          # reordered; gripper held
    events = c.on_state([1.0, 0.5, 0.05], [0, 0, 0], 1.1, now=1.1)
    assert events and events[0].message == 'goal reached' and events[0].goal == 'g'


def test_a_stamp_of_zero_leads_in_from_the_reference_now_to_a_later_first_point():
    """As ros2_controllers' trajectory controller: the first point's time_from_start is the time to get there
    from where the reference is; no jump in position or velocity."""
    c = core()
    c.load(['a', 'b'], [2.0], [[1.0, 0.0]], [[0.0, 0.0]], [], 0.0, now=0.0)
    now = 1.0
    before = c.reference(now)
    ev = c.load(['a', 'b'], [0.5, 1.5], [[0.8, 0.0], [0.2, 0.3]], [], [], 0.0, now=now)
    assert 'led in from the reference over 0.500 s' in ev.message
    after = c.reference(now)
    assert after[0] == pytest.approx(before[0]) and after[1] == pytest.approx(before[1])
    v = np.array([c.reference(x)[1] for x in now + np.linspace(0, 0.1, 101)])
    assert np.abs(np.diff(v, axis=0)).max() < 0.05


def test_a_trajectory_stamped_ahead_is_spliced_at_its_stamp_and_carries_on_from_the_reference_there():
    """What was scheduled before the stamp runs until then; a first point that is the reference at the stamp
    (position, velocity, acceleration) is run exactly as sent from there, no bridge."""
    c = core()
    first = quintic([0.0, 0.0], [1.0, 0.5], 2.0)
    t = np.arange(0.0, 2.0 + 1e-9, 0.01)
    assert c.load(['a', 'b'], t, *first.sample(t), 0.0, now=0.0).level == 'OK'
    t_s = 1.3                                                 # on the running plan: its state there
    q0, v0, a0 = (x[:2] for x in c.reference(t_s))
    second = quintic(q0, [0.2, 0.1], 1.0, v0=v0, a0=a0)
    ev = c.load(['a', 'b'], t[t <= 1.0], *second.sample(t[t <= 1.0]), t_s, now=1.0)
    assert 'carries on from the reference' in ev.message and ev.values['starts_in'] == pytest.approx(0.3)
    assert c.reference(1.2)[0][:2] == pytest.approx(first.state_at(1.2)[0])     # the first still runs
    assert c.reference(1.8)[0][:2] == pytest.approx(second.state_at(0.5)[0])


def test_each_trajectory_is_spliced_onto_the_whole_schedule_at_its_stamp():
    """A runs; B is stamped to take over at 1.5 s, C at 2.0 s: A runs until 1.5, B until 2.0, C after. A D
    stamped 1.8 s, before C's start, drops C (its goal ends: it never runs) and keeps B until 1.8."""
    c = core()
    c.load(['a', 'b'], [3.0], [[1.0, 0.0]], [], [], 0.0, now=0.0, goal='A')
    for name, stamp, target in (('B', 1.5, -0.5), ('C', 2.0, 0.4)):
        ev = c.load(['a', 'b'], [1.0], [[target, 0.0]], [], [], stamp, now=1.0, goal=name)
        assert ev.level == 'OK', ev.message
    assert [e.goal for e in c.schedule.entries] == ['A', 'B', 'C']
    _, events = run(c, 1.0, 1.6)
    assert c.goal == 'B' and [e.goal for e in events if e.outcome] == ['A']     # A preempted at B's start
    ev = c.load(['a', 'b'], [1.0], [[0.0, 0.2]], [], [], 1.8, now=1.6, goal='D')
    assert ev.level == 'OK'
    commands, events = run(c, 1.6, 3.0)
    ended = {e.goal: e.outcome.text for e in events if e.outcome}
    assert 'replaced it before it started' in ended['C'] and 'took over' in ended['B']
    assert c.goal == 'D'
    within_limits(commands)


def test_a_first_point_due_after_the_stamp_that_is_the_reference_then_keeps_the_schedule_until_it():
    """C is stamped 1.2 s with its first point 0.5 s later, where A (running) is then: what was scheduled from
    1.2 s (B, at 1.5 s) is dropped, A runs on until 1.7 s and C carries on from it there exactly."""
    c = core()
    first = quintic([0.0, 0.0], [1.0, 0.5], 3.0)
    t = np.arange(0.0, 3.0 + 1e-9, 0.01)
    c.load(['a', 'b'], t, *first.sample(t), 0.0, now=0.0, goal='A')
    c.load(['a', 'b'], [1.0], [[0.0, 0.0]], [], [], 1.5, now=1.0, goal='B')
    q0, v0, a0 = (x[:2] for x in first.state_at(1.7))
    second = quintic(q0, [0.5, 0.5], 1.0, v0=v0, a0=a0)
    ev = c.load(['a', 'b'], 0.5 + t[t <= 1.0], *second.sample(t[t <= 1.0]), 1.2, now=1.0, goal='C')
    assert 'carries on' in ev.message
    assert [e.goal for e in c.schedule.entries] == ['A', 'C'] and c.schedule.entries[1].start == pytest.approx(1.7)
    assert c.reference(1.6)[0][:2] == pytest.approx(first.state_at(1.6)[0])
    assert c.reference(2.2)[0][:2] == pytest.approx(second.state_at(0.5)[0])


def test_a_first_point_away_from_the_reference_is_bridged_within_the_limits_and_runs_that_much_later():
    """Stamp 0 and a first point due at once, 0.4 rad away: the fastest jerk-limited move gets there, then the
    points run as given. The feedback's time in the points is negative over the bridge."""
    c = core()
    ev = c.load(['a', 'b'], [0.0, 1.0], [[0.4, 0.0], [0.6, 0.0]], [], [], 0.0, now=0.0, goal='g')
    assert ev.level == 'OK' and 'bridged from the reference' in ev.message, ev.message
    bridge = ev.values['bridge']
    assert 0.3 < bridge < 1.5
    assert c.trajectory_time(0.1) == pytest.approx(0.1 - bridge)
    commands, _ = run(c, 0.0, bridge + 1.2)
    within_limits(commands)
    assert c.reference(bridge)[0][0] == pytest.approx(0.4, abs=1e-6)
    assert c.reference(bridge + 1.0)[0][0] == pytest.approx(0.6, abs=1e-6)


def test_a_lead_in_that_would_break_a_limit_is_bridged_instead():
    """A first point 0.05 s ahead and 0.02 rad away: the lead-in from rest over 0.05 s needs more than the
    10 rad/s^2 limit, so the reference is bridged there within the limits, never run with its commands limited."""
    c = core()
    event = c.load(['a', 'b'], [0.05, 1.0], [[0.02, 0.0], [0.1, 0.0]], [], [], 0.0, now=0.0)
    assert event.level == 'OK' and 'bridged' in event.message, event.message
    commands, events = run(c, 0.0, 1.3)
    within_limits(commands)
    assert not [e for e in events if 'limited' in e.message]


def test_a_start_already_past_is_refused_as_late():
    c = core()
    late = c.load(['a', 'b'], [0.5, 1.0], [[0.2, 0.0], [0.4, 0.0]], [], [], start=10.0, now=10.01)
    assert late.level == 'ERROR' and 'in the past' in late.message and late.values['late'] is True
    assert late.outcome.code == -3
    bad = c.load(['a', 'x'], [1.0], [[0.5, 0.5]], [], [], start=0.0, now=11.0)
    assert bad.level == 'ERROR' and 'unknown joints' in bad.message and bad.values['late'] is False
    assert bad.outcome.code == -2


def test_path_tolerance_violation_brakes_and_holds():
    c = core(path=0.05)
    c.load(['a', 'b'], [2.0], [[1.0, 0.0]], [], [], 0.0, now=0.0, goal='g')
    run(c, 0.0, 0.5)
    events = c.on_state([0.3, 0.0, 0.05], None, 0.499, now=0.5)
    assert events[0].level == 'ERROR' and 'path tolerance' in events[0].message and events[0].goal == 'g'
    assert c.mode == 'fault'
    q_end = c.reference(10.0)
    assert np.all(q_end[1] == 0)                          # at rest
    assert abs(q_end[0][0] - c.reference(0.5)[0][0]) < 0.5


def test_a_late_state_is_judged_against_the_command_of_its_own_instant():
    """A simulator whose states come 0.3 s after their stamps, tracking perfectly: no tracking error (the arm was
    where it was told to be then), but a warning that the feedback is late. A state off the command of its
    instant still aborts."""
    c = core(path=0.05)
    c.load(['a', 'b'], [2.0], [[1.0, 0.0]], [], [], 0.0, now=0.0, goal='g')
    commands, _ = run(c, 0.0, 1.0)
    then = commands[600]
    events = c.on_state(then[1], then[2], then[0], now=0.9)
    assert [e.level for e in events] == ['WARN'] and 'arrive late: 0.300 s' in events[0].message
    assert c.mode == 'moving'
    events = c.on_state(then[1] + [0.08, 0, 0], then[2], then[0], now=0.95)
    assert events[0].level == 'ERROR' and 'path tolerance' in events[0].message


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
    """A loop stalled longer than state_timeout could read no states meanwhile: the feedback is lost only if
    none comes within state_timeout after the stall."""
    c = core(state_timeout=0.2)
    c.load(['a', 'b'], [2.0], [[1.0, 0.0]], [], [], 0.0, now=0.0)
    c.advance(0.0)
    c.advance(0.5)                                            # stalled 0.5 s
    assert c.tick(0.5) == [] and c.tick(0.65) == []
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
    assert ev.level == 'OK' and 'carries on' in ev.message
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
    (['a', 'b'], [0.2, 0.3], [[0, 0], [2.0, 0]], 'between the points'),      # 20 rad/s there
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
    c = core()
    (q, qd, qdd), events = c.command(0.0)
    assert q == pytest.approx([0.0, 0.0, 0.05]) and not events
    # A reference beyond a position limit and far away (as a bug would make): limited and reported once.
    c.schedule.replace_all(Entry(0.0, hold(np.array([5.0, -1.0, 0.05]), 1.0), 0.0, kind='hold'))
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
    assert c.guard.limited > 0


def test_an_acceleration_step_between_the_points_is_limited_and_named_as_such():
    """An LSPB sampled every 10 ms: its acceleration steps between two points, where the spline through them
    overshoots the limit (the points themselves keep it)."""
    from picking_core import trajectory
    c = core()
    plan = trajectory.lspb([0.0, 0.0], [0.3, 0.0], 0.6, 9.8)        # 9.8 of the 10 rad/s^2 limit
    t = np.arange(0.0, 0.66 + 1e-9, 0.01)
    q, qd, qdd = plan.sample(t - 0.055)
    assert (0.055 + plan.blend_time[0]) % 0.01 > 1e-3               # the steps fall between two points
    assert c.load(['a', 'b'], t, q, qd, qdd, 0.0, now=0.0).level == 'OK'
    reports = []
    for now in np.arange(0.0, 0.7, 1e-3):
        (_, _, sent_qdd), events = c.command(now)
        assert np.all(np.abs(sent_qdd) <= [10, 10, 3])
        reports += events
    assert len(reports) == 1, [r.message for r in reports]
    assert 'reference of a: its acceleration' in reports[0].message and 'between the points' in reports[0].message


def test_a_stalled_tick_delays_the_schedule_instead_of_jumping_ahead():
    """A 300 ms stall: the schedule goes on 250 ms later (the first 50 ms, the stall limit, still count), the
    entry waiting for its stamp with it; the feedback's time in the points has the delay taken off (negative for the
    waiting entry's goal); once the
    arm holds with nothing scheduled the schedule's clock is the clock again."""
    c = core()
    c.load(['a', 'b'], [2.0], [[1.0, 0.0]], [[0.0, 0.0]], [], 0.0, now=0.0)
    assert c.load(['a', 'b'], [1.0], [[0.0, 0.0]], [], [], 1.2, now=0.0, goal='next').level == 'OK'
    run(c, 0.0, 0.5)
    before = c.reference(0.499)[0]
    events = c.advance(0.799)                                 # 300 ms without a tick
    assert len(events) == 1 and 'stalled for 0.300 s' in events[0].message
    assert events[0].values['delay'] == pytest.approx(0.25)
    after = c.reference(0.799)[0]
    assert np.abs(after - before).max() < 2.0 * 0.051          # within vmax of the last command, no jump
    assert c.trajectory_time(0.799) == pytest.approx(0.549)
    assert c.trajectory_time(0.799, 'next') == pytest.approx(0.549 - 1.2)   # waiting: before its points
    assert c.trajectory_time(0.799, 'another') is None
    (q, _, _), limited = c.command(0.799)
    assert limited == [] and q == pytest.approx(after)
    run(c, 0.8, 1.45)
    assert c.goal is None or c.goal != 'next'
    run(c, 1.45, 1.46)
    assert c.goal == 'next'                                   # took over at 1.2 s of the schedule, 1.45 s of the clock
    assert c.delayed == pytest.approx(0.25)
    for t in np.arange(1.46, 3.0, 0.01):
        c.advance(t)
        c.command(t)
        c.on_state(c.reference(t)[0], [0, 0, 0], t, now=t)
    assert c.mode == 'holding' and c.delay == 0.0


def test_a_state_measured_during_a_stall_is_not_judged_and_one_after_it_is():
    """A whole machine stalled: the simulator catches up and sends states stamped inside the stall, where the
    command is unknown; those are not judged. A state stamped after the stall is, against the command then."""
    c = core(path=0.05)
    c.load(['a', 'b'], [2.0], [[1.0, 0.0]], [[0.0, 0.0]], [], 0.0, now=0.0)
    run(c, 0.0, 0.5)
    c.advance(1.0)                                            # stalled
    c.command(1.0)
    assert [e for e in c.on_state([0.9, 0.0, 0.05], [0, 0, 0], 0.8, now=1.001) if e.level == 'ERROR'] == []
    events = c.on_state([0.9, 0.0, 0.05], [0, 0, 0], 1.0, now=1.002)
    assert events and events[0].level == 'ERROR' and 'path tolerance' in events[0].message


@pytest.mark.parametrize('limit', [0.0, -1.0, np.nan])
def test_stall_limit_must_be_positive(limit):
    with pytest.raises(ValueError, match='stall_limit'):
        ControllerCore(NAMES, [-3] * 3, [3] * 3, [2] * 3, [10] * 3, stall_limit=limit)


def test_a_reference_left_beyond_a_limit_still_takes_a_new_trajectory():
    """A reference a little beyond the speed limit (the command was limited): a new trajectory is spliced onto
    the state commanded, within the limits, instead of being refused for starting beyond the limit."""
    c = core()
    coeffs = np.zeros((1, 6, 3))
    coeffs[0, 1, 0], coeffs[0, 2, 0] = 2.05, 0.5          # a at 2.05 rad/s (limit 2), still speeding up
    coeffs[0, 0, 2] = 0.05
    c.schedule.replace_all(Entry(0.0, PiecewisePolynomial([0.0, 3.0], coeffs), 0.0))
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


def test_cancel_ends_a_waiting_goal_at_once_and_brakes_a_running_one():
    c = core()
    c.load(['a', 'b'], [2.0], [[1.0, 0.0]], [], [], 0.0, now=0.0, goal='run')
    c.load(['a', 'b'], [1.0], [[0.0, 0.0]], [], [], 1.5, now=0.0, goal='wait')
    ok, events = c.cancel('wait', 0.5)
    assert ok and events[0].outcome.status == 'canceled' and [e.goal for e in c.schedule.entries] == ['run']
    run(c, 0.0, 0.6)
    ok, events = c.cancel('run', 0.6)
    assert ok and 'braking' in events[0].message
    commands, _ = run(c, 0.6, 1.5)
    within_limits(commands)
    assert np.abs(commands[-1][2]).max() == 0.0
    t = 1.5
    events = c.on_state(c.reference(t)[0], [0, 0, 0], t, now=t)
    assert events[0].outcome.status == 'canceled' and events[0].goal == 'run'
    assert c.cancel('run', 1.6) == (False, [])


def test_running_a_trajectory_of_many_points_never_imports_numba():
    """A controller that loads, checks and runs a trajectory of 40 points must not stall its loop for numba's
    import (a second or more on a cold cache)."""
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
event = c.load(['a', 'b'], [0.0, 1.0], [[0.3, 0.1], [0.2, 0.0]], [], [], 0.0, now=0.1)
assert event.level == 'OK', event.message
for t in np.linspace(0.0, 4.5, 451):
    c.command(t)
    c.on_state(c.reference(t)[0], None, t, now=t)
print('numba' in sys.modules)
'''
    out = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == 'False'
