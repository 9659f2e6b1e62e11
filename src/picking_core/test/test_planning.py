"""The planner core and the Table 1 pick cycle, in process (no ROS)."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from picking_core.kinematics import Unreachable, pose_matrix
from picking_core.pick_cycle import MIN_DWELL, PickCycle, PickSettings
from picking_core.planning import PATH_METHODS, PLAN_MARGIN, POSE_METHODS, Planner, PlannerSettings

DOWN = Rotation.from_euler('xyz', [180, 0, 0], degrees=True).as_quat()
HOME = np.array([0.0, 0.2, 1.6, 0.0, 1.3, 0.0])
Z = np.zeros(6)


@pytest.fixture(scope='module')
def planner(arm):
    return Planner(arm, PlannerSettings(speed_scale=1.0))


def _within_limits(arm, plan, scale=1.0):
    t = np.linspace(0, plan.duration, 4000)
    q, qd, qdd = plan.trajectory.sample(t)
    n = arm.dof
    assert np.all(np.abs(qd[:, :n]) <= arm.max_velocity * scale * (1 + 1e-6))
    assert np.all(np.abs(qdd[:, :n]) <= arm.max_acceleration * scale**2 * (1 + 1e-6))
    assert np.all(arm.within_limits(q[:, :n]))


@pytest.mark.parametrize('method', POSE_METHODS)
def test_pose_goal_reaches_the_pose_within_the_limits(arm, planner, method):
    T = pose_matrix([0.6, 0.1, 0.4], DOWN)
    plan = planner.plan_pose((HOME, Z, Z), T, method)
    q_end = plan.trajectory.end_state()[0]
    assert arm.fk(q_end) == pytest.approx(T, abs=1e-6)
    _within_limits(arm, plan)
    assert plan.trajectory.start_state()[0] == pytest.approx(HOME)


def test_moves_of_parabolas_are_checked_where_their_extremes_lie():
    """LSPB moves and via points (each piece a parabola) are checked at their breaks, the
    middle of each piece and where a joint turns inside one: the largest |q|, |qd| and |qdd|
    there are those of a sampling every 10 µs (exactly where the sampling meets them), in far
    fewer points; a move with higher powers is sampled every 2.5 ms."""
    from picking_core import trajectory
    from picking_core.planning.limits import _check_times
    rng = np.random.default_rng(21)
    for _ in range(30):
        points = rng.uniform(-1.0, 1.0, (4, 3))
        for traj in (trajectory.via_lspb(points, rng.uniform(0.8, 1.5, 3), 12.0),
                     trajectory.lspb(points[0], points[1], 1.2, 8.0)):
            t = _check_times(traj)
            dense = np.linspace(0.0, traj.duration, int(traj.duration / 1e-5) + 1)
            assert len(t) < 0.1 * traj.duration / 0.0025 and np.all(np.diff(t) >= 0.0)
            assert t[0] == 0.0 and t[-1] == traj.duration
            for at_checks, everywhere in zip(traj.sample(t), traj.sample(dense)):
                assert np.abs(at_checks).max(axis=0) == pytest.approx(np.abs(everywhere).max(axis=0), abs=1e-9)
                assert np.all(at_checks.max(axis=0) >= everywhere.max(axis=0) - 1e-12)
                assert np.all(at_checks.min(axis=0) <= everywhere.min(axis=0) + 1e-12)
    quintic = trajectory.quintic(np.zeros(2), np.ones(2), 1.0)
    assert np.diff(_check_times(quintic)) == pytest.approx(np.full(399, 1.0 / 399))


def test_shortest_duration_uses_a_limit_fully(arm, planner):
    q_goal = HOME + np.array([1.0, 0, 0, 0, 0, 0])
    traj = planner.joint_move(HOME, q_goal, 'quintic')
    _, qd, qdd = traj.sample(np.linspace(0, traj.duration, 4001))
    used = max(np.abs(qd[:, 0]).max() / arm.max_velocity[0], np.abs(qdd[:, 0]).max() / arm.max_acceleration[0])
    assert used == pytest.approx(PLAN_MARGIN, rel=1e-3)


def test_speed_scale_slows_the_move_down(arm):
    T = pose_matrix([0.6, 0.1, 0.4], DOWN)
    fast = Planner(arm, PlannerSettings(speed_scale=1.0)).plan_pose((HOME, Z, Z), T, 'lspb')
    slow = Planner(arm, PlannerSettings(speed_scale=0.25)).plan_pose((HOME, Z, Z), T, 'lspb')
    assert slow.duration == pytest.approx(4 * fast.duration, rel=1e-6)
    _within_limits(arm, slow, 0.25)


def test_fixed_duration_that_breaks_a_limit_is_refused(arm):
    planner = Planner(arm, PlannerSettings(duration=0.05))
    with pytest.raises(Unreachable, match='limit broken'):
        planner.plan_pose((HOME, Z, Z), pose_matrix([0.6, 0.1, 0.4], DOWN), 'quintic')


def test_plan_from_a_moving_state_starts_with_that_velocity(arm, planner):
    qd0 = np.array([0.3, -0.2, 0.1, 0.0, 0.2, -0.4])
    for method in ('quintic', 'lspb', 'line'):
        plan = planner.plan_pose((HOME, qd0, Z), pose_matrix([0.6, 0.1, 0.4], DOWN), method)
        q, qd, _ = plan.trajectory.sample(0.0)
        assert q[0] == pytest.approx(HOME) and qd[0] == pytest.approx(qd0), method


def test_a_move_that_would_overshoot_a_limit_from_the_motion_brakes_first(arm, planner):
    # The wrist turns at 99 % of its speed limit: carried on, a quintic would exceed it.
    qd0 = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 2.97])
    plan = planner.plan_pose((HOME, qd0, Z), pose_matrix([0.6, 0.1, 0.4], DOWN), 'quintic')
    assert [s.label for s in plan.segments] == ['brake', 'move']
    assert plan.trajectory.sample(0.0)[1][0] == pytest.approx(qd0)
    _within_limits(arm, plan)


def test_a_start_that_cannot_stop_before_a_position_limit_is_refused_naming_the_joint(arm, planner):
    # The elbow 0.1 rad from its upper limit, moving toward it at 96 % of its speed limit: any stop
    # within the acceleration limit passes the limit, so every plan from here would.
    q0 = HOME.copy()
    q0[2] = arm.upper[2] - 0.1
    qd0 = np.zeros(6)
    qd0[2] = 0.96 * arm.max_velocity[2]
    goal = pose_matrix([0.6, 0.1, 0.4], DOWN)
    for method in ('quintic', 'lspb', 'line'):
        with pytest.raises(Unreachable, match=r'elbow_joint moves at 2.4 rad/s .* cannot stop before it'):
            planner.plan_pose((q0, qd0, Z), goal, method)
    # Moving away from the limit at the same speed, the plan brakes first and keeps every limit.
    _within_limits(arm, planner.plan_pose((q0, -qd0, Z), goal, 'quintic'))


@pytest.mark.parametrize('method', PATH_METHODS)
def test_path_goal_ends_at_the_last_pose(arm, planner, method):
    poses = [pose_matrix([0.55, -0.1, 0.5], DOWN), pose_matrix([0.5, 0.05, 0.45], DOWN)]
    plan = planner.plan_path((HOME, Z, Z), poses, method)
    assert arm.fk(plan.trajectory.end_state()[0]) == pytest.approx(poses[-1], abs=1e-6)
    _within_limits(arm, plan)


def test_unreachable_and_bad_goals_are_refused(planner):
    with pytest.raises(Unreachable, match='out of reach'):
        planner.plan_pose((HOME, Z, Z), pose_matrix([2.0, 0.0, 0.3], DOWN))
    with pytest.raises(ValueError, match='unknown method'):
        planner.plan_pose((HOME, Z, Z), pose_matrix([0.6, 0.0, 0.4], DOWN), 'teleport')
    with pytest.raises(ValueError, match='an arc needs'):
        planner.plan_path((HOME, Z, Z), [pose_matrix([0.6, 0.0, 0.4], DOWN)], 'arc')
    with pytest.raises(ValueError, match='collinear'):
        planner.arc(HOME, *(pose_matrix(p, DOWN) for p in ([0.6, 0.0, 0.4], [0.55, 0.0, 0.4], [0.5, 0.0, 0.4])))


@pytest.mark.parametrize('bad', [dict(speed_scale=0.0), dict(speed_scale=1.5), dict(method='x'),
                                 dict(sample_period=0.0), dict(duration=-1.0)])
def test_bad_settings_are_refused(bad):
    with pytest.raises(ValueError):
        PlannerSettings(**bad).validate()


APPLE = pose_matrix([0.70, 0.15, 0.65], Rotation.from_euler('y', 90, degrees=True).as_quat())


def test_table1_cycle_visits_every_knot_point_with_the_gripper(arm, planner):
    cycle = PickCycle(planner, PickSettings().validate(arm))
    plan = cycle.plan((HOME, Z, Z), APPLE)
    labels = [s.label for s in plan.segments]
    assert labels == ['P0 home', 'P1 approach', 'P2 to the apple', 'grasp', 'P3 lift and detach', 'P4 above the box',
                      'P5 into the box', 'release', 'P0 back home']
    assert plan.joint_names[-1] == 'gripper_joint'
    poses = cycle.key_poses(APPLE)
    ends = {s.label: s.start + s.duration for s in plan.segments}
    for label, knot in (('P2 to the apple', 'P2'), ('P3 lift and detach', 'P3'), ('P4 above the box', 'P4'),
                        ('P5 into the box', 'P5')):
        q = plan.trajectory.sample(ends[label])[0][0, :6]
        assert arm.fk(q)[:3, 3] == pytest.approx(poses[knot][:3, 3], abs=1e-6), label
    g = plan.trajectory.sample([0.0, plan.extra['grasp_end'], plan.extra['release_start'],
                                plan.extra['release_end']])[0][:, 6]
    s = PickSettings()
    assert g == pytest.approx([s.gripper_open, s.gripper_closed, s.gripper_closed, s.gripper_open])
    assert plan.trajectory.end_state()[0][:6] == pytest.approx(PickSettings().home_positions)
    _within_limits(arm, plan)


def test_a_line_slowed_to_the_joint_limits_uses_them_fully_with_one_ik_pass(arm, planner, monkeypatch):
    """A line too fast for the joints is stretched (its joint path scales exactly in time),
    not re-solved with a safety margin: its fastest joint reaches the plan's limit."""
    import picking_core.planning.cartesian as planning
    passes = []
    solve = planning.cartesian_to_joint
    monkeypatch.setattr(planning, 'cartesian_to_joint', lambda *a, **k: passes.append(1) or solve(*a, **k))
    start = (HOME, Z, Z)
    goal = pose_matrix([0.55, 0.05, 0.35], DOWN)
    fast = Planner(arm, PlannerSettings(speed_scale=1.0, method='line', cartesian_speed=1.5, cartesian_accel=15.0))
    plan = fast.plan_pose(start, goal)
    assert len(passes) == 1
    _within_limits(arm, plan)
    t = np.linspace(0.0, plan.duration, 4000)
    _, qd, qdd = plan.trajectory.sample(t)
    use = max(np.max(np.abs(qd) / fast._vmax), np.sqrt(np.max(np.abs(qdd) / fast._amax)))
    assert 0.99 <= use <= 1.0 + 1e-3
    tool = arm.fk(plan.trajectory.sample(t[::40])[0])[:, :3, 3]
    along = (tool - tool[0]) @ (tool[-1] - tool[0]) / np.linalg.norm(tool[-1] - tool[0]) ** 2
    off = tool - tool[0] - along[:, None] * (tool[-1] - tool[0])
    assert np.abs(off).max() < 1e-4                                  # still a straight line


