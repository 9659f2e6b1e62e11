"""Pose and path goals around obstacles: a joint path around what the plan would hit, another IK
solution for a goal that is itself in contact, a Cartesian path refused with its contact."""

import numpy as np
import pytest
from conftest import shipped_harvest
from scipy.spatial.transform import Rotation

from picking_core import around
from picking_core.approaches import Blocked, BrakeBlocked
from picking_core.collision import CollisionChecker, Scene
from picking_core.collision.scene import rod
from picking_core.harvest import synthetic_tree
from picking_core.kinematics.capsules import ArmCapsules

HOME = np.array([0.0, 0.2, 1.6, 0.0, -0.23, 0.0])
START = (HOME, 0 * HOME, 0 * HOME)


@pytest.fixture(scope='module')
def planner():
    return shipped_harvest().cycle.planner


@pytest.fixture(scope='module')
def caps(planner):
    return ArmCapsules.from_arm(planner.arm)


def goal():
    """An apple's grasp pose turned 70° about the base: the waist swings on the way."""
    turn = np.eye(4)
    turn[:3, :3] = Rotation.from_euler('z', 70.0, degrees=True).as_matrix()
    return turn @ synthetic_tree(10, seed=1)[1]


def wire_across(planner, plan, fraction=0.5):
    """A thin wire across the tool's way at ``fraction`` of the plan."""
    t = fraction * plan.duration
    q0, q1 = np.asarray(plan.trajectory.sample([t, t + 0.05])[0])[:, :6]
    p, ahead = planner.arm.fk(q0)[:3, 3], planner.arm.fk(q1)[:3, 3]
    along = (ahead - p) / np.linalg.norm(ahead - p)
    across = np.cross(along, [0.0, 0.0, 1.0])
    across /= np.linalg.norm(across)
    return Scene((rod('wire', 'wire', p - 0.25 * across, p + 0.25 * across, 0.003),))


@pytest.mark.parametrize('method', ['quintic', 'optimal'])
def test_a_pose_goal_across_a_wire_goes_around_it_to_the_same_pose(planner, caps, method):
    T = goal()
    plain = planner.plan_pose(START, T, method)
    checker = CollisionChecker(caps, wire_across(planner, plain))
    assert checker.check(plain.trajectory) is not None
    plan = around.plan_pose(planner, checker, START, T, method)
    assert checker.check(plan.trajectory) is None
    assert 'around obstacles through' in plan.extra['detours']
    q_end = plan.trajectory.end_state()[0]
    np.testing.assert_allclose(planner.arm.fk(q_end), T, atol=1e-6)
    # Within the limits, and the clear goal is planned as before.
    _, qd, qdd = plan.trajectory.sample(np.linspace(0.0, plan.duration, 400))
    assert (np.abs(qd) <= planner.arm.max_velocity * (1 + 1e-6)).all()
    assert (np.abs(qdd) <= planner.arm.max_acceleration * (1 + 1e-6)).all()
    assert around.plan_pose(planner, None, START, T, method).duration == pytest.approx(plain.duration)


def test_a_pose_goal_whose_arm_would_rest_in_a_branch_takes_another_ik_solution(planner, caps):
    T = goal()
    q_goal = planner.arm.check_reachable(T, seed=HOME)
    # A branch through the elbow of the solution nearest the start, well away from the tool.
    elbow = planner.arm.joint_frames(q_goal[None])[0, 2, :3, 3]
    scene = Scene((rod('branch', 'branch', elbow - [0, 0, 0.04], elbow + [0, 0, 0.04], 0.02),))
    checker = CollisionChecker(caps, scene)
    assert checker.colliding(q_goal[None]).all()
    plan = around.plan_pose(planner, checker, START, T, 'quintic')
    q_end = plan.trajectory.end_state()[0]
    assert np.abs(q_end - q_goal).max() > 0.1
    np.testing.assert_allclose(planner.arm.fk(q_end), T, atol=1e-6)
    assert checker.check(plan.trajectory) is None


def test_a_line_into_a_wire_is_refused_with_its_contact_not_bent(planner, caps):
    T = goal()
    plain = planner.plan_pose(START, T, 'line')
    checker = CollisionChecker(caps, wire_across(planner, plain))
    with pytest.raises(Blocked, match=r'would hit an obstacle: .* wire .*keeps its tool path'):
        around.plan_pose(planner, checker, START, T, 'line')


def test_a_path_through_via_points_goes_around_a_wire_between_them(planner, caps):
    T = goal()
    first = T.copy()
    first[:3, 3] += [0.0, 0.0, 0.15]
    poses = [first, T]
    plain = planner.plan_path(START, poses, 'quintic_via')
    checker = CollisionChecker(caps, wire_across(planner, plain, 0.4))
    assert checker.check(plain.trajectory) is not None
    plan = around.plan_path(planner, checker, START, poses, 'quintic_via')
    assert checker.check(plan.trajectory) is None
    # It still passes every pose asked for, in order.
    t = np.linspace(0.0, plan.duration, 2000)
    tool = planner.arm.fk(np.asarray(plan.trajectory.sample(t)[0]))[:, :3, 3]
    near = [int(np.argmin(np.linalg.norm(tool - P[:3, 3], axis=1))) for P in poses]
    assert near == sorted(near) and all(np.linalg.norm(tool[i] - P[:3, 3]) < 1e-4 for i, P in zip(near, poses))
    with pytest.raises(Blocked, match='keeps its tool path'):
        around.plan_path(planner, checker, START, poses, 'line')


def test_a_moving_start_whose_brake_would_hit_a_wire_says_so_before_any_way_around(planner, caps):
    """The brake from a moving start is the one part no detour can change: its contact is its own
    error (the goal policy tells a guessed start from a known one by it)."""
    start = (HOME, np.array([0.0, 0.8, -0.8, 0.0, 0.0, 0.0]), 0 * HOME)
    stop, _ = planner.come_to_rest(start)
    brake = type('Plan', (), {'duration': stop.duration, 'trajectory': stop})
    checker = CollisionChecker(caps, wire_across(planner, brake))
    with pytest.raises(BrakeBlocked, match='while it brakes: wrist_3_link .* wire'):
        around.plan_pose(planner, checker, start, goal(), 'quintic')
