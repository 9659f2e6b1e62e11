"""Path goals: through the IK of every pose with via-point profiles, or as lines and arcs."""

from __future__ import annotations

import numpy as np

from .. import trajectory
from ..kinematics import Unreachable
from .settings import PATH_METHODS, STRETCH_TIGHT, VIA_SPEEDS


class ViaMoves:
    """The path part of :class:`~picking_core.planning.Planner`."""

    # -- path goals -------------------------------------------------------------------------
    def plan_path(self, start, poses, method=None):
        """Pass through ``poses`` (list of 4x4) from ``start = (q, qd, qdd)``."""
        method = method or self.settings.path_method
        if method not in PATH_METHODS:
            raise ValueError(f'unknown path method {method!r}; choose one of {", ".join(PATH_METHODS)}')
        poses = list(poses)
        if not poses:
            raise ValueError('the path has no poses')
        stop, q = self.come_to_rest(start)
        parts = [('brake', 'quintic', stop)] if stop is not None else []
        cart = []
        if method in ('via_lspb', 'quintic_via', 'optimal'):
            parts.append(('via points', method, self.via(self.via_points(q, poses), method)))
        elif method == 'line':
            T_prev = self.arm.fk(q)
            for i, T in enumerate(poses):
                try:
                    traj, path = self.line(q, T_prev, T)
                except Unreachable as exc:
                    raise Unreachable(f'line to pose {i}: {exc}') from None
                parts.append((f'line {i}', 'line', traj))
                cart.append((len(parts) - 1, path))
                q, T_prev = traj.end_state()[0], T
        else:
            if len(poses) not in (2, 3):
                raise ValueError(f'an arc needs 2 poses (through, end; it starts at the tool) or 3 '
                                 f'(start, through, end), got {len(poses)}')
            if len(poses) == 3:
                q_first = self.arm.check_reachable(poses[0], seed=q)
                parts.append(('to arc start', 'quintic', self.joint_move(q, q_first, 'quintic')))
                q = q_first
            T1 = self.arm.fk(q)
            traj, path = self.arc(q, T1, poses[-2], poses[-1])
            parts.append(('arc', 'arc', traj))
            cart.append((len(parts) - 1, path))
        return self.join(parts, method, cart)

    def via_points(self, q, poses):
        """The joints at rest ``q`` and at each of ``poses`` in turn, each solution nearest the one
        before: shape (1 + len(poses), dof); Unreachable naming the first pose out of reach."""
        qs = [q]
        for i, T in enumerate(poses):
            try:
                qs.append(self.arm.check_reachable(T, seed=qs[-1]))
            except Unreachable as exc:
                raise Unreachable(f'pose {i}: {exc}') from None
        return np.array(qs)

    def via(self, qs, method, start=None, end=None, scales=None):
        """Joint via points timed from the limits, stretched until feasible.

        Each segment starts from the rest-to-rest time of its slowest joint (60 % of
        it for via-point LSPB, which passes its via points at speed); the durations then
        grow by 4 % until the blends fit and the scaled limits hold (a quintic spline
        too fast for them stretches by exactly the factor it needs). ``start`` and
        ``end``: ``(velocity, acceleration)`` at the first and last point, ``optimal`` only
        (default at rest). ``scales``: a speed fraction for each leg between the points (its limits scaled as
        ``speed_scale`` scales them), ``optimal`` only (default all 1).
        """
        if method == 'optimal':
            return self._optimal_via(np.asarray(qs, float), start, end, scales)
        if scales is not None:
            raise ValueError('only optimal via points are slowed leg by leg')
        if start is not None or end is not None:
            raise ValueError('only optimal via points start or end moving')
        profile = 'lspb' if method == 'via_lspb' else 'quintic'
        durations = self._shortest_durations(qs, profile)
        if method == 'via_lspb' and len(durations) > 1:
            # Interior via points are passed at speed, not stopped at: start from 60 %, but not
            # below the timing whose lines keep the speed limit v. An interior line runs at
            # dq / T. The first and last, which blend from and to rest at a, run at
            # 2 dq / (T + sqrt(T^2 - 2 dq / a)): within v from T = dq / v + v / 2a on, and from
            # their shortest time, T = sqrt(2 dq / a), where dq < v^2 / 2a.
            dq = np.abs(np.diff(qs, axis=0))
            v, a = self._vmax, self._amax
            need = np.max(dq / v, axis=1)
            ends = dq[[0, -1]]
            need[[0, -1]] = np.max(np.where(ends >= v * v / (2.0 * a), ends / v + v / (2.0 * a),
                                            np.sqrt(2.0 * ends / a)), axis=1)
            durations = np.maximum(0.6 * durations, need)
        durations = np.maximum(durations, 2 * self.settings.sample_period)
        last = None
        for _ in range(60):
            try:
                if method == 'via_lspb':
                    # The timing alone first (microseconds): the trajectory is built once its blends
                    # fit and its lines keep the scaled speed limit (its fastest speeds are its lines':
                    # the blends join them). A line ending in a blend from rest slows far more than
                    # its stretch near the shortest timing, hence small steps.
                    timing = trajectory.via_lspb_timing(qs, durations, self._amax)
                    if (np.abs(timing[1]) > self._vmax * (1.0 + 1e-9)).any():
                        raise ValueError('a line is faster than the scaled velocity limit')
                    traj = trajectory.via_lspb(qs, durations, self._amax, timing)
                else:
                    # The spline through the points stretched k times: speeds / k, accelerations / k^2.
                    traj = trajectory.quintic_via(qs, durations)
                    over = self._limit_use(traj)
                    if over > 1.0:
                        durations = durations * (over * STRETCH_TIGHT)
                        continue
                self._check(traj, method)
                return traj
            except ValueError as exc:       # blends do not fit, or a limit is broken: slow down
                last = str(exc)             # (the exception itself, its traceback holding this frame, is a cycle)
                durations = durations * 1.04
        raise Unreachable(f'{method}: no timing within the joint limits ({last})')

    def _optimal_via(self, qs, start=None, end=None, scales=None):
        """Jerk-limited, time-optimal segments through via points, passed at speed.

        A joint passes a via point at a multiple of the mean of its neighbouring
        chords' speeds (chords timed rest to rest) where both go the same way, and
        stops where it turns back; each segment is then Ruckig's fastest move
        between those states. The multiple is the fastest of VIA_SPEEDS (the mean
        itself is often too slow: a transfer's via point cost 0.1 s over the direct
        move at 1x, nothing at 2x). A leg slowed to a fraction of the speed (``scales``) has its limits scaled as
        ``speed_scale`` scales them, and its ends are passed within its velocity limit.
        """
        (v0, a0), (vf, af) = start or (None, None), end or (None, None)
        f = np.ones(len(qs) - 1) if scales is None else np.asarray(scales, float)
        if len(f) != len(qs) - 1 or not np.all((f > 0.0) & (f <= 1.0)):
            raise ValueError(f'a speed fraction in (0, 1] for each of the {len(qs) - 1} legs, got {scales}')
        if len(qs) == 2 and f[0] == 1.0:
            return self.joint_move(qs[0], qs[1], 'optimal', v0=v0, a0=a0, vf=vf, af=af)
        chords = self._shortest_durations(qs, 'lspb') / f
        slopes = np.diff(qs, axis=0) / chords[:, None]
        onward = np.sign(slopes[:-1]) == np.sign(slopes[1:])
        mean = np.where(onward, 0.5 * (slopes[:-1] + slopes[1:]), 0.0)
        # (A point is passed within the velocity limit of both legs it joins.)
        vlim = self._vmax * np.minimum(f[:-1], f[1:])[:, None]
        best, error = None, None
        for scale in VIA_SPEEDS:
            v = np.zeros_like(qs)
            v[1:-1] = np.clip(scale * mean, -vlim, vlim)
            a = np.zeros_like(qs)
            for i, vi, ai in ((0, v0, a0), (-1, vf, af)):
                v[i], a[i] = (0.0 if vi is None else vi), (0.0 if ai is None else ai)
            try:
                parts = [trajectory.time_optimal(qs[i], qs[i + 1], self._vmax * f[i], self._amax * f[i] ** 2,
                                                 self._jmax * f[i] ** 3, v[i], a[i], v[i + 1], a[i + 1])
                         for i in range(len(qs) - 1)]
            except ValueError as exc:
                error = str(exc)            # (not the exception: with its traceback, a cycle)
                continue
            if best is None or sum(p.duration for p in parts) < sum(p.duration for p in best):
                best = parts
        if best is None:
            raise ValueError(error)
        traj = trajectory.concatenate(best)
        self._check(traj, 'optimal via points')
        return traj
