"""The scene, the canopy, the collision checker and the pick cycle's search for a clear approach."""

import dataclasses

import coal
import numpy as np
import pytest
from conftest import shipped_harvest
from scipy.spatial.transform import Rotation

from picking_core import approaches
from picking_core.collision import Allowed, Canopy, CollisionChecker, Scene
from picking_core.collision.scene import frames_along, transform
from picking_core.harvest import synthetic_tree
from picking_core.kinematics import Unreachable
from picking_core.kinematics.capsules import ArmCapsules
from picking_core.pick_cycle import PickCycle

HOME = np.array([0.0, 0.2, 1.6, 0.0, -0.23, 0.0])


@pytest.fixture(scope='module')
def cycle():
    return shipped_harvest().cycle


@pytest.fixture(scope='module')
def caps(cycle):
    return ArmCapsules.from_arm(cycle.arm)


def branch(name, p0, p1, radius=0.015):
    return {'name': name, 'from': list(p0), 'to': list(p1), 'radius': radius}


@pytest.mark.parametrize('scene, words', [
    ({'trees': []}, 'unknown keys'),
    ({'branches': [{'from': [0, 0, 0], 'to': [1, 0, 0]}]}, "has no 'radius'"),
    ({'branches': [branch('a', [0, 0, 0], [0, 0, 0])]}, 'the same point'),
    ({'branches': [branch('a', [0, 0, 0], [1, 0, 0], -0.1)]}, 'radius must be a positive'),
    ({'wires': [branch('a', [0, 0, 0], [1, 0, 0]), branch('a', [0, 1, 0], [1, 1, 0])]}, 'names must differ'),
    ({'boxes': [{'center': [0, 0, 0], 'size': [0.1, 0, 0.1]}]}, 'longer than 0 m'),
    ({'boxes': [{'center': [0, 0], 'size': [0.1, 0.1, 0.1]}]}, '3 finite numbers'),
])
def test_a_bad_scene_is_refused_with_the_reason(scene, words):
    with pytest.raises(ValueError, match=words):
        Scene.from_dict(scene)


def test_the_shipped_orchard_scene_loads():
    from picking_description import scene_path
    scene = Scene.from_yaml(scene_path('orchard'))
    kinds = {o.kind for o in scene.obstacles}
    assert {'branch', 'wire', 'box', 'ground'} <= kinds


def naive_contact(checker, q, obstacles, canopy=None):
    """Whether any moving link is within the clearance of an obstacle: coal on every pair, no broad phase."""
    seg = checker.capsules.segments(q)[0]
    request = coal.CollisionRequest()
    request.security_margin = checker.clearance
    for k in checker.moving:
        frame, length = frames_along(seg[k, :1], seg[k, 1:])
        shape = coal.Capsule(float(checker.capsules.radius[k]), float(length[0]))
        others = [(o.shape, o.placed) for o in obstacles]
        if canopy is not None:
            others.append((canopy.octree, coal.Transform3s()))
        for other, pose in others:
            result = coal.CollisionResult()
            coal.collide(shape, transform(frame[0]), other, pose, request, result)
            if result.isCollision():
                return True
    return False


def test_the_broad_phase_clears_only_what_coal_clears(cycle, caps):
    """Random configurations near a scene and a 20 000-point canopy: the checker finds a contact
    exactly where coal, asked about every link and obstacle, finds one."""
    rng = np.random.default_rng(3)
    scene = Scene.from_dict({'ground_z': -0.2, 'branches': [branch('b', [0.6, -0.5, 0.5], [0.6, 0.5, 0.7], 0.03)],
                             'wires': [branch('w', [0.4, -1, 0.3], [0.4, 1, 0.3], 0.002)],
                             'boxes': [{'name': 'box', 'center': [0.1, -0.55, 0.15], 'size': [0.3, 0.3, 0.3]}]})
    canopy = Canopy(rng.uniform([0.65, -0.4, 0.4], [0.9, 0.4, 0.9], (20000, 3)))
    checker = CollisionChecker(caps, scene, canopy, self_check=False)
    q = HOME + rng.normal(0.0, 0.6, (300, 6))
    got = np.array([c is not None for c in checker.contacts(q)])
    want = np.array([naive_contact(checker, qi, scene.obstacles, canopy) for qi in q])
    assert 30 < got.sum() < 270, 'the sample must hold both clear and colliding configurations'
    np.testing.assert_array_equal(got, want)


