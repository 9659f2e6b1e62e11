"""The planner's goal flow without ROS: where plans start, one plan in flight, the newest goal waiting,
resends, late re-plans, re-targets, and a harvest planned again around a changed world."""

import numpy as np
import pytest
from conftest import shipped_harvest
from scipy.spatial.transform import Rotation

from picking_core.collision import World
from picking_core.collision.scene import Scene, rod
from picking_core.goals.lifecycle import ANSWER_GRACE, LATE_REPLANS, OLD_HEADER_TIMESTAMP, RESULT_RETRY
from picking_core.goals.planning import GoalPlanner
from picking_core.goals.requests import Goal, Kind, Target
from picking_core.goals.runner import STREAM_PAUSE, GoalRunner
from picking_core.goals.start import Running, Timing, choose_start
from picking_core.harvest import SIDEWAYS
from picking_core.kinematics import pose_matrix
from picking_core.moving_pick import Follow, final_approach
from picking_core.pick_cycle import HOME_POSITIONS

DOWN = Rotation.from_euler('xyz', [180, 0, 0], degrees=True).as_quat()
HOME = np.array(HOME_POSITIONS)


class Port:
    """A controller and a clock the test drives: what was sent, canceled and said."""

    def __init__(self, planner):
        self.t_wall, self.t = 0.0, 1000.0
        self.planner = planner
        self.sent, self.canceled, self.statuses, self.logs, self.asked = [], [], [], [], []
        self.why, self.ref, self.meas = None, None, (HOME.copy(), 0.09)

    def wall(self):
        return self.t_wall

    def now(self):
        return self.t

    def seconds(self, ns):
        return ns * 1e-9

    def ready(self):
        return self.why

    def reference(self):
        return self.ref

    def measured(self):
        return self.meas

    def goal_planner(self):
        return self.planner

    def send(self, flight, points, stamp):
        self.sent.append((flight, points, stamp))

    def cancel(self, flight):
        self.canceled.append(flight)

    def ask_result(self, flight):
        self.asked.append(flight)

    def status(self, level, text, **values):
        message = dict(level=level, text=text, **values)
        self.statuses.append(message)
        return message

    def repeat(self, message):
        self.statuses.append(message)

    def log(self, level, text):
        self.logs.append((level, text))

    def states(self, key):
        return [s['state'] for s in self.statuses if s.get('goal') == key]


@pytest.fixture(scope='module')
def harvest():
    return shipped_harvest()


@pytest.fixture
def port(harvest):
    cycle = harvest.cycle
    return Port(GoalPlanner(cycle.planner, cycle.s, World(cycle.arm)))


def pose_goal(key, xyz, came=0.0, **kw):
    return Goal(Kind.POSE, key, Target(Kind.POSE, (pose_matrix(xyz, DOWN),)), came, **kw)


def accept(runner, port, k=-1):
    """The controller accepts the k-th plan sent and says its schedule has it."""
    flight = port.sent[k][0]
    runner.on_response(flight, True, handle=object())
    runner.scheduled(flight)
    return flight


def test_the_first_plan_starts_from_the_measured_state_stamped_now(port):
    runner = GoalRunner(port)
    runner.take(pose_goal('g1', [0.6, 0.1, 0.4]))
    flight, points, stamp = port.sent[0]
    assert stamp == 0.0 and flight.start is None                    # from the arm at rest: "now"
    assert points[1][0] == pytest.approx(HOME) and np.abs(points[2][0]).max() == 0.0
    accept(runner, port)
    assert port.states('g1') == ['accepted']


def test_a_goal_mid_motion_starts_on_the_accepted_plan_and_is_stamped_where_it_does():
    """The plan the controller accepted runs as sent: a new goal starts at its state at t_s, stamped t_s,
    so that the controller carries on from it exactly (no guess, no bridge)."""
    from conftest import shipped_harvest as make
    cycle = make().cycle
    port = Port(GoalPlanner(cycle.planner, cycle.s, World(cycle.arm)))
    runner = GoalRunner(port, Timing(lead=0.05))
    port.ref = ((HOME, np.zeros(6), np.zeros(6)), 0.09)
    runner.take(pose_goal('g1', [0.6, 0.1, 0.4]))
    first = accept(runner, port)
    assert first.start == port.sent[0][2] > port.t                  # from the reference at rest: stamped too
    port.t += 0.5
    runner.take(pose_goal('g2', [0.55, -0.15, 0.45]))
    second, points, stamp = port.sent[1]
    assert stamp > port.t and second.start == stamp
    state = first.planned.plan.trajectory.state_at(stamp - first.start)
    assert points[1][0] == pytest.approx(state[0]) and points[2][0] == pytest.approx(state[1])
    assert np.abs(state[1]).max() > 0.1                              # the arm moves there
    assert second.extra['start'] == 'plan'


def test_from_a_moving_reference_the_plan_is_stamped_now_and_its_start_is_what_the_controller_says(port):
    """No plan of ours runs (another client's does): the plan starts from the controller's reference, stamped 0;
    the controller bridges to it and its feedback says where the plan runs, and later goals start on it."""
    runner = GoalRunner(port)
    port.ref = ((HOME, np.full(6, 0.05), np.zeros(6)), 0.09)
    runner.take(pose_goal('g1', [0.6, 0.1, 0.4]))
    flight, _, stamp = port.sent[0]
    assert stamp == 0.0 and flight.extra['start'] == 'reference'
    accept(runner, port)
    assert not runner.running.usable
    runner.on_feedback(flight, port.t + 0.2, 0.1, 0.0)              # 0.1 s into its points at 1000.2 s
    assert flight.start == pytest.approx(port.t + 0.1) and runner.running.usable
    port.t += 0.3
    runner.take(pose_goal('g2', [0.55, -0.15, 0.45]))
    assert port.sent[1][2] > port.t and port.sent[1][0].extra['start'] == 'plan'


def test_one_plan_in_flight_the_newest_goal_waits_and_an_older_waiting_one_is_superseded(port):
    runner = GoalRunner(port)
    runner.take(pose_goal('g1', [0.6, 0.1, 0.4]))
    runner.take(pose_goal('g2', [0.55, 0.1, 0.45]))
    runner.take(pose_goal('g3', [0.6, -0.1, 0.45]))
    assert len(port.sent) == 1 and port.states('g2') == ['superseded']
    accept(runner, port)                                             # the answer lets the newest go
    assert len(port.sent) == 2 and port.sent[1][0].goal.key == 'g3'


def test_a_goal_sent_again_is_answered_again_not_planned_twice(port):
    runner = GoalRunner(port)
    goal = pose_goal('1.5', [0.6, 0.1, 0.4])
    runner.take(goal, content='msg')
    accept(runner, port)
    runner.take(pose_goal('1.5', [0.6, 0.1, 0.4]), content='msg')
    assert len(port.sent) == 1 and [s['state'] for s in port.statuses] == ['accepted', 'accepted']


