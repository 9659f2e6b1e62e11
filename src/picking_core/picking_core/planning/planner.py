"""The planner: one object for one arm, its behaviour split by concern into the classes it joins."""

from __future__ import annotations

from dataclasses import replace

from .. import trajectory
from .cartesian import CartesianMoves
from .joint import JointMoves
from .limits import Limits
from .settings import PlannerSettings
from .via import ViaMoves


class Planner(Limits, JointMoves, CartesianMoves, ViaMoves):
    """Plans for one arm; see the module docstring for the methods."""

    def __init__(self, arm, settings=PlannerSettings()):
        self.arm = arm
        self.settings = settings.validate()
        trajectory.use_compiled_kernels()        # a plan samples its splines many times

    def with_settings(self, **changes):
        return Planner(self.arm, replace(self.settings, **changes))
