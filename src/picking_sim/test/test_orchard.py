"""The simulator's tree and camera clock without ROS: tree descriptions, the arm as the apples see it (fingers at
the opening), and frames released after their latency in capture order."""

from dataclasses import replace

import numpy as np
import pytest

from picking_core.collision import Scene
from picking_core.collision.fruit import Neighbours
from picking_core.kinematics import ArmModel
from picking_core.kinematics.capsules import ArmCapsules
from picking_core.pick_cycle import HOME_POSITIONS
from picking_description import default_urdf, scene_path
from picking_sim.orchard import ArmSamples, Frames, fruit_world, tree_centres


@pytest.fixture(scope='module')
def arm():
    return ArmModel.from_urdf(default_urdf())


def test_trees_come_from_the_generators_or_a_file_and_bad_ones_are_refused_with_the_reason(arm, tmp_path):
    workcell = Scene.from_yaml(scene_path('workcell'))
    centres, scene = tree_centres('orchard 6 1', arm, workcell, HOME_POSITIONS)
    assert centres.shape == (6, 3) and any(o.name.startswith('twig') or o.kind == 'branch' for o in scene.obstacles)
    assert tree_centres('synthetic 4 2')[0].shape == (4, 3) and tree_centres('')[0].shape == (0, 3)
    path = tmp_path / 'tree.yaml'
    path.write_text('apples: [[0.7, 0.1, 0.6], [0.65, -0.1, 0.5]]\n')
    assert tree_centres(str(path))[0] == pytest.approx(np.array([[0.7, 0.1, 0.6], [0.65, -0.1, 0.5]]))
    for bad, why in (('orchard 6', 'give'), ('synthetic x 1', 'integers'), ('nowhere.yaml', 'no such file')):
        with pytest.raises(ValueError, match=why):
            tree_centres(bad, arm, workcell, HOME_POSITIONS)
    path.write_text('apples: [[0.7, .nan, 0.6]]\n')
    with pytest.raises(ValueError, match='finite'):
        tree_centres(str(path))


def test_the_world_needs_the_scenes_fruit_box():
    with pytest.raises(ValueError, match='fruit box'):
        fruit_world(np.zeros((1, 3)), Scene())
    w = fruit_world(np.array([[0.7, 0.1, 0.6]]), Scene.from_yaml(scene_path('workcell')), seed=3)
    assert 0.03 <= w.radius[0] <= 0.0425 and w.box[0][2] < w.box[1][2] and w.ground_z == pytest.approx(-0.45)


def test_the_fingers_stand_at_the_opening_either_side_of_the_grasp_point(arm):
    samples = ArmSamples(arm, ArmCapsules.from_arm(arm), list(arm.all_joint_names))
    tools, openings, links = samples(np.array([[*HOME_POSITIONS, 0.07]]))
    tool = tools[0]
    fingers = (links[0, -2:] - tool[:3, 3]) @ tool[:3, :3]               # in the tool frame
    assert fingers[:, :, 0] == pytest.approx(np.array([[0.045, 0.045], [-0.045, -0.045]]))
    assert fingers[:, 0, 2] == pytest.approx([-0.06, -0.06]) and fingers[:, 1, 2] == pytest.approx([0.0, 0.0])
    assert openings[0] == 0.07 and samples.names[-2:] == ['a finger', 'a finger']
    assert 'wrist_3_link' not in samples.names and len(samples.radii) == links.shape[1]
    # The planner keeps the apples on the tree from the same bodies (picking_core.collision.fruit.Neighbours).
    planner = Neighbours(ArmCapsules.from_arm(arm), [[0.0, 0.0, 0.0]], 0.9)
    assert np.allclose(planner._segments(np.array([[*HOME_POSITIONS, 0.07]]))[:, planner.fine], links)
    assert planner.bodies.names == samples.names and np.allclose(planner.radii[planner.fine], samples.radii)


