"""Joint-space moves: one move between two configurations, a pose goal, and plans joined from parts."""

from __future__ import annotations

import numpy as np

from .. import trajectory
from ..kinematics import Unreachable
from .settings import JERK_UNBOUNDED, JOINT_METHODS, POSE_METHODS, Plan, Segment


class JointMoves:
    """The joint-space part of :class:`~picking_core.planning.Planner`."""

    def join(self, parts, method, cartesian=()):
        """Concatenate (label, method, traj) parts into a Plan with its segment table."""
        segments, t = [], 0.0
        for label, m, traj in parts:
            segments.append(Segment(label, m, t, traj.duration))
            t += traj.duration
        whole = trajectory.concatenate([p[2] for p in parts])
        return Plan(whole, method, segments, list(cartesian), self.arm.joint_names)

    # -- pose goals -----------------------------------------------------------------------
    def joint_move(self, q0, qf, method, duration=None, v0=None, a0=None, vf=None, af=None):
        """A joint-space move between configurations within the limits (``optimal`` only:
        to a moving target state ``vf``, ``af``)."""
        if method not in JOINT_METHODS:
            raise ValueError(f'unknown joint method {method!r}; choose one of {", ".join(JOINT_METHODS)}')
        if self.settings.limit_jerk and method in JERK_UNBOUNDED:
            raise ValueError(f'{method} moves step the acceleration (unbounded jerk): with limit_jerk choose '
                             'optimal or quintic')
        if method == 'optimal':
            traj = trajectory.time_optimal(q0, qf, self._vmax, self._amax, self._jmax, v0, a0, vf, af,
                                           min_duration=duration or self.settings.duration or 0.0)
            self._check(traj, 'optimal move')
            return traj
        if vf is not None or af is not None:
            raise ValueError('only optimal moves end at a moving target state')
        T = duration or self.settings.duration or self.shortest_duration(q0, qf, method)
        if method == 'cubic':
            traj = trajectory.cubic(q0, qf, T, 0.0 if v0 is None else v0)
        elif method == 'quintic':
            traj = trajectory.quintic(q0, qf, T, 0.0 if v0 is None else v0, 0.0,
                                      0.0 if a0 is None else a0)
        else:
            accel = np.maximum(self._amax, trajectory.min_lspb_accel(q0, qf, T) * (1 + 1e-9))
            traj = trajectory.lspb(q0, qf, T, accel)
        self._check(traj, f'{method} move')
        return traj

    def plan_pose(self, start, T_goal, method=None):
        """Move the tool to ``T_goal`` (4x4 in the base frame) from ``start = (q, qd, qdd)``."""
        method = method or self.settings.method
        if method not in POSE_METHODS:
            raise ValueError(f'unknown method {method!r}; choose one of {", ".join(POSE_METHODS)}')
        q, qd, qdd = start = self.check_start(start)
        if method == 'line':
            stop, q_rest = self.come_to_rest(start)
            traj, path = self.line(q_rest, self.arm.fk(q_rest), T_goal)
            parts = ([('brake', 'quintic', stop)] if stop is not None else []) + [('line', 'line', traj)]
            cart = [(len(parts) - 1, path)]
            return self.join(parts, 'line', cart)
        q_goal = self.arm.check_reachable(T_goal, seed=q)
        if method in ('cubic', 'quintic', 'optimal'):
            try:
                traj = self.joint_move(q, q_goal, method, v0=qd, a0=qdd if method != 'cubic' else None)
                return self.join([('move', method, traj)], method)
            except Unreachable:
                if self.come_to_rest(start)[0] is None:
                    raise
                # Carried on from this motion the move would cross a limit (an overshoot near a
                # joint limit, or a start already near the speed limit): brake first, then move.
        stop, q_rest = self.come_to_rest(start)
        parts = ([('brake', 'quintic', stop)] if stop is not None else [])
        parts.append(('move', method, self.joint_move(q_rest, q_goal, method)))
        return self.join(parts, method)
