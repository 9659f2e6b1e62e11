"""Cartesian lines and arcs, timed along their path within the joint limits."""

from __future__ import annotations

import numpy as np

from .. import geometry, trajectory
from ..kinematics import Unreachable, cartesian_to_joint
from ..kinematics.paths import check_joint_limits
from .settings import DEFAULT_JERK_PER_ACCEL, STRETCH_TIGHT


class CartesianMoves:
    """The Cartesian part of :class:`~picking_core.planning.Planner`."""

    # -- Cartesian lines and arcs ----------------------------------------------------------
    def _timed_cartesian(self, curve, q0, orientations, keys=None, ends=(0.0, 0.0), rest=None):
        """Time a curve: start from the Cartesian guess, stretch until the joints keep their limits.

        ``ends``: the progress speed at the start and at the end, as fractions of the
        fastest progress that keeps the joint limits from rest to rest (``optimal``
        profile only): a line entered or left at speed, blended with the joint move
        before or after it. The joint trajectory then starts (ends) with the
        velocity and acceleration of the moving path. ``rest``: the same curve's
        rest-to-rest path, if already timed (else timed here first).
        """
        s = self.settings
        shape, T, limits, moving = self._progress_timing(curve, q0, orientations, keys, ends, rest)
        if shape is None:
            path = geometry.CartesianPath.timed(curve, T, s.cartesian_profile, orientations=orientations,
                                                keys=keys, limits=limits)
        else:
            path = geometry.CartesianPath(curve, shape.stretched(T / shape.duration), orientations, keys)
        jp = cartesian_to_joint(self.arm, path, q0, dt=s.sample_period, max_joint_step=s.max_joint_step,
                                check_limits=False, free_ends=moving)
        over = max(float(np.max(jp.peak_velocity / self._vmax)),
                   float(np.sqrt(np.max(jp.peak_acceleration / self._amax))))
        if s.limit_jerk:
            over = max(over, self._jerk_ratio(jp.trajectory, np.linspace(0.0, T, max(50, int(T / 0.0025))))
                       ** (1.0 / 3.0))
        return self._stretched_within_limits(jp, path, over)

    def _progress_timing(self, curve, q0, orientations, keys, ends, rest):
        """How progress along ``curve`` is first timed: ``(shape, duration, limits, moving)``, ``shape`` the
        time-optimal progress profile for ends at speed (None from rest to rest: a profile of the settings),
        ``limits`` the progress's speed, acceleration and jerk limits (1/s^k; ``optimal`` profile only),
        ``moving`` whether each end is at speed."""
        s = self.settings
        length = curve.length
        limits = None
        if s.cartesian_profile == 'optimal':
            # The tool's speed and acceleration guesses, and a jerk of DEFAULT_JERK_PER_ACCEL times the
            # acceleration, as limits of the progress (1/s^k): the time-optimal shape within them.
            limits = (np.array([s.cartesian_speed, s.cartesian_accel, DEFAULT_JERK_PER_ACCEL * s.cartesian_accel])
                      / max(length, 1e-9))
            guess = max(geometry.optimal_progress(limits).duration, 0.2)
        else:
            guess = max(1.875 * length / s.cartesian_speed, np.sqrt(5.78 * length / s.cartesian_accel), 0.2)
        moving = tuple(float(f) > 0.0 for f in ends)
        if not any(moving):
            return None, s.duration or guess, limits, moving
        if s.cartesian_profile != 'optimal' or s.duration:
            raise ValueError('a line or arc entered or left at speed needs cartesian_profile optimal and no '
                             'fixed duration')
        if not all(0.0 <= float(f) < 1.0 for f in ends):
            raise ValueError(f'end speeds must be fractions in [0, 1), got {list(ends)}')
        # The rest-to-rest timing gives the progress limits that keep the joints' (its
        # profile stretched k times is the time-optimal one within limits / k, / k^2, / k^3).
        if rest is None:
            _, rest = self._timed_cartesian(curve, q0, orientations, keys)
        k = rest.duration / geometry.optimal_progress(limits).duration
        limits = limits / np.array([k, k * k, k ** 3])
        shape = trajectory.time_optimal([0.0], [1.0], *limits, v0=[ends[0] * limits[0]], vf=[ends[1] * limits[0]])
        if shape.sample(np.linspace(0.0, shape.duration, 200))[1].min() < -1e-9:
            raise Unreachable(f'entered at {ends[0]:.0%} of its speed the path overshoots its end')
        return shape, shape.duration, limits, moving

    def _stretched_within_limits(self, jp, path, over):
        """The joint path ``jp`` of ``path`` slowed until its peaks are ``over`` <= 1 of the limits: ``(traj, path)``.

        Slowed down by k, the tool passes the same poses, so the joints pass the same
        configurations: the joint path is this one stretched in time, its speeds divided by
        k, accelerations by k^2, jerks by k^3 (the spline through the IK samples stretches
        with them). The IK is solved once; its samples end up k * sample_period apart, and
        the points the conversion checked are checked again, stretched the same way."""
        s = self.settings
        traj = jp.trajectory
        t_check, q_check, qd_check, qdd_check = jp.checked
        stretch = 1.0
        for _ in range(6):
            if over <= 1.0:
                # The peaks were taken at these points, within the planner's (scaled) limits: what
                # can still fail is a position limit, which no stretch mends.
                check_joint_limits(self.arm, t_check * stretch, q_check, qd_check / stretch,
                                   qdd_check / stretch ** 2)
                return traj, path
            if s.duration:
                raise Unreachable(f'the path needs {over:.2f} times the allowed joint speed in the '
                                  f'fixed duration {s.duration} s')
            k = over * STRETCH_TIGHT
            traj, path = traj.stretched(k), path.stretched(k)
            stretch *= k
            over = over / k
        raise Unreachable('could not time the Cartesian path within the joint limits')

    def line(self, q0, T_start, T_goal, ends=(0.0, 0.0), rest=None):
        """Straight tool line from ``T_start`` to ``T_goal`` with slerped orientation
        (``ends``, ``rest``: see :meth:`_timed_cartesian`)."""
        self.arm.check_reachable(T_goal, seed=q0)
        line = geometry.Line(T_start[:3, 3], T_goal[:3, 3])
        rots = np.stack([T_start[:3, :3], T_goal[:3, :3]])
        if self.arm.dof < 6:
            rots = None
        return self._timed_cartesian(line, q0, rots, ends=ends, rest=rest)

    def arc(self, q0, T1, T2, T3, ends=(0.0, 0.0), rest=None):
        """Tool arc from ``T1`` (the current pose) through ``T2`` to ``T3`` (Sec. 2.3)
        (``ends``, ``rest``: see :meth:`_timed_cartesian`)."""
        for T in (T2, T3):
            self.arm.check_reachable(T, seed=q0)
        curve = geometry.Arc.through(T1[:3, 3], T2[:3, 3], T3[:3, 3])
        rots = None
        keys = None
        if self.arm.dof >= 6:
            rots = np.stack([T1[:3, :3], T2[:3, :3], T3[:3, :3]])
            # The key of p2 is its arc-length fraction along the arc.
            p = curve.points(2001)
            keys = [0.0, float(np.argmin(np.linalg.norm(p - T2[:3, 3], axis=1)) / 2000), 1.0]
            keys[1] = min(max(keys[1], 1e-3), 1 - 1e-3)
        return self._timed_cartesian(curve, q0, rots, keys, ends, rest)
