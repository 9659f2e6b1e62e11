"""Row 10: apples counted by the world. The branch scenario's orchard trees harvested by the shipped planner, from
the apples' true poses and from what the simulator's camera sees of them (3 mm noise, and none), and from the true
poses and the noisy camera with the pick cycle's ``apple_pass_speed`` on (joint moves go around apples they would
pass fast, or are slowed past them); each planned
harvest played through the simulator's fruit world (picking_core.fruit, as picking-sim judges the measured joint
states), which counts the apples in the box, the bruised and the dropped. The arm follows its plan exactly here:
the servo's lag, the camera's latency and the swaying of a gust are the simulator's, not this row's."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from picking_bringup.shipped import shipped_harvest, shipped_orchard
from picking_core.camera import CameraSettings, DepthCamera, look_at
from picking_core.collision import CollisionChecker
from picking_core.fruit import Fate
from picking_core.fruit_map import FruitMap
from picking_core.harvest import Harvest
from picking_core.kinematics.capsules import ArmCapsules
from picking_core.pick_cycle import GRIPPER_OPEN, PickCycle
from picking_sim.orchard import ArmSamples, fruit_world
from picking_sim.parameters import PARAMS

#: The branch scenario's trees (demo.yaml: orchard_apples, orchard_seed 1) and two more seeds.
APPLES, SEEDS = 12, (1, 2, 3)
#: s the camera watches the tree from home before the harvest is planned, at its rate.
LOOK = 1.0
#: s between the arm's samples played through the world (the simulator's joint_states period).
STEP = 0.01
#: m/s: the pick cycle's apple_pass_speed of the last variant (the shipped configuration leaves it off).
PASS_SPEED = 0.9


def _camera_default(name):
    return next(p.default for p in PARAMS if p.name == name)


def _seen(orchard, world, samples, home, noise, seed):
    """The grasp poses of the apples the fruit map confirms after the camera watched the tree for LOOK s from home
    (the arm and the tree's branches hide what they hide); the number of confirmed apples."""
    settings = CameraSettings(noise=noise, seed=seed)
    camera = DepthCamera(look_at(_camera_default('camera.position'), _camera_default('camera.look_at')), settings)
    ends, radii = orchard.scene.rods()
    _, _, links = samples(np.append(home, GRIPPER_OPEN)[None])
    blockers, blocker_radii = np.concatenate([ends, links[0]]), np.concatenate([radii, samples.radii])
    fruit_map = FruitMap(branches=(ends, radii))
    present = world.fate == Fate.ON_TREE
    R, o = camera.mount[:3, :3], camera.origin
    for t in np.arange(0.0, LOOK, 1.0 / settings.rate):
        seen = camera.capture(world.p.copy(), world.radius, present, blockers, blocker_radii)
        positions = np.array([o + R @ d.position for d in seen]).reshape(-1, 3)
        covariances = np.array([R @ np.eye(3) * d.sigma ** 2 @ R.T for d in seen]).reshape(-1, 3, 3)
        fruit_map.update(t, positions, covariances, np.array([d.diameter for d in seen]),
                         np.array([d.score for d in seen]))
    return fruit_map.grasp_poses()


def _one(harvest, orchard, seed, source):
    """One tree harvested from ``source`` ('truth' or a camera noise in m): the world's counts, the planned
    duration, the apples the harvest started from and those of them within reach."""
    samples = ArmSamples(harvest.arm, ArmCapsules.from_arm(harvest.arm),
                         [*harvest.arm.joint_names, 'gripper_joint'])
    centres = np.array([T[:3, 3] for T in orchard.apples])
    world = fruit_world(centres, orchard.scene, seed=seed)
    home = np.asarray(harvest.home, float)
    apples = list(orchard.apples) if source == 'truth' else _seen(orchard, world, samples, home, source, seed)
    z = np.zeros(harvest.arm.dof)
    plan = harvest.plan((home, z, z), apples)
    trajectory = plan.plan.trajectory
    t = np.arange(0.0, trajectory.duration + STEP, STEP)
    q = trajectory.sample(np.minimum(t, trajectory.duration))[0]
    tools, openings, links = samples(q)
    world.observe(t + STEP, tools, openings, links, samples.radii, samples.names)
    reachable = len(harvest.reach(list(orchard.apples))[0])
    return world.counts(), trajectory.duration, len(apples), reachable


def counted_by_the_world():
    """Rows 10: apples in the box an hour, success of the reachable and of the detected, damage, per source."""
    shipped = shipped_harvest()
    rows = []
    for label, source, pass_speed in (('true poses', 'truth', 0.0), ('camera, 3 mm noise', 0.003, 0.0),
                                      ('camera, no noise', 0.0, 0.0),
                                      (f'true poses, apples passed at ≤ {PASS_SPEED:g} m/s', 'truth', PASS_SPEED),
                                      (f'camera, 3 mm noise, apples passed at ≤ {PASS_SPEED:g} m/s', 0.003, PASS_SPEED)):
        total = {'in_the_box': 0, 'bruised': 0, 'dropped': 0, 'knocked': 0}
        seconds = started = reachable = 0
        for seed in SEEDS:
            orchard = shipped_orchard(APPLES, seed)
            checker = CollisionChecker(ArmCapsules.from_arm(shipped.arm), orchard.scene)
            settings = replace(shipped.cycle.s, apple_pass_speed=pass_speed or shipped.cycle.s.apple_pass_speed)
            harvest = Harvest(PickCycle(shipped.cycle.planner, settings, checker))
            counts, duration, n, ok = _one(harvest, orchard, seed, source)
            for k in total:
                total[k] += counts[k]
            seconds, started, reachable = seconds + duration, started + n, reachable + ok
            print(f'  {label}, tree {seed}: {counts["in_the_box"]} of {APPLES} in the box ({n} to pick, {ok} '
                  f'reachable), {counts["bruised"]} bruised, {counts["dropped"]} dropped, {duration:.1f} s',
                  flush=True)
        n_all = APPLES * len(SEEDS)
        per_hour = total['in_the_box'] / seconds * 3600
        of_reachable = 100 * total['in_the_box'] / max(reachable, 1)
        of_detected = 100 * total['in_the_box'] / max(started, 1)
        damage = 100 * total['bruised'] / n_all
        ok = per_hour >= 850 and of_reachable >= 97 and total['bruised'] == 0
        rows.append(['10', f'apples in the box an hour, the world\'s count ({label})', f'{per_hour:.0f}/h',
                     f'{total["in_the_box"]} of {n_all} apples of {len(SEEDS)} orchard trees in the box in '
                     f'{seconds:.0f} s planned: {of_reachable:.0f} % of the {reachable} reachable, {of_detected:.0f} % '
                     f'of the {started} the harvest started from; {damage:.1f} % bruised ({total["bruised"]}), '
                     f'{total["dropped"]} dropped, {total["knocked"]} knocked', '≥ 850/h, ≥ 97 %, 0 bruised',
                     'meets' if ok else 'misses'])
    return rows