def test_a_release_lead_opens_the_fingers_on_the_line_into_the_box_and_shortens_the_dwell(arm, planner):
    plain = PickCycle(planner, PickSettings().validate(arm)).plan((HOME, Z, Z), APPLE)
    release = next(s.duration for s in plain.segments if s.label == 'release')
    for lead in (0.05, 10.0):                   # (10 s: as much as the line and the dwell, less MIN_DWELL, allow)
        plan = PickCycle(planner, PickSettings(release_lead=lead).validate(arm)).plan((HOME, Z, Z), APPLE)
        seg = {s.label: s for s in plan.segments}
        line, dwell = seg['P5 into the box'], seg['release']
        led = min(lead, line.duration, release - MIN_DWELL)
        assert dwell.duration == pytest.approx(release - led)
        assert plan.extra['release_start'] == pytest.approx(line.start + line.duration - led)
        assert plan.extra['release_end'] == pytest.approx(dwell.start + dwell.duration)
        assert plan.duration == pytest.approx(plain.duration - led)
        g = plan.trajectory.sample([plan.extra['release_start'], dwell.start, plan.extra['release_end']])[0][:, 6]
        s = PickSettings()
        assert g[0] == pytest.approx(s.gripper_closed) and s.gripper_closed < g[1] < s.gripper_open
        assert g[2] == pytest.approx(s.gripper_open)
        assert np.abs(plan.trajectory.sample([dwell.start + dwell.duration / 2])[1][0][:6]).max() < 1e-9
        _within_limits(arm, plan)
    for bad in (-0.1, float('nan')):
        with pytest.raises(ValueError, match='release_lead'):
            PickSettings(release_lead=bad).validate(arm)


