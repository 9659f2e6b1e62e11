"""Cartesian geometry of tool paths: straight lines, 3-point arcs, timed paths.

>>> from picking_core import geometry
>>> arc = geometry.Arc.through((10, 3, 4), (11, 3, 5), (10, 3, 6))
>>> arc.center, arc.radius       # (10, 3, 5), 1
"""

from .arc import Arc
from .cartesian import PROFILES, CartesianPath, optimal_progress, progress_profile
from .line import Line

__all__ = ['Arc', 'Line', 'CartesianPath', 'progress_profile', 'optimal_progress', 'PROFILES']