def test_a_contact_names_the_link_the_obstacle_where_and_how_near(cycle, caps):
    tool = cycle.arm.fk(HOME)[:3, 3]
    # A branch along y, 7 cm above the tool point: the tool's sphere (4.5 cm) comes within 2.5 cm of its
    # surface (1.5 cm radius) less... 7 - 4.5 - 1.5 = 1 cm, inside the 2 cm clearance.
    scene = Scene.from_dict({'branches': [branch('twig', tool + [0, -0.3, 0.07], tool + [0, 0.3, 0.07])]})
    contact = CollisionChecker(caps, scene).first_contact([HOME], times=[1.5])
    assert contact.obstacle == 'twig' and contact.time == 1.5
    assert contact.link in ('tool0', 'wrist_3_link')
    assert contact.distance < 0.02
    assert 'twig' in str(contact) and 't = 1.500 s' in str(contact)
    # Touching inside the apple's region is allowed.
    assert CollisionChecker(caps, scene).first_contact([HOME], allowed=Allowed(tool + [0, 0, 0.07], 0.2)) is None
    far = Scene.from_dict({'branches': [branch('twig', tool + [0, -0.3, 0.3], tool + [0, 0.3, 0.3])]})
    assert CollisionChecker(caps, far).first_contact([HOME]) is None


def test_the_arm_folded_onto_itself_is_a_self_collision(caps):
    checker = CollisionChecker(caps)
    assert checker.first_contact([HOME]) is None
    folded = np.array([0.0, -1.0, 2.55, 0.0, 2.0, 0.0])        # the elbow shut: the gripper on the shoulder
    contact = checker.first_contact([HOME, folded])
    assert contact is not None and contact.index == 1 and 'the arm\'s' in contact.obstacle
    # A plan that folds the arm onto itself on its way is not clear, and says when.
    from picking_core.planning import Planner, PlannerSettings
    move = Planner(caps.arm, PlannerSettings()).joint_move(HOME, folded, 'quintic')
    hit = checker.check(move)
    assert hit is not None and 'the arm\'s' in hit.obstacle and 0.0 < hit.time <= move.duration


def test_a_trajectory_is_checked_so_densely_that_no_link_moves_a_centimetre_between_checks(cycle, caps):
    plan = cycle.plan((HOME, 0 * HOME, 0 * HOME), synthetic_tree(3, seed=2)[0])
    checker = CollisionChecker(caps)
    t, q = checker.samples(plan.trajectory)
    seg = caps.segments(q)
    assert np.linalg.norm(np.diff(seg, axis=0), axis=-1).max() <= 0.01
    assert t[0] == 0.0 and t[-1] == pytest.approx(plan.duration)
    # Along its way too: every capsule end's travel between two checks (on a sampling far denser) is at most
    # a centimetre; where the arm rests (the grasp, the release) a configuration or two stand for the dwell.
    dense = np.union1d(np.linspace(0.0, plan.duration, 40 * len(t)), t)
    ends = caps.segments(plan.trajectory.sample(dense)[0])
    travel = np.concatenate([np.zeros((1,) + ends.shape[1:3]),
                             np.cumsum(np.linalg.norm(np.diff(ends, axis=0), axis=-1), axis=0)])
    at = np.searchsorted(dense, t)
    assert np.diff(travel[at], axis=0).max() <= 0.01 + 1e-4
    grasp = next(s for s in plan.segments if s.label == 'grasp')
    assert ((t > grasp.start + 1e-6) & (t < grasp.start + grasp.duration - 1e-6)).sum() <= 2


def test_the_canopy_bound_never_exceeds_the_distance_to_its_points():
    rng = np.random.default_rng(0)
    points = rng.uniform(0.0, 0.5, (5000, 3))
    canopy = Canopy(points)
    queries = rng.uniform(-0.3, 0.8, (2000, 3))
    true = np.linalg.norm(queries[:, None] - points[None], axis=-1).min(axis=1)
    assert np.all(canopy.lower_bound(queries) <= true)
    with pytest.raises(ValueError, match='finite point'):
        Canopy(np.full((3, 3), np.nan))


# -- the pick cycle around branches ---------------------------------------------------------------------------------