def test_table1_cycle_with_an_arc_lift(arm, planner):
    settings = PickSettings(lift_method='arc').validate(arm)
    plan = PickCycle(planner, settings).plan((HOME, Z, Z), APPLE)
    assert ('P3 lift and detach', 'arc') in [(s.label, s.method) for s in plan.segments]
    assert plan.cartesian                                  # the lines and the arc, for deviation checks


def test_unreachable_apple_names_the_knot_point(arm, planner):
    cycle = PickCycle(planner, PickSettings().validate(arm))
    with pytest.raises(Unreachable, match='P1 \\(approach\\)|P2 \\(the apple\\)'):
        cycle.plan((HOME, Z, Z), pose_matrix([1.6, 0.0, 0.6], DOWN))


@pytest.mark.parametrize('transfer', ['via_lspb', 'quintic_via', 'optimal'])
def test_a_slowed_cycle_and_via_path_keep_the_scaled_limits(arm, transfer):
    """At half speed every segment stays within half the velocity limits and a quarter of the
    accelerations (via-point LSPB once timed its lines against the full limits: 0.8 of them)."""
    slow = Planner(arm, PlannerSettings(speed_scale=0.5, path_method=transfer))
    plan = PickCycle(slow, PickSettings(transfer_method=transfer).validate(arm)).plan((HOME, Z, Z), APPLE)
    _within_limits(arm, plan, scale=0.5)
    path = slow.plan_path((HOME, Z, Z), [pose_matrix([0.55, 0.3, 0.45], DOWN), pose_matrix([0.5, -0.4, 0.4], DOWN)])
    _within_limits(arm, path, scale=0.5)