def test_a_harvest_passing_apples_slowly_presses_none_off_its_stem():
    """A dense tree (the demo's kind: 20 apples 8 cm apart) harvested with the apples passed at <= 0.9 m/s, played
    through the fruit world: no link drags an apple off its stem (two fingers did, pressing from above at 0.7 m/s,
    before the planner felt the fingers), none is bruised, all are in the box."""
    from picking_bringup.shipped import shipped_harvest
    from picking_core.collision import CollisionChecker
    from picking_core.harvest import Harvest, synthetic_tree
    from picking_core.pick_cycle import PickCycle
    shipped = shipped_harvest()
    workcell = Scene.from_yaml(scene_path('workcell'))
    checker = CollisionChecker(ArmCapsules.from_arm(shipped.arm), workcell)
    harvest = Harvest(PickCycle(shipped.cycle.planner, replace(shipped.cycle.s, apple_pass_speed=0.9), checker))
    apples = synthetic_tree(20, 11)
    home, z = np.asarray(harvest.home, float), np.zeros(harvest.arm.dof)
    plan = harvest.plan((home, z, z), list(apples)).plan
    world = fruit_world(np.array([T[:3, 3] for T in apples]), workcell, seed=11)
    samples = ArmSamples(harvest.arm, ArmCapsules.from_arm(harvest.arm), list(plan.joint_names))
    t = np.arange(0.0, plan.duration + 0.01, 0.01)
    events = world.observe(t + 0.01, *samples(plan.trajectory.sample(np.minimum(t, plan.duration))[0]),
                           samples.radii, samples.names)
    assert not [e.words for e in events if e.kind in ('knocked off', 'bruised', 'dropped')]
    assert world.counts()['in_the_box'] == 20


def test_frames_go_out_after_their_latency_in_capture_order():
    clock = Frames(rate=30.0, latency=0.05, t0=10.0)
    assert clock.wake() == 10.0
    clock.hold(10.0, 'a')
    clock.hold(10.033, 'b')
    assert clock.due(10.04) == [] and clock.wake() == pytest.approx(10.0)   # the next capture is due first
    clock.next_capture = 10.066
    assert clock.wake() == pytest.approx(10.05) and clock.due(10.09) == ['a', 'b']


@pytest.mark.parametrize('lead', [0.0, 0.2])
def test_an_apple_let_go_on_the_line_into_the_box_lands_in_it_unbruised(lead):
    """The shipped pick cycle played through the fruit world: with the release begun on the line into the box
    (``release_lead``) the apple still ends in the box, unbruised, and the cycle is shorter by what the dwell lost."""
    from picking_bringup.shipped import shipped_harvest
    from picking_core.harvest import SIDEWAYS
    from picking_core.pick_cycle import PickCycle
    from scipy.spatial.transform import Rotation
    shipped = shipped_harvest()
    cycle = PickCycle(shipped.cycle.planner, replace(shipped.cycle.s, release_lead=lead))
    apple = np.array([0.70, 0.15, 0.65])
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = Rotation.from_euler('xyz', SIDEWAYS).as_matrix(), apple
    home = np.asarray(cycle.s.home_positions, float)
    plan = cycle.plan((home, 0 * home, 0 * home), T)
    world = fruit_world(apple[None], Scene.from_yaml(scene_path('workcell')), seed=1)
    samples = ArmSamples(cycle.arm, ArmCapsules.from_arm(cycle.arm), list(plan.joint_names))
    t = np.arange(0.0, plan.duration + 1.0, 0.005)
    tools, openings, links = samples(plan.trajectory.sample(np.minimum(t, plan.duration))[0])
    events = world.observe(t, tools, openings, links, samples.radii, samples.names)
    assert world.counts()['in_the_box'] == 1 and not world.bruised[0], [e.words for e in events]
    released = next(e.t for e in events if e.kind == 'released')
    seg = {s.label: s for s in plan.segments}
    into_box = seg['P5 into the box']
    # The fingers open from release_start, on the line into the box when led, and let go before the arm rises.
    assert plan.extra['release_start'] == pytest.approx(into_box.start + into_box.duration - min(lead, into_box.duration))
    assert plan.extra['release_start'] <= released <= seg['release'].start + seg['release'].duration + 0.01
    if lead:
        plain = PickCycle(shipped.cycle.planner, replace(shipped.cycle.s, release_lead=0.0)).plan(
            (home, 0 * home, 0 * home), T)
        assert plan.duration == pytest.approx(plain.duration - min(lead, into_box.duration), abs=1e-9)