def test_a_goal_told_apart_before_it_is_made_is_a_resend_while_planned_and_after(port):
    """A harvest of the apples seen is made from the fruit map when it comes: a resend, found before that, is the
    harvest under way (answered again once answered), never a second harvest of what is seen by then."""
    runner = GoalRunner(port)
    first = pose_goal('2.5', [0.6, 0.1, 0.4])
    assert not runner.resent(first, 'header')
    runner.take(first)
    assert runner.resent(pose_goal('2.5', [0.55, 0.1, 0.45]), 'header')       # before the controller answered
    accept(runner, port)
    assert runner.resent(pose_goal('2.5', [0.55, 0.1, 0.45]), 'header')
    assert not runner.resent(pose_goal('2.6', [0.55, 0.1, 0.45]), 'header')   # another stamp: another goal
    assert len(port.sent) == 1 and port.states('2.5') == ['accepted', 'accepted']
    assert sum('came again' in text for _, text in port.logs) == 2


def test_a_goal_that_waits_too_long_for_the_arm_is_refused_with_the_reason(port):
    runner = GoalRunner(port)
    port.why = 'no joint_states received: the planner does not know where the arm is'
    runner.take(pose_goal('g', [0.6, 0.1, 0.4], came=0.0))
    port.t_wall = 4.0
    runner.tick()
    assert port.states('g') == []
    port.t_wall = 5.5
    runner.tick()
    assert port.states('g') == ['refused'] and 'waited 5 s' in port.statuses[-1]['text']


def test_a_plan_refused_as_late_is_planned_again_further_ahead_then_refused(port):
    runner = GoalRunner(port)
    runner.take(pose_goal('g', [0.6, 0.1, 0.4]))
    for attempt in range(LATE_REPLANS + 1):
        flight = accept(runner, port)
        runner.on_result(flight, 'aborted', OLD_HEADER_TIMESTAMP, 'it starts 0.1 s in the past')
        assert len(port.sent) == min(attempt + 2, LATE_REPLANS + 1)
    assert port.states('g')[-1] == 'refused' and 'too late 3 times' in port.statuses[-1]['text']


def test_a_plan_the_controller_does_not_answer_by_its_start_is_planned_again_and_its_late_answer_canceled(port):
    """A goal response can be lost (a DDS service drops it while the server has not yet discovered the client):
    the goal is planned again instead of waiting for an answer that may never come."""
    port.ref = ((HOME, np.zeros(6), np.zeros(6)), 0.09)              # stamped: it starts from the reference
    runner = GoalRunner(port)
    runner.take(pose_goal('g', [0.6, 0.1, 0.4]))
    lost, _, stamp = port.sent[-1]
    assert stamp > 0
    port.t = stamp + ANSWER_GRACE + 0.1
    runner.tick()
    again, _, _ = port.sent[-1]
    assert len(port.sent) == 2 and again.goal.key == 'g' and again.goal.attempt == 1
    assert any('did not answer the plan' in text for level, text in port.logs if level == 'WARN')
    runner.on_response(lost, True, handle=object())                 # it came after all: no longer ours
    assert port.canceled == [lost]
    runner.on_response(again, True, handle=object())
    runner.on_result(again, 'succeeded', 0, '')
    assert port.states('g')[-1] == 'succeeded' and port.states('g').count('succeeded') == 1


def test_a_result_overdue_is_asked_for_again_every_second_until_it_comes(port):
    """A result response can be lost like a goal response: past the plan's end the result is asked for again,
    once a second, and the goal ends with the first that comes."""
    port.ref = ((HOME, np.zeros(6), np.zeros(6)), 0.09)
    runner = GoalRunner(port)
    runner.take(pose_goal('g', [0.6, 0.1, 0.4]))
    flight = accept(runner, port)
    end = flight.start + flight.duration
    port.t, port.t_wall = end + 0.5, 5.0
    runner.tick()
    assert port.asked == []                                         # not yet overdue
    for wall in (6.0, 6.5, 7.1):
        port.t, port.t_wall = end + RESULT_RETRY + 0.1 + (wall - 6.0), wall
        runner.tick()
    assert port.asked == [flight, flight]                            # at 6.0 and 7.1, not at 6.5
    runner.on_result(flight, 'succeeded', 0, '')
    runner.on_result(flight, 'succeeded', 0, '')                    # the second answer ends nothing
    assert port.states('g').count('succeeded') == 1


def test_retargets_move_the_running_goal_and_the_newest_wins_while_one_is_planned(port):
    runner = GoalRunner(port)
    runner.take(pose_goal('g', [0.6, 0.1, 0.4]))
    first = accept(runner, port)
    for k in range(3):                                               # a stream: the plan before is answered each time
        assert runner.retarget(pose_matrix([0.6, 0.1 + 0.01 * (k + 1), 0.4], DOWN), 0.1 * k) is None
        accept(runner, port)
    assert [f.goal.key for f, _, _ in port.sent] == ['g'] * 4 and runner.retargets['spliced'] == 3
    runner.retarget(pose_matrix([0.6, 0.2, 0.4], DOWN), 1.0)        # sent, not answered yet
    runner.retarget(pose_matrix([0.6, 0.21, 0.4], DOWN), 1.1)       # waits ...
    runner.retarget(pose_matrix([0.6, 0.22, 0.4], DOWN), 1.2)       # ... and is replaced by the newest
    assert runner.retargets['replaced'] == 1
    accept(runner, port)
    newest = port.sent[-1][0]
    assert newest.goal.target.pose[:3, 3] == pytest.approx([0.6, 0.22, 0.4]) and newest.goal.retargets == 6
    runner.on_result(first, 'aborted', -1, 'preempted')              # an older plan's end ends nothing
    runner.on_response(newest, True, handle=object())
    runner.on_result(newest, 'succeeded', 0, '')
    assert 'succeeded' not in port.states('g')                      # at rest at its target, open for the stream
    port.t_wall += STREAM_PAUSE
    runner.tick()
    assert port.states('g').count('succeeded') == 1 and 'aborted' not in port.states('g')
    end = port.statuses[-1]
    assert [end[f'retargets_{k}'] for k in ('received', 'spliced', 'replaced', 'refused')] == [6, 5, 1, 0]


