"""The simulator's tree and camera (pure: no rclpy): the apples a tree description gives, made bodies in a
:class:`~picking_core.fruit.FruitWorld` among the scene's fruit box, surfaces and ground; the arm's samples
turned into what the world judges (tool pose, finger opening, link capsules); and the camera's frames,
captured on its clock and released after its latency.
"""

from __future__ import annotations

import heapq
from pathlib import Path

import numpy as np
import yaml

from picking_core.fruit import OPEN, ArmBodies, FruitWorld, Wind

#: m: apples' diameters are drawn in this range (what the gripper's 9 cm opening takes) ...
DIAMETERS = (0.06, 0.085)
#: m: ... and their stems' lengths in this one.
STEMS = (0.03, 0.06)
#: The scene's box an apple is dropped into (its name).
FRUIT_BOX = 'fruit box'


def tree_centres(spec, arm=None, workcell=None, home=None):
    """The apples' centres (N, 3, the arm's base frame) and the tree's scene (or None) of ``spec``: '' (no tree),
    ``orchard N SEED`` (picking_core.orchard's tree among branches, for ``arm`` in ``workcell`` at ``home``),
    ``synthetic N SEED`` (picking_core.harvest's), or a YAML file with ``apples: [[x, y, z], ...]`` (m). ValueError
    naming what is wrong."""
    spec = spec.strip()
    if not spec:
        return np.empty((0, 3)), None
    words = spec.split()
    if words[0] in ('orchard', 'synthetic'):
        if len(words) != 3:
            raise ValueError(f"tree {spec!r}: give '{words[0]} <apples> <seed>'")
        try:
            n, seed = int(words[1]), int(words[2])
        except ValueError:
            raise ValueError(f"tree {spec!r}: the number of apples and the seed are integers") from None
        if n < 0:
            raise ValueError(f'tree {spec!r}: the number of apples must be >= 0')
        if words[0] == 'orchard':
            from picking_core.orchard import orchard_tree
            tree = orchard_tree(n, seed, arm, workcell, home)
            return np.array([T[:3, 3] for T in tree.apples]).reshape(-1, 3), tree.scene
        from picking_core.harvest import synthetic_tree
        return np.array([T[:3, 3] for T in synthetic_tree(n, seed)]).reshape(-1, 3), None
    path = Path(spec)
    if not path.exists():
        raise ValueError(f"tree {spec!r}: no such file (or give 'orchard N SEED' or 'synthetic N SEED')")
    data = yaml.safe_load(path.read_text()) or {}
    try:
        centres = np.array(data['apples'], float).reshape(-1, 3)
    except (KeyError, TypeError, ValueError):
        raise ValueError(f'tree file {spec}: give apples: [[x, y, z], ...] in m') from None
    if not np.all(np.isfinite(centres)):
        raise ValueError(f'tree file {spec}: every apple needs three finite coordinates')
    return centres, None


def fruit_world(centres, scene, seed=0, wind=Wind(), t0=0.0):
    """The apples at ``centres`` as bodies (diameters and stems drawn from ``seed``) among ``scene``'s fruit box
    (ValueError when it has none), other boxes and ground."""
    rng = np.random.default_rng([seed, 7])
    n = len(centres)
    radii = rng.uniform(*DIAMETERS, n) / 2
    stems = rng.uniform(*STEMS, n)
    boxes = [o for o in scene.obstacles if o.kind == 'box']
    fruit_box = next((o for o in boxes if o.name == FRUIT_BOX), None)
    if fruit_box is None:
        raise ValueError(f"the scene has no box named {FRUIT_BOX!r} for the apples to go in")
    ground = [o.hi[2] for o in scene.obstacles if o.kind == 'ground']
    surfaces = [(o.name, o.lo, o.hi) for o in boxes if o is not fruit_box]
    return FruitWorld(centres, radii, stems, (fruit_box.lo, fruit_box.hi), surfaces,
                      max(ground) if ground else -np.inf, wind, t0=t0)


class ArmSamples:
    """What the world judges of the arm (``arm``: an ArmModel; ``capsules``: its ArmCapsules) from joint
    samples ``q`` (N, all joints, named ``names``): tool poses, finger openings (the position of the joint
    ``gripper``, by default the arm's gripper joint; without one the fingers stay OPEN apart), and the segments
    of the bodies that touch apples (:class:`~picking_core.fruit.ArmBodies`), with their ``radii`` and
    ``names``."""

    def __init__(self, arm, capsules, names, gripper=None):
        self.arm, self.bodies = arm, ArmBodies(capsules)
        gripper = gripper or arm.gripper_joint
        self.gripper = names.index(gripper) if gripper in names else None
        self.radii, self.names = self.bodies.radii, self.bodies.names

    def __call__(self, q):
        q = np.atleast_2d(np.asarray(q, float))
        openings = q[:, self.gripper] if self.gripper is not None else np.full(len(q), OPEN)
        tools, links = self.bodies(q[:, :self.arm.dof], openings)
        return tools, openings, links


class Frames:
    """The camera's clock: captures every ``1 / rate`` s from ``t0``, each released ``latency`` s after it."""

    def __init__(self, rate, latency, t0):
        self.period, self.latency = 1.0 / rate, latency
        self.next_capture = t0
        self._pending = []               # (due, serial, frame)
        self._serial = 0

    def hold(self, t_capture, frame):
        heapq.heappush(self._pending, (t_capture + self.latency, self._serial, frame))
        self._serial += 1

    def due(self, now):
        """The frames whose time to go has come, oldest first."""
        out = []
        while self._pending and self._pending[0][0] <= now:
            out.append(heapq.heappop(self._pending)[2])
        return out

    def wake(self):
        """When something is next to do: the next capture or release."""
        return min([self.next_capture] + ([self._pending[0][0]] if self._pending else []))
