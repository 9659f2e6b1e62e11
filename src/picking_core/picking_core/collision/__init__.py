"""Collision checking (pure core): the scene and canopy the planner knows, and whether a motion
of the arm stays clear of them and of itself. See docs/collisions.md."""

from .checker import CLEARANCE, STEP, Allowed, CollisionChecker, Contact
from .scene import RESOLUTION, Canopy, Obstacle, Scene
from .world import World

__all__ = ['CLEARANCE', 'RESOLUTION', 'STEP', 'Allowed', 'Canopy', 'CollisionChecker', 'Contact', 'Obstacle',
           'Scene', 'World']