def test_a_retarget_waits_for_the_schedule_to_have_the_plan_before_and_never_starts_from_one_refused_late(port):
    """A goal the controller accepted may still be refused as late (its stamp past when it came to be spliced):
    the next re-target is planned only once the controller says its schedule has the plan before it. Planned from
    a plan that never ran, it would not carry on from the schedule: the controller would bridge it, and it would
    run that much later (a swaying apple's fingers closing centimetres off)."""
    runner = GoalRunner(port, Timing(lead=0.05))
    port.ref = ((HOME, np.zeros(6), np.zeros(6)), 0.09)
    runner.take(pose_goal('g', [0.6, 0.1, 0.4]))
    first = accept(runner, port)
    port.t += 0.5
    assert runner.retarget(pose_matrix([0.6, 0.12, 0.4], DOWN), 0.1) is None
    late = port.sent[-1][0]
    runner.on_response(late, True, handle=object())             # accepted; the word on its stamp still to come
    assert runner.retarget(pose_matrix([0.6, 0.14, 0.4], DOWN), 0.2) is None
    assert port.sent[-1][0] is late and runner.blocked()        # it waits
    runner.on_result(late, 'aborted', OLD_HEADER_TIMESTAMP, 'it starts 0.01 s in the past')
    again, points, stamp = port.sent[-1]
    assert again is not late and again.start == stamp
    state = first.planned.plan.trajectory.state_at(stamp - first.start)  # from the plan that runs
    assert points[1][0] == pytest.approx(state[0]) and points[2][0] == pytest.approx(state[1])
    runner.on_response(again, True, handle=object())
    assert port.sent[-1][0] is again
    runner.on_feedback(again, port.t, port.t - again.start, 0.0)   # waiting on the schedule for its start
    newest, points, stamp = port.sent[-1]
    assert newest.goal.target.pose[:3, 3] == pytest.approx([0.6, 0.14, 0.4])
    state = again.planned.plan.trajectory.state_at(stamp - again.start)
    assert points[1][0] == pytest.approx(state[0]) and points[2][0] == pytest.approx(state[1])
    assert 'executing' not in port.states('g')


def test_a_retargeted_goal_at_rest_waits_for_its_stream_then_ends(port):
    """A stream of re-targets that pauses (the arm reaches the last target meanwhile) moves the same goal on when
    it resumes within STREAM_PAUSE; after a longer pause the goal ends succeeded; a new goal or a cancel ends it at
    once."""
    runner = GoalRunner(port)
    runner.take(pose_goal('g', [0.6, 0.1, 0.4]))
    accept(runner, port)
    assert runner.retarget(pose_matrix([0.6, 0.12, 0.4], DOWN), port.wall()) is None
    moved = accept(runner, port)
    runner.on_result(moved, 'succeeded', 0, '')
    port.t_wall += 0.9 * STREAM_PAUSE
    runner.tick()
    assert 'succeeded' not in port.states('g')
    assert runner.retarget(pose_matrix([0.6, 0.14, 0.4], DOWN), port.wall()) is None   # the stream resumes
    again = accept(runner, port)
    assert again.goal.key == 'g' and again.goal.retargets == 2
    runner.on_result(again, 'succeeded', 0, '')
    port.t_wall += STREAM_PAUSE
    runner.tick()
    assert port.states('g').count('succeeded') == 1
    assert port.statuses[-1]['retargets_received'] == 2
    assert runner.retarget(np.eye(4), port.wall()) == 'no pose or pick goal runs to move'
    # A new goal ends a goal at rest at once; so does a cancel.
    for stop in ('new goal', 'cancel'):
        key = f'h{stop[0]}'
        runner.take(pose_goal(key, [0.6, 0.1, 0.4]))
        accept(runner, port)
        runner.retarget(pose_matrix([0.6, 0.12, 0.4], DOWN), port.wall())
        runner.on_result(accept(runner, port), 'succeeded', 0, '')
        if stop == 'cancel':
            assert runner.cancel(key) and port.states(key)[-1] == 'canceled'
        else:
            runner.take(pose_goal('other', [0.6, 0.0, 0.4]))
            assert port.states(key)[-1] == 'succeeded'
            runner.on_result(accept(runner, port), 'succeeded', 0, '')


def test_without_a_running_goal_a_retarget_is_not_taken(port):
    assert GoalRunner(port).retarget(np.eye(4), 0.0) == 'no pose or pick goal runs to move'


def test_a_start_from_a_plan_that_ended_badly_comes_from_the_reference():
    traj = shipped_harvest().cycle.planner.plan_pose((HOME, np.zeros(6), np.zeros(6)),
                                                      pose_matrix([0.6, 0.1, 0.4], DOWN)).trajectory
    running = Running(traj, tuple('abcdef'), 10.0, 1, 6)
    ref = ((HOME + 0.1, np.full(6, 0.2), np.zeros(6)), 0.05)
    assert choose_start(running, 10.5, ref, None).source == 'plan'
    assert choose_start(Running(traj, tuple('abcdef'), 10.0, 1, 6, 'aborted'), 10.5, ref, None).source == 'reference'
    # A plan that succeeded holds its end, unless another client moved the arm since.
    done = Running(traj, tuple('abcdef'), 10.0, 1, 6, 'succeeded')
    at_end = ((traj.end_state()[0], np.zeros(6), np.zeros(6)), 0.05)
    assert choose_start(done, 20.0, at_end, None).source == 'plan'
    assert choose_start(done, 20.0, ref, None).source == 'reference'
    assert choose_start(None, 20.0, None, (HOME, 0.09)).source == 'measured'


def test_a_pose_goal_whose_rest_a_new_obstacle_blocks_is_stopped(port):
    runner = GoalRunner(port)
    runner.take(pose_goal('g', [0.6, 0.1, 0.4]))
    flight = accept(runner, port)
    runner.on_feedback(flight, port.t, 0.0, 0.0)
    end = port.planner.planner.arm.fk(flight.planned.plan.trajectory.end_state()[0][:6])[:3, 3]
    port.planner.world.replace(scene=Scene((rod('post', 'branch', end - [0, 0, 0.3], end + [0, 0, 0.3], 0.03),)))
    runner.world_changed()
    assert port.canceled == [flight] and 'world changed' in flight.stopped
    runner.on_result(flight, 'canceled', 0, '')
    assert port.states('g')[-1] == 'aborted' and 'stopped' in port.statuses[-1]['text']


def test_a_harvest_whose_later_apples_a_new_obstacle_blocks_is_planned_again_as_the_same_goal(port):
    """A branch appears across the last apples while the first is in hand: the rest is planned again from the
    box after the apple in hand, stamped where that apple is in the box, as the same goal; each apple counts
    once and the old plan's end ends nothing."""
    runner = GoalRunner(port)
    R = Rotation.from_euler('xyz', SIDEWAYS).as_matrix()
    apples = [np.block([[R, np.array([[0.7], [y], [0.6]])], [np.zeros((1, 3)), np.ones((1, 1))]]) for y in (0.15, 0.3, 0.45)]
    runner.take(Goal(Kind.HARVEST, 'h', Target(Kind.HARVEST, tuple(apples)), 0.0))
    flight = accept(runner, port)
    runner.on_feedback(flight, port.t, 0.0, 0.0)
    plan = flight.planned.harvest
    last = plan.apples[-1]
    where = apples[last.index][:3, 3] - [0.06, 0.0, 0.0]              # across its approach
    port.planner.world.replace(scene=Scene((rod('new branch', 'branch', where - [0, 0.03, 0], where + [0, 0.03, 0],
                                                0.008),)))
    port.t = flight.start + 0.5 * plan.apples[0].end
    runner.world_changed()
    assert 'replanned' in port.states('h')
    rest, points, stamp = port.sent[-1]
    assert rest.goal.key == 'h' and stamp == pytest.approx(flight.start + plan.apples[0].end)
    redone = rest.planned.harvest
    assert sorted([a.index for a in redone.apples] + [s.index for s in redone.skipped]) == sorted(
        a.index for a in plan.apples[1:])                            # the apples not started, each once
    assert port.planner.world.check(redone.plan.trajectory, list(rest.planned.regions)) is None
    accept(runner, port)
    runner.on_result(flight, 'aborted', -1, 'preempted: a newer trajectory took over from it')
    assert port.states('h').count('aborted') == 0
    port.t = stamp + rest.planned.plan.duration + 1.0
    runner.tick()
    runner.on_result(rest, 'succeeded', 0, '')
    picked = [s['apple'] for s in port.statuses if s.get('apple_state') == 'picked']
    assert len(picked) == len(set(picked)) and plan.apples[0].index in picked
    # Each apple's status says where it was (the rest's goal keeps the apples' indices in the first).
    for s in port.statuses:
        if s.get('apple_state') in ('picked', 'skipped'):
            assert np.allclose([s['x'], s['y'], s['z']], apples[s['apple']][:3, 3])
    assert port.statuses[-1]['state'] == 'succeeded' and port.statuses[-1]['planned'] == len(apples) - len(
        rest.planned.harvest.skipped) - len(plan.skipped)