def apple():
    return synthetic_tree(10, seed=1)[1]


def test_a_branch_across_the_straight_approach_is_passed_from_another_direction(cycle, caps):
    T = apple()
    a = T[:3, 3]
    scene = Scene.from_dict({'branches': [branch('low branch', a + [-0.08, -0.4, -0.07], a + [-0.08, 0.4, -0.07])]})
    checker = CollisionChecker(caps, scene)
    straight = PickCycle(cycle.planner, dataclasses.replace(cycle.s, approach_cone=0.0), checker)
    start = (HOME, 0 * HOME, 0 * HOME)
    with pytest.raises(approaches.Blocked, match='low branch'):
        straight.plan(start, T)
    plan = PickCycle(cycle.planner, cycle.s, checker).plan(start, T)
    assert 0.0 < plan.extra['approach_tilt'] <= np.radians(45.0) + 1e-9
    assert plan.extra['approach'].startswith('approached ')
    assert checker.check(plan.trajectory, Allowed(a, cycle.s.apple_region)) is None
    # The grasp is at the apple, along the approach taken.
    q_grasp = plan.trajectory.sample([plan.extra['grasp_start']])[0][0, :6]
    np.testing.assert_allclose(cycle.arm.fk(q_grasp)[:3, 3], a, atol=1e-4)


def test_a_twig_just_above_the_apple_is_passed_by_pulling_the_apple_straight_back_out(cycle, caps):
    """On the branch scenario's tree (seed 1) a twig hung in front of a higher apple lies just above apple 1: the
    way in is clear, but the lift straight up meets the twig at every grasp of the cone. The apple is pulled
    straight back out along the approach instead, and the plan says so."""
    from conftest import shipped_orchard
    tree = shipped_orchard(12, seed=1)
    T = tree.apples[1]
    a = T[:3, 3]
    checker = CollisionChecker(caps, tree.scene)
    start = (HOME, 0 * HOME, 0 * HOME)
    pick = PickCycle(cycle.planner, cycle.s, checker)
    as_set = pick._plan(start, T, None, False, True)             # the settings' lift: straight up
    assert 'twig' in str(checker.check(as_set.trajectory, Allowed(a, cycle.s.apple_region)))
    plan = pick.plan(start, T)
    assert plan.extra['approach'].endswith('lifted out straight back')
    lift = next(x for x in plan.segments if x.label == 'P3 lift and detach')
    assert lift.method == 'back'
    assert checker.check(plan.trajectory, Allowed(a, cycle.s.apple_region)) is None
    # Out along the grasp axis (short of P3 by the blend radius, where the transfer takes over).
    grasp = cycle.arm.fk(plan.trajectory.sample([plan.extra['grasp_start']])[0][0, :6])
    top = cycle.arm.fk(plan.trajectory.sample([lift.start + lift.duration])[0][0, :6])
    out = grasp[:3, 3] - top[:3, 3]
    assert np.linalg.norm(np.cross(out, grasp[:3, 2])) < 1e-3
    assert out @ grasp[:3, 2] > cycle.s.lift_height - cycle.s.blend_radius - 1e-3


def test_an_apple_enclosed_by_the_canopy_is_refused_with_what_blocks_it(cycle, caps):
    T = apple()
    rng = np.random.default_rng(1)
    shell = rng.normal(size=(4000, 3))
    shell = T[:3, 3] + 0.12 * shell / np.linalg.norm(shell, axis=1)[:, None]
    checker = CollisionChecker(caps, canopy=Canopy(shell))
    with pytest.raises(approaches.Blocked, match=r'the canopy blocks every approach within 45°'):
        PickCycle(cycle.planner, cycle.s, checker).plan((HOME, 0 * HOME, 0 * HOME), T)


