"""The world a planner plans in: its scene and the newest canopy cloud, replaceable while it plans
(pure core of the planner node's collision checking)."""

from __future__ import annotations

import threading

import numpy as np

from ..kinematics.capsules import ArmCapsules
from .checker import CLEARANCE, CollisionChecker
from .scene import Canopy, Scene


class World:
    """The arm's capsules with a :class:`Scene` and a :class:`Canopy` (either replaced whole at
    any time, from any thread), checked with ``clearance`` m; ``enabled`` False checks nothing (a
    baseline that plans as if the world were empty). ``apples``: the centres (n, 3, m in the arm's
    base) of the apples the arm knows hang on the tree (the camera's): not obstacles, passed slowly
    (:class:`~picking_core.collision.fruit.Neighbours`)."""

    def __init__(self, arm, scene=None, clearance=CLEARANCE, enabled=True):
        self._lock = threading.Lock()
        base = CollisionChecker(ArmCapsules.from_arm(arm), scene or Scene(), None, clearance)
        self._checker, self.enabled = base, bool(enabled)
        self.apples = np.zeros((0, 3))

    @property
    def checker(self):
        """The :class:`CollisionChecker` of the newest scene and canopy, or None when disabled."""
        with self._lock:
            return self._checker if self.enabled else None

    @property
    def scene(self):
        """The newest scene."""
        return self._checker.scene

    @property
    def canopy(self):
        return self._checker.canopy

    def replace(self, scene=None, canopy=None, clearance=None, enabled=None, apples=None):
        """A new scene, canopy (a :class:`Canopy`, or points to build one from), clearance, switch or
        apples (centres, (n, 3)); what is not given stays. A canopy is built before the lock is taken: planning
        goes on with the old one meanwhile."""
        if canopy is not None and not isinstance(canopy, Canopy):
            canopy = Canopy(canopy)
        with self._lock:
            changes = {k: v for k, v in (('scene', scene), ('canopy', canopy), ('clearance', clearance))
                       if v is not None}
            if changes:
                self._checker = self._checker.replaced(**changes)
            if enabled is not None:
                self.enabled = bool(enabled)
            if apples is not None:
                self.apples = np.asarray(apples, float).reshape(-1, 3)

    def clear_canopy(self):
        """No canopy cloud (an empty cloud came): the scene and the arm only."""
        with self._lock:
            self._checker = self._checker.replaced()
            self._checker.canopy = None

    def check(self, trajectory, allowed=None, slack=0.0):
        """The first contact along ``trajectory``, or None (also when disabled); ``slack`` m less
        clearance (a plan whose parts were each checked at samples STEP apart is checked again whole,
        at other samples, allowing for how far a link may come closer between two of them)."""
        checker = self.checker
        if checker is None:
            return None
        if slack:
            checker = checker.replaced(clearance=max(0.0, checker.clearance - slack))
        return checker.check(trajectory, allowed)

    def words(self):
        """What the planner avoids, for its log."""
        c = self._checker
        if not self.enabled:
            return 'collision checking off'
        cloud = f', a canopy of {len(c.canopy)} points' if c.canopy is not None else ''
        return f'{len(c.scene)} obstacles{cloud}, the arm itself; clearance {c.clearance:g} m'