def test_an_apple_the_fingers_were_measured_holding_is_picked_and_one_they_closed_on_air_is_missed(port):
    """The planner claims an apple only as the measured gripper shows it: fingers resting on an apple's width
    while they carry it are a pick; fingers closed to their closed opening held nothing (a knocked-off apple,
    a closing beside one), and that apple is missed, with why, not counted."""
    runner = GoalRunner(port)
    R = Rotation.from_euler('xyz', SIDEWAYS).as_matrix()
    apples = [np.block([[R, np.array([[0.7], [y], [0.6]])], [np.zeros((1, 3)), np.ones((1, 1))]]) for y in (0.1, 0.3)]
    runner.take(Goal(Kind.HARVEST, 'h', Target(Kind.HARVEST, tuple(apples)), 0.0))
    flight = accept(runner, port)
    runner.on_feedback(flight, port.t, 0.0, 0.0)
    plan = flight.planned.harvest
    closed = shipped_harvest().cycle.s.gripper_closed
    # The first read closed for a moment as the fingers settled on it; the second was lost on the way.
    for apple, openings in zip(plan.apples, ((closed, 0.075, 0.075, 0.075, 0.075),
                                             (0.075, 0.075, closed + 0.0005, closed + 0.0005, closed + 0.0005))):
        for s, opening in zip(np.linspace(apple.held[0] + 0.15, apple.held[1], 5), openings):
            port.t, port.meas = flight.start + s, (HOME.copy(), opening)
            runner.tick()
    port.t = flight.start + plan.plan.duration + 0.5
    runner.tick()
    runner.on_result(flight, 'succeeded', 0, '')
    said = {s['apple']: s for s in port.statuses if s.get('apple_state')}
    first, second = (said[a.index] for a in plan.apples)
    assert first['apple_state'] == 'picked' and first['verified'] is True
    assert second['apple_state'] == 'missed' and 'held nothing' in second['text'] and second['level'] == 'WARN'
    final = port.statuses[-1]
    assert final['state'] == 'succeeded' and final['picked'] == 1 and final['missed'] == 1
    assert final['picked_apples'] == str(plan.apples[0].index) and final['missed_apples'] == str(plan.apples[1].index)
    assert '1 missed' in final['text']


def _swaying(t):
    """A pick's apple swaying ±30 mm at 1 Hz across the approach (along y)."""
    return np.array([0.70, 0.15 + 0.03 * np.sin(2 * np.pi * t), 0.65])


def _pick_at(key, t, came=0.0):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = Rotation.from_euler('xyz', SIDEWAYS).as_matrix(), _swaying(t)
    return Goal(Kind.PICK, key, Target(Kind.PICK, (T,)), came, stamp=f'{t:.9f}')


def _streamed(port, frames, missing=()):
    """A pick of the swaying apple, then its places sent on the topic at 30 Hz for ``frames`` frames (none in
    ``missing``: the camera out), the controller taking each plan: the runner and its plans aimed at the sway."""
    runner = GoalRunner(port)
    runner.take(_pick_at('p', port.t))
    flight = accept(runner, port)
    runner.on_feedback(flight, port.t, 0.0, 0.0)
    for k in range(1, frames + 1):
        port.t += 1 / 30
        port.t_wall += 1 / 30
        if k not in missing:
            runner.take(_pick_at(f'q{k}', port.t, came=port.t_wall))
        if port.sent[-1][0] is not flight:
            flight = accept(runner, port)
        runner.on_feedback(flight, port.t, port.t - flight.start if flight.start else 0.0, 0.0)
    return runner, [f for f, _, _ in port.sent if 'closes_in' in f.planned.plan.extra]


def _closing_miss(port, flight):
    """m from the tool to the apple when ``flight``'s plan closes the fingers."""
    closes = flight.start + flight.planned.plan.extra['closes_in']
    arm = port.planner.planner.arm
    q = flight.planned.plan.trajectory.sample([closes - flight.start])[0][0]
    return float(np.linalg.norm(arm.fk(q[:arm.dof])[:3, 3] - _swaying(closes)))


def test_a_pick_whose_apple_streams_in_on_the_topic_is_aimed_where_it_will_be_at_closing(port):
    """Picks of the same apple sent on the topic at 30 Hz (its places, stamped) move the first pick on; once its
    places show a sway, each plan closes the fingers where the apple will be then (sure of it: it never waits)."""
    runner, aimed = _streamed(port, 30)
    assert 'holding' not in port.states('p')
    assert all(s == 'superseded' for k in range(1, 31) for s in port.states(f'q{k}'))
    assert 'taken as its new target' in [s for s in port.statuses if s.get('goal') == 'q30'][-1]['text']
    assert aimed and all(f.goal.key == 'p' for f, _, _ in port.sent)
    assert _closing_miss(port, aimed[-1]) < 0.004                        # where the apple will be then
    counts = runner._moves['p']
    # Each place ends one way (how many of each depends on how long planning takes here, which sets the starts).
    assert counts['received'] == 30 and sum(counts[k] for k in ('spliced', 'replaced', 'held', 'refused')) == 30, \
        (counts, [t[:200] for _, t in port.logs if 'refused' in t])


