"""A goal's plan from a start state, checked against the world (pure core)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import around
from ..approaches import Blocked
from ..collision import STEP as COLLISION_STEP
from ..collision import Allowed
from ..collision.fruit import RADIUS, Neighbours
from ..harvest import Harvest, HarvestPlan
from ..moving_pick import AimHolds, closing_margin, decide
from ..pick_cycle import PickCycle
from ..planning import JERK_UNBOUNDED, PATH_METHODS, POSE_METHODS, Plan
from .requests import Kind


@dataclass(frozen=True)
class Planned:
    """A goal's plan: ``plan`` (its trajectory, segments and joint names), ``regions`` where touching is allowed
    along it (its apples), and a harvest's :class:`~picking_core.harvest.HarvestPlan` (its apples' times)."""

    plan: Plan
    regions: tuple = ()
    harvest: HarvestPlan | None = None


class GoalPlanner:
    """Plans goals with a :class:`~picking_core.planning.Planner`, the pick cycle's settings and a
    :class:`~picking_core.collision.World` (each as it is when planning starts)."""

    def __init__(self, planner, pick, world):
        self.planner, self.pick, self.world = planner, pick, world

    def check(self, target):
        """ValueError when ``target`` names a method this planner does not know (before any planning)."""
        self._planner_for(target)

    def plan(self, target, start, at=0.0):
        """The :class:`Planned` of ``target`` from ``start`` (a :class:`~.start.Start`; ``at`` the schedule time
        it is expected to start at on the ROS clock, for a pick of a moving apple); raises ValueError (or Unreachable, Blocked, or
        :class:`~picking_core.moving_pick.AimHolds`) with the reason."""
        checker = self.world.checker
        if target.kind == Kind.POSE:
            planned = Planned(around.plan_pose(self._planner_for(target), checker, start.state, target.pose,
                                               target.method or None))
        elif target.kind == Kind.PATH:
            planned = Planned(around.plan_path(self._planner_for(target), checker, start.state, list(target.poses),
                                               target.method or None))
        elif target.kind == Kind.PICK and target.back_off:
            planned = Planned(self._cycle(checker).back_off(start.state))
        elif target.kind == Kind.PICK and target.follow is not None:
            planned = Planned(self._aimed(self._cycle(checker), target, start, at))
        elif target.kind == Kind.PICK:
            planned = Planned(self._cycle(checker).plan(start.state, target.pose, gripper_start=start.gripper,
                                                        neighbours=self._neighbours(checker, target.pose)))
        else:
            harvest = Harvest(self._cycle(checker)).plan(start.state, list(target.poses), gripper_start=start.gripper,
                                                          indices=list(target.indices), follows=target.follows, t0=at)
            planned = Planned(harvest.plan, harvest=harvest)
        regions = tuple(Allowed(np.asarray(T)[:3, 3], self.pick.apple_region) for T in target.apples())
        planned = Planned(planned.plan, regions, planned.harvest)
        if target.kind in (Kind.PICK, Kind.HARVEST):
            # A pick's or a harvest's parts were each planned clear of the world; the whole is checked once more,
            # its joins included (a pose or path goal's plan was checked whole by around).
            contact = self.world.check(planned.plan.trajectory, list(regions), slack=COLLISION_STEP / 2)
            if contact is not None:
                raise Blocked(f'the plan would hit an obstacle: {contact}')
        return planned

    @staticmethod
    def _aimed(cycle, target, start, t0):
        """A pick's plan aimed where its moving apple will be when the fingers close (:mod:`~picking_core.moving_pick`),
        keeping the closing instant of its last plan; ``t0`` the ROS time the plan starts. An aim that
        :func:`~picking_core.moving_pick.holds_off` is a plan to the stand-off instead, its ``extra['holds']`` the
        closing margin it had (m)."""
        follow = target.follow

        def plan_to(T, least):
            return cycle.plan(start.state, T, gripper_start=start.gripper, approach_time=least,
                              from_here=follow.holding, rides=True)
        at = None if follow.closes_at is None else follow.closes_at - t0
        decided = decide(plan_to, lambda s: follow.predict(t0 + s), target.pose[:3, :3], follow.width, at,
                         follow.holding, cycle.ride)
        if decided is None:
            raise AimHolds('no new plan closes the fingers on time: the running plan keeps its aim')
        aimed, holds = decided
        if holds:
            plan = cycle.stand_off(start.state, aimed.T)
            plan.extra['holds'] = closing_margin(aimed)
            return plan
        aimed.plan.extra['closes_in'] = aimed.at
        return aimed.plan

    def _cycle(self, checker):
        return PickCycle(self.planner, self.pick, checker)

    def _neighbours(self, checker, T):
        """The apples the world knows on the tree but the one at ``T`` (within RADIUS of its centre), passed no
        faster than the pick settings' ``apple_pass_speed``; None without a checker, a pass speed or any."""
        centres = self.world.apples
        others = centres[np.linalg.norm(centres - np.asarray(T, float)[:3, 3], axis=1) > RADIUS]
        if checker is None or self.pick.apple_pass_speed <= 0.0 or not len(others):
            return None
        return Neighbours(checker.capsules, others, self.pick.apple_pass_speed)

    def _planner_for(self, target):
        """The planner for a goal that names its own method (empty: the planner's settings). A method that steps
        the acceleration (cubic, LSPB), asked for by name, is planned as the paper defines it: with the velocity
        and acceleration limits, not the jerk limits."""
        method = target.method
        if not method or target.kind not in (Kind.POSE, Kind.PATH):
            return self.planner
        methods, parameter = (POSE_METHODS, 'method') if target.kind == Kind.POSE else (PATH_METHODS, 'path_method')
        if method not in methods:
            raise ValueError(f'unknown {parameter} {method!r}; choose one of {", ".join(methods)}')
        if method in JERK_UNBOUNDED and self.planner.settings.limit_jerk:
            return self.planner.with_settings(limit_jerk=False, **{parameter: method})
        return self.planner
