"""Pose and path goals around obstacles (pure core).

A pose goal, or a path goal through via points, whose plan would hit something is planned again:
each leg between its joint configurations that is not clear is replaced by a collision-free joint
path (RRT-Connect, shortcut: :mod:`~picking_core.planning.joint_path`), and all the points are
timed together by the goal's via-point method within the limits. A pose goal whose joint solution
nearest the start is itself in contact (an elbow in a branch) tries the arm's other IK solutions of
the same pose. A Cartesian line or arc is the tool path the goal asks for: it is refused with its
contact, never bent.
"""

from __future__ import annotations

import numpy as np

from .approaches import Blocked, BrakeBlocked
from .planning.joint_path import REFINE, NoPath, clear_edge, doubled, rrt_connect

#: The via-point method that times a pose goal's move through a detour, for each pose method.
VIA_METHOD = {'cubic': 'quintic_via', 'quintic': 'quintic_via', 'lspb': 'via_lspb', 'optimal': 'optimal'}


def plan_pose(planner, checker, start, T_goal, method=None):
    """:meth:`Planner.plan_pose`, around what ``checker`` (None: nothing) sees; Blocked naming the
    contact when no way around is found."""
    method = method or planner.settings.method
    plan = planner.plan_pose(start, T_goal, method)
    contact = None if checker is None else checker.check(plan.trajectory)
    if contact is None:
        return plan
    if method not in VIA_METHOD:
        raise Blocked(f'the plan would hit an obstacle: {contact} (a {method} goal keeps its tool path)')
    stop, q_rest = planner.come_to_rest(start)
    arm = planner.arm
    q_goal = arm.check_reachable(T_goal, seed=q_rest)
    others = [q for q in arm.ik_all(T_goal) if arm.within_limits(q) and np.abs(q - q_goal).max() > 1e-6]
    goals = [q for q in [q_goal] + sorted(others, key=lambda q: float(np.abs(q - q_rest).max()))
             if not checker.colliding(q[None])[0]]
    if not goals:
        raise Blocked(f'the plan would hit an obstacle: {contact}; the arm touches something at the goal pose on '
                      f'every IK solution ({checker.first_contact(q_goal[None])})')
    return _around(planner, checker, stop, [np.array([q_rest, q]) for q in goals], VIA_METHOD[method], 'move',
                   contact)


def plan_path(planner, checker, start, poses, method=None):
    """:meth:`Planner.plan_path`, around what ``checker`` (None: nothing) sees (via-point methods; a
    line or an arc is refused with its contact); Blocked naming the contact when no way around is
    found."""
    method = method or planner.settings.path_method
    plan = planner.plan_path(start, poses, method)
    contact = None if checker is None else checker.check(plan.trajectory)
    if contact is None:
        return plan
    if method in ('line', 'arc'):
        raise Blocked(f'the plan would hit an obstacle: {contact} (a {method} goal keeps its tool path)')
    stop, q_rest = planner.come_to_rest(start)
    qs = planner.via_points(q_rest, poses)
    for i, q in enumerate(qs[1:]):
        if checker.colliding(q[None])[0]:
            raise Blocked(f'the plan would hit an obstacle: {contact}; the arm touches something at pose {i} '
                          f'itself ({checker.first_contact(q[None])})')
    return _around(planner, checker, stop, [qs], method, 'via points', contact)


def _around(planner, checker, stop, tries, method, label, contact):
    """The first of ``tries`` (joint points from rest, each an array (k, dof)) that is made clear: its
    legs around obstacles, timed by ``method`` after the ``stop`` (None at rest)."""
    arm = planner.arm
    colliding = checker.colliding
    braking = None if stop is None else checker.check(stop)
    if braking is not None:
        raise BrakeBlocked(f'the plan would hit an obstacle while it brakes: {braking}')
    why = 'no collision-free joint path around it'
    for qs in tries:
        points = [qs[0]]
        try:
            for a, b in zip(qs[:-1], qs[1:]):
                points.extend(rrt_connect(colliding, a, b, arm.lower, arm.upper)[1:]
                              if not clear_edge(colliding, a, b) else [b])
        except NoPath as exc:
            why = str(exc)
            continue
        points = np.array(points)
        waypoints = len(points) - len(qs)
        for _ in range(REFINE + 1):
            parts = ([('brake', 'quintic', stop)] if stop is not None else [])
            parts.append((label, method, planner.via(points, method)))
            plan = planner.join(parts, method)
            left = checker.check(plan.trajectory)
            if left is None:
                plural = 's' * (waypoints != 1)
                plan.extra['detours'] = f'{label} around obstacles through {waypoints} waypoint{plural}'
                return plan
            points = doubled(points)
        why = f'the timed way around still touches: {left}'
    raise Blocked(f'the plan would hit an obstacle: {contact}; {why}')