def test_a_pick_never_sure_of_its_swaying_apple_waits_at_the_stand_off_then_backs_off_without_closing(port):
    """Places 25 mm to either side of the sway at random, across the fingers (a poor camera, gusts): no aim is sure,
    so the pick goes to the stand-off and waits there, aimed again at each place; when the pick cycle's hold_time has
    passed it backs off home and the goal ends aborted, saying why. Once its places tell how it moves, no plan
    closes the fingers."""
    rng = np.random.default_rng(3)
    runner = GoalRunner(port)
    runner.take(_pick_at('p', port.t))
    flight = accept(runner, port)
    runner.on_feedback(flight, port.t, 0.0, 0.0)
    for _ in range(60):
        port.t += 1 / 30
        port.t_wall += 1 / 30
        T = _pick_at('x', port.t).target.pose.copy()
        T[1, 3] += rng.choice([-0.025, 0.025])
        runner.retarget(T, port.t_wall, f'{port.t:.9f}')
        if port.sent[-1][0] is not flight:
            flight = accept(runner, port)
    plans = [f.planned.plan.extra for f, _, _ in port.sent]
    first = next(k for k, x in enumerate(plans) if 'holds' in x)      # once the places tell how it moves
    assert first < len(plans) - 10 and all('holds' in x and 'closes_in' not in x for x in plans[first:])
    assert 'holding' in port.states('p') and port.states('p').count('holding') == 1
    hold = port.planner.pick.hold_time
    runner.on_result(flight, 'succeeded', 0, '')                 # at rest at the stand-off: the goal goes on
    assert port.states('p')[-1] != 'aborted'
    port.t_wall += hold
    runner.tick()
    backing = accept(runner, port)
    assert backing.goal.target.back_off and backing.planned.plan.segments[-1].label == 'P0 back off'
    q_end = backing.planned.plan.trajectory.sample([backing.planned.plan.duration])[0][0]
    assert q_end == pytest.approx(HOME, abs=1e-6)
    assert 'backs off' in runner.retarget(T, port.t_wall, f'{port.t:.9f}')  # a place now moves nothing
    runner.on_result(backing, 'succeeded', 0, '')
    assert port.states('p')[-1] == 'aborted'
    assert 'backed off home without closing' in port.statuses[-1]['text']


def test_a_pick_that_went_on_and_came_back_to_the_stand_off_waits_only_what_was_left_of_its_hold(port):
    """Places first 35 mm to either side of the sway at random (the pick waits at the stand-off), then on the sway
    (an aim is sure: it goes on), then at random again before its straight approach (back to the stand-off): the
    hold_time counts from its first wait, so it backs off home then, not a whole hold_time after it came back."""
    rng = np.random.default_rng(3)
    runner = GoalRunner(port)
    runner.take(_pick_at('p', port.t))
    flight = accept(runner, port)
    runner.on_feedback(flight, port.t, 0.0, 0.0)
    plans = []
    for k in range(150):
        port.t += 1 / 30
        port.t_wall += 1 / 30
        T = _pick_at('x', port.t).target.pose.copy()
        if k < 36 or k >= 75:
            T[1, 3] += rng.choice([-0.035, 0.035])
        runner.retarget(T, port.t_wall, f'{port.t:.9f}')
        if port.sent[-1][0] is not flight:
            flight = accept(runner, port)
        runner.on_feedback(flight, port.t, port.t - flight.start if flight.start else 0.0, 0.0)
        runner.tick()
        extra = flight.planned.plan.extra
        plans.append((port.t_wall, 'back off' if flight.goal.target.back_off else 'holds' if 'holds' in extra else
                      'closes' if 'closes_in' in extra else 'aims'))
    changes = [plans[0]] + [b for a, b in zip(plans, plans[1:]) if a[1] != b[1]]
    # (An early plan whose straight approach is still far off may close before the first wait: it is not judged.)
    assert [c[1] for c in changes][-4:] == ['holds', 'closes', 'holds', 'back off'], changes
    first, back = next(t for t, kind in changes if kind == 'holds'), changes[-2][0]
    hold = port.planner.pick.hold_time
    assert first + hold <= changes[-1][0] <= first + hold + 0.15 < back + hold
    said = [s['text'] for s in port.statuses if s.get('goal') == 'p' and s['state'] == 'holding']
    assert len(said) == 2 and f'up to {hold:g} s' in said[0] and f'up to {hold:g} s' not in said[1], said


@pytest.mark.parametrize('way', ['topic', 'retarget'])
def test_places_of_a_picks_apple_passed_over_in_a_burst_still_tell_how_it_sways(port, way):
    """A second of the apple's places came while the planner was busy (on pick_target, or on retarget): only the
    newest is planned, but each older one is a place of the apple all the same, so the newest's plan is already
    aimed at the sway. Another goal passed over is superseded as before."""
    runner = GoalRunner(port)
    runner.take(_pick_at('p', port.t))
    accept(runner, port)
    for k in range(1, 31):
        port.t += 1 / 30
        port.t_wall += 1 / 30
        if way == 'topic':
            runner.passed_over(_pick_at(f'q{k}', port.t, came=port.t_wall))
        else:
            runner.replaced(_pick_at('x', port.t).target.pose, f'{port.t:.9f}')
    assert all('a place of it taken' in s['text'] for s in port.statuses if s.get('goal', '').startswith('q'))
    port.t += 1 / 30
    runner.take(_pick_at('q31', port.t, came=port.t_wall))
    assert 'closes_in' in accept(runner, port).planned.plan.extra
    runner.passed_over(pose_goal('g', [0.6, 0.1, 0.4]))
    assert port.statuses[-1]['state'] == 'superseded' and 'a newer goal came' in port.statuses[-1]['text']


def test_a_camera_out_for_half_a_second_leaves_the_pick_aimed(port):
    """No place for 0.5 s mid-approach, once the pick is aimed at the sway: it runs on as aimed and closes where the
    apple will be; the places after the gap find its straight approach begun (the aim holds)."""
    _, aimed = _streamed(port, 60, missing=range(27, 42))
    assert aimed and _closing_miss(port, aimed[-1]) < 0.004
    assert 'straight approach' in [s for s in port.statuses if s.get('goal') == 'q60'][-1]['text']


def test_a_picks_places_out_of_order_ahead_of_the_clock_or_jumping_are_refused_with_the_reason(port):
    runner = GoalRunner(port)
    runner.take(_pick_at('p', port.t))
    flight = accept(runner, port)
    runner.on_feedback(flight, port.t, 0.0, 0.0)
    for k in range(1, 31):                                          # a second of a steady sway: fitted
        port.t += 1 / 30
        assert runner.retarget(_pick_at('x', port.t).target.pose, port.t_wall, f'{port.t:.9f}') is None
        if port.sent[-1][0] is not flight:
            flight = accept(runner, port)
    sent = len(port.sent)
    older = runner.retarget(_pick_at('x', port.t - 0.2).target.pose, port.t_wall, f'{port.t - 0.2:.9f}')
    assert 'out of order' in older
    ahead = runner.retarget(_pick_at('x', port.t + 1.0).target.pose, port.t_wall, f'{port.t + 1.0:.9f}')
    assert 'ahead of the clock' in ahead
    T = _pick_at('x', port.t + 0.01).target.pose.copy()
    T[1, 3] += 0.08                                                 # another apple, 8 cm off the sway
    assert 'jumps 8' in runner.retarget(T, port.t_wall, f'{port.t + 0.01:.9f}')
    assert len(port.sent) == sent and runner._moves['p']['refused'] == 3
    # The same on the topic: a place of the running apple stamped out of order is refused, not taken.
    late = _pick_at('late', port.t - 0.3)
    late.target.poses[0][:3, 3] = runner._picks['p'].fit.newest
    runner.take(late)
    assert port.states('late') == ['refused'] and 'out of order' in port.statuses[-1]['text']
    ahead_goal = _pick_at('ahead', 0.0)
    ahead_goal.stamp = f'{port.t + 5.0:.9f}'
    runner.take(ahead_goal)
    assert port.states('ahead') == ['refused'] and 'ahead of the clock' in port.statuses[-1]['text']



