"""A planner goal as the planner takes it in: what it asks for, typed (pure core).

Every goal, from a topic or an action, is a :class:`Goal` with a :class:`Target` in the arm's base
frame: the pose of a pose goal, the poses of a path, the grasp pose of an apple, or a tree's apples.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np


class Kind(str, enum.Enum):
    """What a goal asks for."""

    POSE = 'pose'
    PATH = 'path'
    PICK = 'pick'
    HARVEST = 'harvest'


@dataclass(frozen=True)
class Target:
    """What a goal asks for, in the arm's base frame: ``poses`` (4x4 arrays) are the pose (one), the path's
    poses, the apple's grasp pose (one) or a harvest's apples; ``method`` a pose or path goal's own method
    ('': the planner's); ``indices`` a harvest's apples' indices in its goal; ``follow`` a pick's apple in motion
    (a :class:`~picking_core.moving_pick.Follow`: the pick is aimed where it will be), or None; ``back_off`` why a
    pick gives up (its plan goes home without closing), or ''; ``seen``: a harvest of the apples the camera sees
    (those it shows later join it); ``follows`` a harvest's swaying apples, index to Follow (its first is aimed at
    its sway, :meth:`~picking_core.harvest.Harvest.plan`), or None."""

    kind: Kind
    poses: tuple
    method: str = ''
    indices: tuple = ()
    follow: object = field(default=None, compare=False)
    back_off: str = ''
    seen: bool = False
    follows: object = field(default=None, compare=False)

    def __post_init__(self):
        if not self.poses:
            raise ValueError({Kind.PATH: 'the path has no poses',
                              Kind.HARVEST: 'the harvest has no apples (an empty PoseArray)'}.get(
                                  self.kind, 'the goal has no pose'))
        for k, T in enumerate(self.poses):
            if np.shape(T) != (4, 4) or not np.all(np.isfinite(T)):
                raise ValueError(f'pose {k} is not a finite 4x4 transform')
        if self.kind == Kind.HARVEST and not self.indices:
            object.__setattr__(self, 'indices', tuple(range(len(self.poses))))

    @property
    def pose(self):
        """The goal's one pose (a pose goal's, an apple's)."""
        return self.poses[0]

    def apples(self):
        """The apples this goal grasps (touching them is allowed): a pick's and a harvest's poses."""
        return self.poses if self.kind in (Kind.PICK, Kind.HARVEST) else ()

    def moved_to(self, pose):
        """The same goal's target moved to ``pose`` (a re-target of a pose or pick goal)."""
        if self.kind not in (Kind.POSE, Kind.PICK):
            raise ValueError(f'a {self.kind.value} goal has no one target to move')
        return replace(self, poses=(np.asarray(pose, float),))


@dataclass(frozen=True)
class Rest:
    """A harvest goal's apples not started, planned again (around a changed world, or with apples seen since):
    ``why`` in words, ``at`` the schedule time the apple in hand is in the box (the rest takes over there) and
    ``plan_time`` that time in the running plan's own time (s from its start); ``keep``: a rest that cannot be
    planned leaves the running plan on (it hits nothing; else it is stopped)."""

    why: str
    at: float
    plan_time: float
    keep: bool = False


@dataclass
class Goal:
    """A goal as the planner took it.

    Attributes
    ----------
    kind : Kind
    key : str
        Its id: an action goal's UUID as hex, a topic goal's header stamp, or an id of its own.
    target : Target or None
        None only for a goal refused before its message could be read.
    came : float
        When it came (wall clock, s).
    stamp : str
        A topic goal's header stamp as text (its statuses carry it: its sender's name for it).
    attempt : int
        How many times it was planned again after its plan reached the controller too late.
    rest : Rest or None
        Set on the rest of a running harvest planned again around a changed world.
    retargets : int
        How many times its target was moved while it ran; ``moved_by`` names the newest move (its message's stamp).
    finish, feedback : callable or None
        An action goal's hooks: ``finish(outcome, message, code, duration)`` once when it ends,
        ``feedback(phase, time_left, tracking_error)``.
    """

    kind: Kind
    key: str
    target: Target | None
    came: float = 0.0
    stamp: str = ''
    attempt: int = 0
    rest: Rest | None = None
    retargets: int = 0
    moved_by: str = ''
    finish: Callable | None = field(default=None, repr=False)
    feedback: Callable | None = field(default=None, repr=False)

    def again(self, **changes):
        """This goal with ``changes`` (the same key: it answers as the same goal)."""
        return replace(self, **changes)