def test_an_approach_out_of_reach_is_replaced_by_one_within_the_cone(cycle):
    """The search serves kinematic failures too: here the requested grasp pose fails (as a line that
    needs another IK branch midway does), and a tilted one is planned instead."""
    T = apple()
    pick = PickCycle(cycle.planner, cycle.s)

    def plan_one(pose, detours=None, branch=None, slow=None, lift=None):
        if np.allclose(pose, T):
            raise Unreachable('path fails at t = 0.244 s: wrist_3_joint would jump 0.363 rad')
        return pick._plan((HOME, 0 * HOME, 0 * HOME), pose, None, False, True, detours, branch, slow, lift=lift)
    plan = approaches.clear_cycle(pick, plan_one, T)
    assert plan.extra['approach_tilt'] > 0.0 or plan.extra['approach_roll'] != 0.0
    narrow = PickCycle(cycle.planner, dataclasses.replace(cycle.s, approach_cone=0.0))
    with pytest.raises(Unreachable, match='would jump'):
        approaches.clear_cycle(narrow, plan_one, T)


def test_a_line_that_would_jump_on_the_branch_nearest_home_is_planned_on_another_branch(cycle):
    """The grasp is kept as requested: the line to the apple that needs a joint to jump on the IK
    solution nearest home is continuous from another solution at its start."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat([-0.1539, -0.3374, 0.0834, 0.925]).as_matrix()
    T[:3, 3] = [0.653, 0.193, 0.7]
    start = (HOME, 0 * HOME, 0 * HOME)
    narrow = PickCycle(cycle.planner, dataclasses.replace(cycle.s, approach_cone=0.0))
    with pytest.raises(Unreachable, match='would jump'):
        narrow._plan(start, T, None, False, True)
    plan = narrow.plan(start, T)
    assert plan.extra['approach'] == 'approached as requested on another IK branch of the arm'
    assert plan.extra['approach_tilt'] == 0.0 and plan.extra['approach_roll'] == 0.0
    q_grasp = plan.trajectory.sample([plan.extra['grasp_start']])[0][0, :6]
    np.testing.assert_allclose(cycle.arm.fk(q_grasp), T, atol=1e-4)
    others = approaches.other_branches(narrow, approaches.candidates(T, 0.0)[0])
    assert others and all(cycle.arm.within_limits(a.branch) for a in others)


def test_the_candidates_stay_within_the_cone_and_start_with_the_requested_pose():
    T = apple()
    found = approaches.candidates(T, np.radians(45.0))
    assert np.allclose(found[0].pose, T)
    tilts = [np.degrees(np.arccos(np.clip(c.pose[:3, 2] @ T[:3, 2], -1, 1))) for c in found]
    assert max(tilts) <= 45.0 + 1e-6 and min(tilts[1 + len(approaches.ROLLS) - 1:]) >= 15.0 - 1e-6
    assert all(np.allclose(c.pose[:3, 3], T[:3, 3]) for c in found)
    assert approaches.candidates(T, 0.0)[1:] == [] or all(c.tilt == 0.0 for c in approaches.candidates(T, 0.0))


def test_an_orchard_tree_is_seeded_its_apples_clear_of_its_branches_and_some_hang_behind_a_twig(cycle, caps):
    from conftest import shipped_orchard

    from picking_core.kinematics.capsules import segment_distances
    from picking_core.orchard import APPLE_GAP
    a, b = shipped_orchard(16, seed=3), shipped_orchard(16, seed=3)
    assert np.array_equal(a.cloud, b.cloud) and all(np.array_equal(x, y) for x, y in zip(a.apples, b.apples))
    assert len(a.apples) == 16 and a.blocked
    for T in a.apples:
        p = T[:3, 3]
        for o in a.scene.obstacles:
            if o.ends is not None and not o.name.startswith('twig'):
                assert segment_distances(p, p, o.ends[0], o.ends[1]) - o.radius >= APPLE_GAP - 1e-9
    # Each twig crosses the straight approach of its apple: that cycle is not clear, and is refused
    # when no other approach may be tried.
    checker = CollisionChecker(caps, a.scene, Canopy(a.cloud))
    straight = PickCycle(cycle.planner, dataclasses.replace(cycle.s, approach_cone=0.0), checker)
    for i in a.blocked:
        with pytest.raises(Unreachable):
            straight.plan((HOME, 0 * HOME, 0 * HOME), a.apples[i])


def test_a_wire_across_the_transfer_is_passed_on_a_joint_path_around_it(cycle, caps):
    from picking_core.collision.scene import rod
    T = apple()
    start = (HOME, 0 * HOME, 0 * HOME)
    plan = cycle.plan(start, T)
    transfer = next(s for s in plan.segments if s.label == 'P4 above the box')
    t = transfer.start + 0.5 * transfer.duration
    q0, q1 = np.asarray(plan.trajectory.sample([t, t + 0.05])[0])[:, :6]
    p, ahead = cycle.arm.fk(q0)[:3, 3], cycle.arm.fk(q1)[:3, 3]
    along = (ahead - p) * [1, 1, 0]
    across = np.cross(along / np.linalg.norm(along), [0.0, 0.0, 1.0])
    wire = rod('wire', 'wire', p - 0.2 * across, p + 0.2 * across, 0.003)        # across the tool's way to the box
    checker = CollisionChecker(caps, Scene((wire,)))
    assert checker.check(plan.trajectory) is not None                            # the plan without it hits it
    around = PickCycle(cycle.planner, cycle.s, checker).plan(start, T)
    assert 'P4 above the box through' in around.extra['detours']
    assert checker.check(around.trajectory, Allowed(T[:3, 3], cycle.s.apple_region)) is None


def test_a_pick_from_where_the_way_home_crosses_a_branch_goes_around_it(cycle, caps):
    T = apple()
    a = T[:3, 3]
    checker = CollisionChecker(caps, Scene.from_dict(
        {'branches': [branch('low branch', a + [-0.08, -0.4, -0.06], a + [-0.08, 0.4, -0.06])]}))
    away = np.eye(4)
    away[:3, :3] = Rotation.from_euler('x', 180.0, degrees=True).as_matrix()
    away[:3, 3] = [0.6, 0.4, 0.45]                   # tool down beyond the branch: home is across it
    q0 = cycle.arm.check_reachable(away, seed=HOME)
    start, allowed = (q0, 0 * q0, 0 * q0), Allowed(a, cycle.s.apple_region)
    plain = PickCycle(cycle.planner, cycle.s).plan(start, T)
    assert approaches.check(checker, plain, allowed).part == 'P0 home'
    plan = PickCycle(cycle.planner, cycle.s, checker).plan(start, T)
    assert 'P0 home through' in plan.extra['detours']
    assert checker.check(plan.trajectory, allowed) is None


def test_a_joint_path_is_found_around_an_obstacle_and_shortcut():
    from picking_core.planning.joint_path import NoPath, clear_edge, rrt_connect
    # Two joints; a wall at 0.4 < q0 < 0.6 for q1 < 0.8: the way from (0, 0) to (1, 0) goes over it.
    def colliding(q):
        q = np.atleast_2d(q)
        return (q[:, 0] > 0.4) & (q[:, 0] < 0.6) & (q[:, 1] < 0.8)
    lower, upper = np.array([-1.0, -1.0]), np.array([2.0, 2.0])
    path = rrt_connect(colliding, [0.0, 0.0], [1.0, 0.0], lower, upper)
    assert np.allclose(path[0], [0, 0]) and np.allclose(path[-1], [1, 0]) and len(path) >= 3
    assert all(clear_edge(colliding, a, b) for a, b in zip(path[:-1], path[1:]))
    assert path[:, 1].max() >= 0.8
    with pytest.raises(NoPath, match='not clear'):
        rrt_connect(colliding, [0.5, 0.0], [1.0, 0.0], lower, upper)
    with pytest.raises(NoPath, match='no collision-free joint path'):
        rrt_connect(lambda q: (np.atleast_2d(q)[:, 0] > 0.4) & (np.atleast_2d(q)[:, 0] < 0.6), [0.0, 0.0],
                    [1.0, 0.0], lower, upper, iterations=200)      # a wall across the whole space


def test_segment_distances_agree_with_sampling_when_either_segment_is_a_point():
    """A sphere is a capsule of no length: as the second segment it was measured from the first's start."""
    from picking_core.kinematics.capsules import segment_distances
    rng = np.random.default_rng(0)
    s = np.linspace(0.0, 1.0, 401)[:, None]
    for k in range(600):
        p0, p1, q0, q1 = rng.normal(size=(4, 3))
        if k % 3 == 0:
            q1 = q0
        elif k % 3 == 1:
            p1 = p0
        sampled = np.min(np.linalg.norm((p0 + s * (p1 - p0))[:, None] - (q0 + s * (q1 - q0))[None], axis=2))
        d = segment_distances(p0, p1, q0, q1)
        assert d <= sampled + 1e-9 and sampled - d < 0.02