def _camera(runner, port, seconds, where, rng, neighbour=(0.70, 0.30, 0.65)):
    """The camera's frames at 30 Hz for ``seconds``: the apple (8 cm wide) at ``where(t)`` and a still neighbour
    (7 cm), 3 mm noise."""
    for _ in range(int(seconds * 30)):
        port.t += 1 / 30
        port.t_wall += 1 / 30
        places = np.array([where(port.t), neighbour]) + rng.normal(0.0, 0.003, (2, 3))
        runner.seen(places, [0.08, 0.07] + rng.normal(0.0, 0.003, 2), f'{port.t:.9f}')
        if port.sent and port.sent[-1][0].state.name == 'SENT':
            accept(runner, port)


def test_a_pick_of_a_swaying_apple_the_camera_sees_is_aimed_from_its_first_plan_and_follows_it(port):
    """The camera watched the apple sway before the pick came (sent where it hangs at rest, unstamped): its
    frames fit the sway at once, so the first plan already closes the fingers where the apple will be; the
    frames during the pick move it on, as a stream of its places on the topic would."""
    rng = np.random.default_rng(1)
    runner = GoalRunner(port)
    _camera(runner, port, 2.0, _swaying, rng)
    assert not port.sent                                             # frames alone move nothing
    T = _pick_at('p', 0.0).target.pose.copy()
    T[:3, 3] = (0.70, 0.15, 0.65)
    runner.take(Goal(Kind.PICK, 'p', Target(Kind.PICK, (T,)), port.t_wall))
    first = accept(runner, port)
    # (The fingers are timed to meet the width the camera sees, not a typical apple's.)
    assert 'closes_in' in first.planned.plan.extra and first.goal.target.follow.width == pytest.approx(0.08, abs=2e-3)
    # (Stamped 0, from the controller's reference: it starts when planned to, as its feedback then says.)
    port.t = runner._picks['p'].closes - first.planned.plan.extra['closes_in']
    runner.on_feedback(first, port.t, 0.0, 0.0)
    assert _closing_miss(port, first) < 0.005
    _camera(runner, port, 0.5, _swaying, rng)
    assert runner._moves['p']['received'] >= 10 and all(f.goal.key == 'p' for f, _, _ in port.sent)
    assert _closing_miss(port, port.sent[-1][0]) < 0.005


def test_a_pick_of_a_still_apple_the_camera_sees_keeps_the_plan_it_was_sent(port):
    rng = np.random.default_rng(2)
    runner = GoalRunner(port)
    _camera(runner, port, 2.0, lambda t: np.array([0.70, 0.15, 0.65]), rng)
    T = _pick_at('p', 0.0).target.pose.copy()
    T[:3, 3] = (0.70, 0.15, 0.65)
    runner.take(Goal(Kind.PICK, 'p', Target(Kind.PICK, (T,)), port.t_wall))
    first = accept(runner, port)
    runner.on_feedback(first, port.t, 0.0, 0.0)
    _camera(runner, port, 0.5, lambda t: np.array([0.70, 0.15, 0.65]), rng)
    assert len(port.sent) == 1 and 'closes_in' not in first.planned.plan.extra and 'p' not in runner._moves
    arm, grasp = port.planner.planner.arm, first.planned.plan.extra['grasp_start']
    assert arm.fk(first.planned.plan.trajectory.sample([grasp])[0][0][:arm.dof])[:3, 3] == pytest.approx(T[:3, 3],
                                                                                                    abs=1e-6)


def _late_re_aim(port):
    """A swaying apple's pick re-targeted frame by frame into its approach: the runner, its newest plan (sent, not
    yet refused) and the accepted plan that one takes over from."""
    rng = np.random.default_rng(4)
    runner = GoalRunner(port)
    _camera(runner, port, 2.0, _swaying, rng)
    T = _pick_at('p', 0.0).target.pose.copy()
    T[:3, 3] = (0.70, 0.15, 0.65)
    runner.take(Goal(Kind.PICK, 'p', Target(Kind.PICK, (T,)), port.t_wall))
    first = accept(runner, port)
    port.t = runner._picks['p'].closes - first.planned.plan.extra['closes_in']
    runner.on_feedback(first, port.t, 0.0, 0.0)
    for _ in range(24):                                         # into the approach, re-targeted frame by frame
        _camera(runner, port, 1 / 30, _swaying, rng)
        runner.on_feedback(port.sent[-1][0], port.t, port.t - first.start, 0.0)
    late = port.sent[-1][0]
    before = late.replaces
    assert before is not None and before.handle is not None and before is not late
    return runner, late, before


def test_a_moving_picks_re_plan_that_came_too_late_leaves_the_plan_before_it_running_as_the_picks(port):
    """A re-target's plan the controller refused as late (its stamp past) never ran: the plan before it runs on,
    and the pick is again that plan's (its closing instant kept, not aimed afresh with the fingers opened on the
    tree); the pick is aimed again from it, and it ends when that plan does."""
    runner, late, before = _late_re_aim(port)
    closes = before.start + before.planned.plan.extra['closes_in']
    sent, held = len(port.sent), runner._moves['p']['held']
    runner.on_result(late, 'aborted', OLD_HEADER_TIMESTAMP, 'it starts 0.004 s in the past')
    # Aimed again from the plan that runs, whose closing is sure: held, nothing new sent.
    assert len(port.sent) == sent and runner._moves['p']['held'] == held + 1
    assert runner.lifecycle.flights['p'] is before and not before.overtaken
    assert runner._picks['p'].closes == pytest.approx(closes)
    runner.on_result(before, 'succeeded', 0, '')
    assert port.states('p')[-1] == 'succeeded'


def test_a_moving_picks_re_plan_refused_once_the_older_plans_straight_approach_began_is_not_planned_again(port):
    """The refusal of a late re-aim comes after the plan before it has closed the fingers (the planner learned of it
    late, as in CI): a new plan would back out of the approach and open them, so none is made; that plan carries
    the apple on to the box."""
    runner, late, before = _late_re_aim(port)
    port.t = before.start + before.planned.plan.extra["closes_in"] + 0.05
    sent = len(port.sent)
    runner.on_result(late, 'aborted', OLD_HEADER_TIMESTAMP, 'it starts 0.004 s in the past')
    assert len(port.sent) == sent and runner.lifecycle.flights['p'] is before
    runner.on_result(before, 'succeeded', 0, '')
    assert port.states('p')[-1] == 'succeeded'