def test_via_lspb_lines_run_at_the_speed_limit_where_it_binds(arm):
    """Long moves through a via point: the timing starts where the lines just keep the scaled speed
    limit (an end line blends from rest: T = dq / v + v / 2a), neither above it nor far below."""
    planner = Planner(arm, PlannerSettings(speed_scale=0.5))
    qs = np.array([HOME, HOME + [1.2, 0.3, -0.3, 0.5, 0.0, 0.8], HOME + [2.4, 0.0, 0.0, 0.9, 0.2, 1.6]])
    traj = planner.via(qs, 'via_lspb')
    _, qd, _ = traj.sample(np.linspace(0.0, traj.duration, 4000))
    use = np.max(np.abs(qd) / planner._vmax)
    assert 0.999 <= use <= 1.0 + 1e-9


@pytest.mark.parametrize('bad', [dict(home_positions=(0.0,) * 5), dict(approach_distance=0.0),
                                 dict(lift_method='jump'), dict(gripper_closed=0.2),
                                 dict(box_position=(0.0, float('nan'), 0.3)), dict(approach_distance=3109.0),
                                 dict(box_drop_height=1e9)])
def test_bad_pick_settings_are_refused(arm, bad):
    with pytest.raises(ValueError):
        PickSettings(**bad).validate(arm)


