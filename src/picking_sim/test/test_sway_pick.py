"""A swaying apple picked, by the fruit world's count: aimed at the sway fit's prediction and re-targeted at the
camera's rate it lands in the box with the fingers closing near its true centre; tracking it without prediction
closes farther off, not tracking it at all misses it; a still apple gets today's cycle."""

import pathlib

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from picking_core.collision import Scene
from picking_core.fruit import Wind
from picking_core.harvest import SIDEWAYS
from picking_core.kinematics.capsules import ArmCapsules
from picking_core.platform import load_harvest
from picking_description import default_urdf, scene_path
from picking_sim.orchard import ArmSamples, fruit_world
from picking_sim.sway_pick import pick_swaying

CONFIG = pathlib.Path(__file__).resolve().parents[3] / 'config'
APPLE = np.array([0.70, 0.15, 0.65])
ROTATION = Rotation.from_euler('xyz', SIDEWAYS).as_matrix()
SEEDS = range(4)


@pytest.fixture(scope='module')
def arm():
    cycle = load_harvest(default_urdf(), [CONFIG / 'planner.yaml', CONFIG / 'pick_cycle.yaml']).cycle
    samples = ArmSamples(cycle.arm, ArmCapsules.from_arm(cycle.arm), [*cycle.arm.joint_names, 'gripper_joint'])
    return cycle, samples, Scene.from_yaml(scene_path('workcell'))


def _picks(arm, mode, push=2.4, direction=np.pi / 2):
    cycle, samples, scene = arm
    out = []
    for seed in SEEDS:
        world = fruit_world(APPLE[None], scene, seed=seed,
                            wind=Wind(amplitude=push, frequency=1.0, direction=direction, seed=seed))
        out.append(pick_swaying(cycle, samples, world, 0, ROTATION, mode, seed=seed))
    return out


def test_an_apple_swaying_30_mm_at_1_hz_is_picked_where_it_will_be(arm):
    predicted, latest, fixed = (_picks(arm, mode) for mode in ('predicted', 'latest', 'fixed'))
    assert all(r.in_box and not r.bruised for r in predicted), predicted
    miss = {name: np.median([r.miss for r in runs if r.miss is not None])
            for name, runs in (('predicted', predicted), ('latest', latest), ('fixed', fixed))}
    # (Margins for the noise of four runs: the benchmark's row 11 gives the figures over more.)
    assert miss['predicted'] < 0.004 and miss['predicted'] < miss['latest'] / 2 < miss['fixed'] / 2, miss
    assert sum(r.in_box for r in fixed) < len(SEEDS)                   # not tracked, the apple is missed
    assert all(r.plans > 1 for r in predicted) and all(r.plans == 1 for r in fixed)


def test_a_still_apple_gets_todays_cycle(arm):
    aimed, today = _picks(arm, 'predicted', push=0.0), _picks(arm, 'fixed', push=0.0)
    assert all(r.in_box and r.miss < 0.002 for r in aimed), aimed
    for a, b in zip(aimed, today):
        assert a.cycle == pytest.approx(b.cycle, rel=0.02)


def test_an_unknown_aim_is_refused(arm):
    cycle, samples, scene = arm
    world = fruit_world(APPLE[None], scene)
    with pytest.raises(ValueError, match='unknown mode'):
        pick_swaying(cycle, samples, world, 0, ROTATION, 'guess')