def test_a_re_target_the_controller_rejected_leaves_the_plan_before_it_running(port):
    """A pose goal re-targeted mid-motion whose new plan the controller rejects: the plan before it runs on and
    still answers for the goal, which ends when that plan does."""
    runner = GoalRunner(port)
    runner.take(pose_goal('g', [0.6, 0.1, 0.4]))
    first = accept(runner, port)
    runner.on_feedback(first, port.t, 0.0, 0.0)
    port.t += 0.2
    assert runner.retarget(pose_matrix([0.6, 0.15, 0.4], DOWN), port.t_wall) is None
    second = port.sent[-1][0]
    assert second is not first and second.replaces is first
    runner.on_response(second, False)
    assert runner.lifecycle.flights['g'] is first
    runner.on_result(first, 'succeeded', 0, '')
    assert port.states('g')[-1] == 'succeeded'


EMPTY = None                                      # the fingers at their closed opening: nothing between them


@pytest.mark.parametrize('held, outcome', [
    ((0.075,) * 5, 'succeeded'),
    ((EMPTY,) * 5, 'aborted'),
    ((EMPTY, EMPTY, 0.075, 0.075, 0.075), 'succeeded'),     # a dip as they settled on it (a late contact)
    ((0.075, 0.075, 0.075, EMPTY, EMPTY), 'aborted'),       # the apple slipped out on the way
])
def test_a_pick_succeeds_only_when_the_measured_fingers_carried_its_apple(port, held, outcome):
    """Fingers resting on the apple's width at the end of the carry: the pick succeeded, even if they read closed
    for a moment as they settled; closed to their closed opening then (a closing beside the apple, an apple
    knocked off or lost on the way) they held nothing, and the pick ends aborted saying so."""
    runner = GoalRunner(port)
    runner.take(_pick_at('p', port.t))
    flight = accept(runner, port)
    runner.on_feedback(flight, port.t, 0.0, 0.0)
    extra, closed = flight.planned.plan.extra, port.planner.pick.gripper_closed
    for s, opening in zip(np.linspace(extra['grasp_end'] + 0.15, extra['release_start'], 5), held):
        port.t, port.meas = flight.start + s, (HOME.copy(), opening or closed + 0.0005)
        runner.tick()
    runner.on_result(flight, 'succeeded', 0, '')
    assert port.states('p')[-1] == outcome
    assert (outcome == 'aborted') == ('not in the fingers' in port.statuses[-1]['text'])


def _seen_harvest(runner, port, ys=(0.15, 0.3)):
    R = Rotation.from_euler('xyz', SIDEWAYS).as_matrix()
    apples = [np.block([[R, np.array([[0.7], [y], [0.6]])], [np.zeros((1, 3)), np.ones((1, 1))]]) for y in ys]
    runner.take(Goal(Kind.HARVEST, 'h', Target(Kind.HARVEST, tuple(apples), seen=True), 0.0))
    flight = accept(runner, port)
    runner.on_feedback(flight, port.t, 0.0, 0.0)
    return apples, flight


def test_an_apple_seen_while_a_harvest_of_the_apples_seen_runs_joins_it_as_the_same_goal(port):
    """The camera shows an apple the arm hid at home once the arm is away: it joins the apples not started,
    planned again from the box after the apple in hand; the apples the harvest knows are never taken in twice."""
    runner = GoalRunner(port)
    apples, flight = _seen_harvest(runner, port)
    plan = flight.planned.harvest
    port.t = flight.start + 0.5 * plan.apples[0].end
    new = apples[0].copy()
    new[:3, 3] = [0.65, 0.0, 0.55]
    # The apples it has (seen again, a few millimetres off) are no new ones.
    again = [T.copy() for T in apples]
    again[0][:3, 3] += 0.004
    assert runner.seen_more(again) == 0 and len(port.sent) == 1
    assert runner.seen_more([*again, new]) == 1
    assert 'replanned' in port.states('h')
    rest, _, stamp = port.sent[-1]
    assert rest.goal.key == 'h' and stamp == pytest.approx(flight.start + plan.apples[0].end)
    redone = rest.planned.harvest
    later = sorted(a.index for a in plan.apples[1:])
    assert sorted([a.index for a in redone.apples] + [s.index for s in redone.skipped]) == sorted([*later, 2])
    assert runner.seen_more([*again, new]) == 0                        # taken in once, even before it is accepted
    accept(runner, port)
    runner.on_result(flight, 'aborted', -1, 'preempted: a newer trajectory took over from it')
    assert runner.seen_more([*again, new]) == 0 and len(port.sent) == 2
    port.t = stamp + rest.planned.plan.duration + 1.0
    runner.tick()
    runner.on_result(rest, 'succeeded', 0, '')
    picked = [s for s in port.statuses if s.get('apple_state') == 'picked']
    assert sorted(s['apple'] for s in picked) == [0, 1, 2]
    assert [s['text'][-8:] for s in picked] == ['(1 of 3)', '(2 of 3)', '(3 of 3)']      # of the goal's apples
    assert np.allclose(next([s['x'], s['y'], s['z']] for s in picked if s['apple'] == 2), [0.65, 0.0, 0.55])
    assert port.statuses[-1]['state'] == 'succeeded' and port.statuses[-1]['picked'] == 3


def test_an_apple_seen_before_a_rest_begins_joins_that_rest_from_its_own_start(port):
    """An apple seen while a rest of the harvest waits to take over in the box joins it there, not after the rest's
    first apple: until then the arm would pass it unknown, at full speed."""
    runner = GoalRunner(port)
    apples, flight = _seen_harvest(runner, port, ys=(0.15, 0.3, 0.0))
    port.t = flight.start + 0.3 * flight.planned.harvest.apples[0].end
    first_new, second_new = apples[0].copy(), apples[0].copy()
    first_new[:3, 3], second_new[:3, 3] = [0.65, -0.15, 0.55], [0.62, 0.05, 0.45]
    assert runner.seen_more([*apples, first_new]) == 1
    rest = accept(runner, port)
    runner.on_feedback(rest, port.t, rest.start - port.t, 0.0)       # on the schedule, waiting for its start
    assert port.t < rest.start
    assert runner.seen_more([*apples, first_new, second_new]) == 1
    again, _, stamp = port.sent[-1]
    assert again is not rest and stamp == pytest.approx(rest.start)
    assert sorted(again.goal.target.indices) == sorted([*rest.goal.target.indices, 4])
    q0 = again.planned.plan.trajectory.sample([0.0])[0][0]
    assert q0 == pytest.approx(rest.planned.plan.trajectory.sample([0.0])[0][0])     # from the same rest in the box