def test_an_extrapolated_start_is_held_within_the_limits_and_every_method_plans_from_it(arm, planner):
    from picking_core.planning import feasible_start
    vmax, amax = arm.max_velocity, arm.max_acceleration
    # Carried on too far: beyond the elbow's upper limit still moving up, the wrist at its
    # speed limit still accelerating, the base decelerating inwards (kept).
    q = HOME.copy()
    q[2] = arm.upper[2] + 0.1
    qd = np.array([0.5, 0.0, 1.0, 0.0, 0.0, vmax[5] * 1.5])
    qdd = np.array([-2.0, 0.0, 3.0, 0.0, 0.0, 5.0])
    q1, qd1, qdd1 = feasible_start(arm, q, qd, qdd)
    assert q1[2] == arm.upper[2] and qd1[2] == 0.0 and qdd1[2] == 0.0
    assert qd1[5] == vmax[5] and qdd1[5] == 0.0
    assert qd1[0] == 0.5 and qdd1[0] == -2.0
    assert np.all(np.abs(qdd1) <= amax)
    goal = pose_matrix([0.55, 0.05, 0.45], DOWN)
    for method in ('quintic', 'optimal', 'lspb'):
        plan = planner.plan_pose((q1, qd1, qdd1), goal, method=method)
        _within_limits(arm, plan)


def test_an_extrapolated_start_racing_toward_a_near_limit_is_held_to_a_speed_that_can_stop(arm, planner):
    """Found by a CI run (a controller stopped by SIGSTOP, its reference extrapolated): the elbow 6 mrad
    below its limit moving up at 0.7 rad/s could not stop before it, and the goal was refused."""
    from picking_core.planning import feasible_start
    q, qd, qdd = HOME.copy(), np.zeros(6), np.zeros(6)
    q[2], qd[2], qdd[2] = arm.upper[2] - 0.006, 0.705, 1.0
    with pytest.raises(Unreachable, match='cannot stop before it'):
        planner.plan_pose((q, qd, qdd), pose_matrix([0.55, 0.05, 0.45], DOWN), method='quintic')
    q1, qd1, qdd1 = feasible_start(arm, q, qd, qdd)
    assert 0.0 < qd1[2] < 0.705 and qdd1[2] == 0.0 and qd1[2] ** 2 / arm.max_acceleration[2] <= 0.006 + 1e-12
    goal = pose_matrix([0.55, 0.05, 0.45], DOWN)
    for method in ('quintic', 'optimal', 'lspb'):
        _within_limits(arm, planner.plan_pose((q1, qd1, qdd1), goal, method=method))


def test_a_jerk_limited_line_with_the_optimal_progress_is_faster_and_keeps_every_limit(arm):
    start = (HOME, Z, Z)
    goal = pose_matrix([0.55, 0.05, 0.35], DOWN)
    plans = {}
    for profile in ('quintic', 'optimal'):
        p = Planner(arm, PlannerSettings(speed_scale=1.0, method='line', path_method='optimal', limit_jerk=True,
                                         cartesian_profile=profile))
        plans[profile] = p.plan_pose(start, goal)
        _within_limits(arm, plans[profile])
        t = np.linspace(0.0, plans[profile].duration, 4000)
        assert np.all(np.abs(plans[profile].trajectory.jerk(t)[:, :arm.dof]) <= p._jmax / PLAN_MARGIN * (1 + 1e-6))
    assert plans['optimal'].duration < 0.95 * plans['quintic'].duration


