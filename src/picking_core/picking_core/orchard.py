"""A seeded synthetic orchard tree with branches (pure core): what branch-aware picking is shown
and measured on.

A trellised tree in front of the arm: the trunk and scaffold branches (in the scene, as capsules),
two trellis wires (thin cylinders), and apples among them, grasped along +x as a synthetic tree's.
A fraction of the apples hang behind a twig, across the straight approach, close enough that the
gripper would touch it (in the scene, and in the cloud). The cloud holds the woody parts (twigs,
scaffolds, the trunk) a depth camera would see once the apples, the targets, are taken out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from .collision import Scene
from .collision.scene import rod
from .harvest import SIDEWAYS
from .kinematics.capsules import ArmCapsules, segment_distances

#: m: an apple's centre at least this far from a scene branch's or wire's surface.
APPLE_GAP = 0.09
#: m: the box the apples hang in (a synthetic tree's), and how far apart they are at least.
LOW, HIGH, SPACING = (0.55, -0.35, 0.40), (0.80, 0.35, 0.85), 0.10
#: Fraction of the apples a twig hangs in front of.
TWIG_SHARE = 0.5
#: m: a twig's surface at least this far from the arm resting at home.
HOME_GAP = 0.12
#: m: twigs hang only in front of apples at least this deep in the canopy (x).
TWIG_DEPTH = 0.70
#: m: the way in to every other apple, this long along -x from it, stays 10 cm from a twig.
OTHERS_REACH = 0.15
#: m: points of the cloud on a surface, about this far apart.
CLOUD_STEP = 0.012


@dataclass(frozen=True)
class Orchard:
    """A tree: its ``scene`` (the workcell, trunk, scaffolds, wires), its apples (4x4 grasp poses),
    the ``twigs`` (ends (T, 2, 3) and radii, m) and the ``cloud`` (N, 3) a camera sees, m,
    ``blocked``: the indices of the apples a twig crosses the straight approach of."""

    scene: Scene
    apples: list
    twigs: np.ndarray
    twig_radius: np.ndarray
    cloud: np.ndarray
    blocked: tuple


def orchard_tree(n, seed, arm, workcell, home):
    """A tree of ``n`` apples from ``seed`` (ValueError when they do not fit among its branches) in front of
    ``arm`` (an ArmModel) standing in ``workcell`` (a Scene with its ground), its twigs clear of the arm
    resting at ``home`` (rad): the arm stands where it can move."""
    rng = np.random.default_rng(seed)
    capsules = ArmCapsules.from_arm(arm)
    at_home = capsules.segments(np.asarray(home, float))[0]
    ground = min(o.hi[2] for o in workcell.obstacles if o.kind == 'ground')
    rods = [rod('trunk', 'branch', [1.0, 0.0, ground], [1.0, 0.0, 1.2], 0.06),
            rod('wire low', 'wire', [0.92, -1.5, 0.45], [0.92, 1.5, 0.45], 0.002),
            rod('wire high', 'wire', [0.92, -1.5, 0.82], [0.92, 1.5, 0.82], 0.002)]
    for k, (z, side) in enumerate(zip(rng.uniform(0.3, 0.9, 4), (1, -1, 1, -1))):
        # Along the row (a fruiting wall), leaning a little toward the arm.
        end = [rng.uniform(0.84, 0.92), side * rng.uniform(0.4, 0.6), z + rng.uniform(0.05, 0.15)]
        rods.append(rod(f'scaffold {k + 1}', 'branch', [1.0, 0.0, z], end, rng.uniform(0.02, 0.03)))
    scene = Scene(tuple(rods), workcell.frame).merged(workcell.obstacles, f'orchard tree {seed}')
    centres = np.empty((0, 3))
    for p in rng.uniform(LOW, HIGH, (400 * n, 3)):
        if len(centres) == n:
            break
        if len(centres) and np.min(np.sum((centres - p) ** 2, axis=1)) < SPACING ** 2:
            continue
        if all(segment_distances(p, p, r.ends[0], r.ends[1]) - r.radius >= APPLE_GAP for r in rods):
            centres = np.vstack([centres, p])
    if len(centres) < n:
        raise ValueError(f'{n} apples do not fit among the branches of tree {seed}')
    apples = list(np.repeat(np.eye(4)[None], n, axis=0))
    for T, p in zip(apples, centres):
        T[:3, :3] = Rotation.from_euler('xyz', SIDEWAYS).as_matrix()
        T[:3, 3] = p
    twigs, radii, blocked = [], [], []
    for i in rng.permutation(n):
        if len(twigs) == int(round(TWIG_SHARE * n)):
            break
        a = centres[i]
        if a[0] < TWIG_DEPTH:
            continue                                    # in the arm's way to every apple, not one
        # Across the straight approach (along +x), in front of the apple and below its grasp axis: near
        # enough that the straight gripper touches it, far enough that one tilted from above can pass.
        yaw = rng.uniform(-0.5, 0.5)
        half = 0.1 * np.array([np.sin(yaw), np.cos(yaw), 0.0])
        middle = a + [-rng.uniform(0.085, 0.10), 0.0, -rng.uniform(0.065, 0.08)]
        ends = np.array([middle - half, middle + half])
        others = np.delete(centres, i, axis=0)
        if len(others) and segment_distances(others - [OTHERS_REACH, 0.0, 0.0], others, ends[0], ends[1]).min() < 0.08:
            continue                                    # it would block another apple too
        arm = segment_distances(at_home[:, 0], at_home[:, 1], ends[0], ends[1]) - capsules.radius
        if arm.min() < HOME_GAP:
            continue                                    # it would reach into the arm at rest
        twigs.append(ends)
        radii.append(0.01)
        blocked.append(int(i))
    twigs = np.array(twigs).reshape(-1, 2, 3)
    radii = np.array(radii)
    cloud = np.vstack([_surface(e[0], e[1], r, rng) for e, r in zip(twigs, radii)]
                      + [_surface(r.ends[0], r.ends[1], r.radius, rng) for r in rods if r.kind == 'branch'])
    # The twigs are in the scene too, so that the simulator, which watches the scene, sees them touched.
    scene = Scene(scene.obstacles + tuple(rod(f'twig {k + 1}', 'branch', e[0], e[1], r)
                                          for k, (e, r) in enumerate(zip(twigs, radii))), scene.frame)
    return Orchard(scene, apples, twigs, radii, cloud, tuple(sorted(blocked)))


def _surface(p0, p1, radius, rng):
    """Points on the surface of the capsule ``p0``-``p1`` of ``radius``, about CLOUD_STEP apart, m."""
    axis = p1 - p0
    length = np.linalg.norm(axis)
    n_along = max(2, int(length / CLOUD_STEP))
    n_round = max(4, int(2 * np.pi * radius / CLOUD_STEP))
    z = axis / length
    x = np.cross(z, [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    s = rng.uniform(0.0, 1.0, n_along * n_round)
    phi = rng.uniform(0.0, 2 * np.pi, n_along * n_round)
    return p0 + s[:, None] * axis + radius * (np.cos(phi)[:, None] * x + np.sin(phi)[:, None] * y)