def test_a_harvest_of_the_apples_seen_is_aimed_again_at_its_next_swaying_apple_before_the_drop(port):
    """The apple after the one in hand sways (±20 mm at 1 Hz): shortly before the apple in hand is dropped the apples
    not started are planned again from the box, the swaying one first and aimed where it will be when the fingers
    close (said on the harvest's status); once for each apple in hand, and not while the drop is far off."""
    runner = GoalRunner(port)
    apples, flight = _seen_harvest(runner, port)
    first, second = flight.planned.harvest.apples
    centre = apples[second.index][:3, 3]

    def sway(t):
        return centre + [0.0, 0.02 * np.sin(2 * np.pi * t), 0.0]
    follow = Follow(lambda t: (sway(t), np.eye(3) * 1e-6), 0.07)

    def follow_of(p):
        return follow if np.linalg.norm(p - centre) < 0.01 else None
    drop = flight.start + first.end
    port.t = flight.start + 0.3 * first.end
    assert runner.reaim(follow_of) == 0 and len(port.sent) == 1
    while runner.reaim(follow_of) == 0:
        port.t += 0.02
        assert port.t < drop, 'not aimed again before the drop'
    assert runner.reaim(follow_of) == 0 and len(port.sent) == 2
    assert 'sways: aimed where it will be' in [s for s in port.statuses if s.get('state') == 'replanned'][-1]['text']
    rest, _, stamp = port.sent[-1]
    assert stamp == pytest.approx(drop) and second.index in rest.goal.target.follows
    redone = rest.planned.harvest
    aimed = redone.apples[0]
    assert aimed.index == second.index
    t = np.arange(aimed.start, aimed.held[0], 1e-3)
    trajectory, dof = rest.planned.plan.trajectory, port.planner.planner.arm.dof
    closes = t[np.flatnonzero(trajectory.sample(t)[0][:, -1] <= 0.07)[0]]
    tool = port.planner.planner.arm.fk(trajectory.sample([closes])[0][0, :dof])[:3, 3]
    assert np.linalg.norm(tool - sway(stamp + closes)) < 0.002


def _late(runner, port, rest):
    """The controller accepts ``rest``'s plan, then aborts it: it starts in the past (its clock just past the start)."""
    port.t = rest.start + 0.243
    runner.tick()                                   # (the apple in hand is in the box by then)
    runner.on_response(rest, True, handle=object())
    runner.on_result(rest, 'aborted', OLD_HEADER_TIMESTAMP, 'it starts 0.243 s in the past')


def test_a_harvests_aim_that_came_too_late_leaves_it_running_as_planned_and_the_next_apple_is_aimed(port):
    """A re-aim whose plan reached the controller after its start never ran: the plan it was to take over from runs
    on and is again what the planner plans from, so the apple after the next one is aimed before its turn."""
    runner = GoalRunner(port)
    apples, flight = _seen_harvest(runner, port, ys=(0.15, 0.3, 0.0))
    first, second, _ = flight.planned.harvest.apples

    def follow_of(p):
        return Follow(lambda t: (p + [0.0, 0.02 * np.sin(2 * np.pi * t), 0.0], np.eye(3) * 1e-6), 0.07)
    port.t = flight.start + 0.3 * first.end
    while runner.reaim(follow_of) == 0:
        port.t += 0.02
    _late(runner, port, port.sent[-1][0])
    assert len(port.sent) == 2 and runner.running.key == flight.serial and runner.lifecycle.flights['h'] is flight
    assert 'came too late' in port.statuses[-1]['text'] and 'runs on as planned' in port.statuses[-1]['text']
    runner.tick()
    assert [s['apple'] for s in port.statuses if s.get('apple_state') == 'picked'] == [first.index]   # said once
    port.t = flight.start + first.end + 0.5
    while runner.reaim(follow_of) == 0:
        port.t += 0.02
        assert port.t < flight.start + second.end, 'not aimed again before the second drop'
    rest, _, stamp = port.sent[-1]
    assert stamp == pytest.approx(flight.start + second.end)
    assert [a.index for a in rest.planned.harvest.apples] == list(rest.goal.target.follows)


def test_a_rest_taking_in_an_apple_that_came_too_late_takes_it_in_after_the_next_apple_in_hand(port):
    runner = GoalRunner(port)
    apples, flight = _seen_harvest(runner, port, ys=(0.15, 0.3, 0.0))
    first, second, _ = flight.planned.harvest.apples
    port.t = flight.start + 0.5 * first.end
    new = apples[0].copy()
    new[:3, 3] = [0.65, -0.15, 0.55]
    assert runner.seen_more([*apples, new]) == 1
    _late(runner, port, port.sent[-1][0])
    rest, _, stamp = port.sent[-1]
    assert len(port.sent) == 3 and rest.goal.attempt == 1 and rest.replaces is flight
    assert stamp == pytest.approx(flight.start + second.end)
    assert 3 in [a.index for a in rest.planned.harvest.apples] + [s.index for s in rest.planned.harvest.skipped]
    assert first.index not in rest.goal.target.indices and second.index not in rest.goal.target.indices
    assert runner.harvests['h'].before.plan is flight.planned.harvest


def test_only_a_harvest_of_the_apples_seen_takes_in_apples_seen_later(port):
    runner = GoalRunner(port)
    R = Rotation.from_euler('xyz', SIDEWAYS).as_matrix()
    apple = np.block([[R, np.array([[0.7], [0.15], [0.6]])], [np.zeros((1, 3)), np.ones((1, 1))]])
    runner.take(Goal(Kind.HARVEST, 'given', Target(Kind.HARVEST, (apple, apple @ _shift([0, 0.15, 0]))), 0.0))
    accept(runner, port)
    assert runner.seen_more([apple @ _shift([0, -0.15, -0.05])]) == 0 and len(port.sent) == 1


def test_an_apple_over_the_box_is_never_taken_in(port):
    runner = GoalRunner(port)
    apples, flight = _seen_harvest(runner, port)
    port.t = flight.start + 0.5 * flight.planned.harvest.apples[0].end
    over = apples[0].copy()
    over[:3, 3] = np.asarray(port.planner.pick.box_position) + [0.0, 0.0, 0.05]
    assert runner.seen_more([over]) == 0 and len(port.sent) == 1


def test_an_apple_seen_too_late_is_said_not_taken_in(port):
    """An apple seen after the last one is in hand is not taken in: said, with why, on the harvest's status."""
    runner = GoalRunner(port)
    apples, flight = _seen_harvest(runner, port, ys=(0.15,))
    port.t = flight.start + 0.5 * flight.planned.harvest.apples[0].end
    runner._harvest_rest = lambda *a, **k: None                       # the last apple is in hand
    far = apples[0] @ _shift([0, 0.3, 0])
    assert runner.seen_more([far]) == 0 and not port.canceled
    assert [s['apple'] for s in port.statuses if s.get('apple_state') == 'skipped'] == [1]


def test_a_rest_that_only_took_in_apples_seen_and_cannot_be_planned_leaves_the_harvest_running(port):
    """(A rest planned around a changed world that cannot be planned stops the harvest instead: it would hit what
    changed.)"""
    runner = GoalRunner(port)
    apples, flight = _seen_harvest(runner, port)
    port.t = flight.start + 0.5 * flight.planned.harvest.apples[0].end
    unreachable = apples[0].copy()
    unreachable[:3, 3] = [3.0, 0.0, 0.5]                              # far beyond the arm's reach
    planner, refuse = port.planner.plan, []

    def fails(*a, **k):
        refuse.append(1)
        raise ValueError('no apple can be picked')
    port.planner.plan = fails
    assert runner.seen_more([unreachable]) == 1 and refuse
    assert not port.canceled and port.states('h')[-1] == 'executing'
    assert 'not replanned' in port.statuses[-1]['text']
    port.planner.plan = planner


def _shift(xyz):
    T = np.eye(4)
    T[:3, 3] = xyz
    return T
