"""Goals of the FollowJointTrajectory action, without ROS: the tolerances a goal asks for, and how it ends.

A goal's tolerances override the controller's defaults joint by joint, with the action's
conventions: 0 keeps the default, -1 switches that check off, a positive value sets it. Every
goal ends in one :class:`Outcome` (succeeded, aborted or canceled) with an :class:`ErrorCode`
and the reason in words; the core attaches it to the event that ends the goal.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .events import LateTrajectory, Tolerances


class ErrorCode(enum.IntEnum):
    """``control_msgs/action/FollowJointTrajectory`` result codes."""

    SUCCESSFUL = 0
    INVALID_GOAL = -1
    INVALID_JOINTS = -2
    OLD_HEADER_TIMESTAMP = -3
    PATH_TOLERANCE_VIOLATED = -4
    GOAL_TOLERANCE_VIOLATED = -5


class InvalidJoints(ValueError):
    """A trajectory whose joints are not this arm's (unknown, missing or repeated)."""


@dataclass(frozen=True)
class Outcome:
    """How a goal ended: ``status`` is 'succeeded', 'aborted' or 'canceled'."""

    status: str
    code: ErrorCode
    text: str

    @classmethod
    def refused(cls, exc):
        """A trajectory refused before it ran, with the code its reason calls for."""
        code = (ErrorCode.INVALID_JOINTS if isinstance(exc, InvalidJoints)
                else ErrorCode.OLD_HEADER_TIMESTAMP if isinstance(exc, LateTrajectory)
                else ErrorCode.INVALID_GOAL)
        return cls('aborted', code, f'trajectory rejected: {exc}')


@dataclass(frozen=True)
class JointTolerances:
    """The tolerances one trajectory runs under, one value per joint (inf: not checked), rad, rad/s, s."""

    path: np.ndarray                 # |measured - reference| while moving
    path_velocity: np.ndarray        # |measured - reference velocity| while moving
    goal: np.ndarray                 # |measured - final position| at the end
    goal_velocity: np.ndarray        # |measured velocity| at the end ("at rest")
    goal_time: float                 # s after the end to get within ``goal``

    @cached_property
    def checks_path_velocity(self):
        return bool(np.isfinite(self.path_velocity).any())

    @classmethod
    def default(cls, tol: Tolerances, n):
        full = lambda v: np.broadcast_to(np.asarray(v, float), (n,)).copy()  # noqa: E731
        return cls(full(tol.path), full(np.inf), full(tol.goal), full(tol.stopped_velocity), float(tol.goal_time))

    def overridden(self, names, path=(), goal=(), goal_time=0.0):
        """These tolerances with a goal's: ``path`` and ``goal`` are ``(name, position, velocity,
        acceleration)`` tuples (JointTolerance); ``goal_time`` s, 0 for the default.

        Raises ValueError for an unknown joint, a negative value other than -1, or an acceleration
        tolerance (the arm reports no acceleration to check it against).
        """
        names = list(names)
        values = {k: v.copy() for k, v in (('path', self.path), ('path_velocity', self.path_velocity),
                                           ('goal', self.goal), ('goal_velocity', self.goal_velocity))}
        for kind, given in (('path', path), ('goal', goal)):
            for name, position, velocity, acceleration in given:
                if name not in names:
                    raise ValueError(f'{kind}_tolerance names the unknown joint {name!r} (this arm has {names})')
                j = names.index(name)
                for what, value, key in (('position', position, kind), ('velocity', velocity, f'{kind}_velocity')):
                    values[key][j] = _tolerance(value, values[key][j], f'{kind}_tolerance {what} of {name}')
                if acceleration not in (0.0, -1.0):
                    raise ValueError(f'{kind}_tolerance acceleration of {name} is {acceleration:g}: this controller '
                                     'measures no acceleration to check it against (give 0 or -1)')
        goal_time = float(goal_time)
        if not (np.isfinite(goal_time) and goal_time >= 0.0):
            raise ValueError(f'goal_time_tolerance must be >= 0 s, got {goal_time:g}')
        return JointTolerances(**values, goal_time=goal_time if goal_time > 0.0 else self.goal_time)


def _tolerance(value, default, what):
    value = float(value)
    if value == 0.0:
        return default
    if value == -1.0:
        return np.inf
    if not (np.isfinite(value) and value > 0.0):
        raise ValueError(f'{what} is {value:g}: give a value > 0, 0 for the default or -1 for no check')
    return value