def test_plans_from_extrapolated_moving_starts_keep_every_limit(arm):
    """States a controller's reference carried on too far (speeds and accelerations up to
    1.2 and 1.5 times the limits), held within the limits, then planned from: the brake and
    the move keep every limit (a quintic brake broke one for about a fifth of them)."""
    from picking_core.planning import feasible_start
    planner = Planner(arm, PlannerSettings(speed_scale=0.5))
    goal = pose_matrix([0.55, 0.05, 0.45], DOWN)
    rng = np.random.default_rng(3)
    for _ in range(200):
        start = feasible_start(arm, HOME + rng.normal(0.0, 0.1, 6),
                               rng.uniform(-1.2, 1.2, 6) * arm.max_velocity,
                               rng.uniform(-1.5, 1.5, 6) * arm.max_acceleration)
        _within_limits(arm, planner.plan_pose(start, goal))


@pytest.mark.parametrize('optimal', [False, True])
def test_planning_a_pick_cycle_leaves_nothing_for_the_cycle_collector(arm, optimal):
    """No reference cycles: a refusal kept while the search goes on (its traceback holds the
    searching frame) once left every plan to the cycle collector, which stops the process to
    find them; now each plan is freed as soon as its last reference goes."""
    import gc
    if optimal:
        planner = Planner(arm, PlannerSettings(speed_scale=1.0, method='optimal', path_method='optimal',
                                               limit_jerk=True, cartesian_profile='optimal'))
        settings = PickSettings(approach_method='optimal', transfer_method='optimal', blend=True,
                                blend_radius=0.02).validate(arm)
    else:
        planner, settings = Planner(arm, PlannerSettings(speed_scale=1.0)), PickSettings().validate(arm)
    apple = pose_matrix([0.70, 0.15, 0.65], [0.0, np.sqrt(0.5), 0.0, np.sqrt(0.5)])
    start = (np.asarray(settings.home_positions, float), Z, Z)
    PickCycle(planner, settings).plan(start, apple)
    gc.collect()
    gc.disable()
    try:
        for _ in range(3):
            PickCycle(planner, settings).plan(start, apple).samples(0.01)
        assert gc.collect() == 0
    finally:
        gc.enable()


def test_a_start_state_is_checked_and_a_single_number_holds_for_every_joint(arm, planner):
    """``start = (q, qd, qdd)``: a velocity or an acceleration given as one number is every joint's
    (found by the long fuzz run: 3 rad/s crashed the braking check with an IndexError); a wrong
    number of values, NaN or a start that is not three parts is refused, naming which part."""
    T = pose_matrix([0.6, 0.1, 0.4], DOWN)
    with pytest.raises(Unreachable, match='elbow_joint moves at 3 rad/s from 1.6 rad toward its limit'):
        planner.plan_pose((HOME, 3.0, 0.0), T, 'lspb')
    moving = planner.plan_pose((HOME, 0.05, 0.0), T, 'quintic')
    assert moving.trajectory.start_state()[1][:arm.dof] == pytest.approx(np.full(arm.dof, 0.05))
    for start, part in (((HOME, np.zeros(5), Z), 'start velocity'), ((HOME[:5], Z, Z), 'start position'),
                        ((HOME, Z, np.full(6, np.nan)), 'start acceleration'), ((HOME, Z), 'start must be')):
        with pytest.raises(ValueError, match=part):
            planner.plan_pose(start, T, 'quintic')
    with pytest.raises(ValueError, match='start velocity'):          # before the knot points are checked
        cycle = PickCycle(planner, PickSettings().validate(arm))
        cycle.plan((HOME, [0.0] * 7, Z), pose_matrix([0.7, 0.15, 0.65], DOWN))


def test_a_quintic_pose_goal_with_limit_jerk_takes_long_enough_to_keep_the_jerk_limits(arm):
    """Not refused ("jerk limit broken"): its duration allows for the jerk at its ends, 60 h / T^3."""
    planner = Planner(arm, PlannerSettings(speed_scale=1.0, method='quintic', path_method='optimal', limit_jerk=True))
    plan = planner.plan_pose((HOME, Z, Z), pose_matrix([0.6, 0.1, 0.4], DOWN))
    t = np.linspace(0.0, plan.duration, 2000)
    assert planner._jerk_ratio(plan.trajectory, t) <= 1.0
