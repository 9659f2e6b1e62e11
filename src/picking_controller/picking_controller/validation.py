"""What a trajectory must be to be run: its joints, the shape of its points, and every limit at its
points and along the spline through them (pure core)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .goals import InvalidJoints


@dataclass(frozen=True)
class Limits:
    """The arm's joints, in command order, and their limits (inf where none): rad, rad/s, rad/s², rad/s³.
    ``optional``: joints a trajectory may leave out (a gripper): they hold their reference."""

    names: tuple
    lower: np.ndarray
    upper: np.ndarray
    max_velocity: np.ndarray
    max_acceleration: np.ndarray
    max_jerk: np.ndarray
    optional: frozenset = frozenset()

    @classmethod
    def of(cls, names, lower, upper, max_velocity, max_acceleration, max_jerk=None, optional=()):
        n = len(names)
        arr = lambda v: np.broadcast_to(np.asarray(v, float), (n,)).copy()  # noqa: E731
        jerk = arr(np.inf if max_jerk is None else max_jerk)
        return cls(tuple(names), arr(lower), arr(upper), arr(max_velocity), arr(max_acceleration), jerk,
                   frozenset(optional))

    @property
    def n(self):
        return len(self.names)

    def held(self, q, qd, qdd):
        """A reference state held within the limits: a joint at a position limit stops there, one at its speed
        limit stops accelerating past it."""
        from picking_core.trajectory import held_within_limits
        return held_within_limits(q, qd, qdd, self.lower, self.upper, self.max_velocity, self.max_acceleration)


class Validator:
    """Checks of a trajectory message's content against the arm's :class:`Limits`."""

    def __init__(self, limits):
        self.limits = limits

    def order(self, joint_names):
        """For each of the arm's joints its column in the message (-1: an optional joint left out);
        :class:`InvalidJoints` for unknown, missing or repeated names."""
        names, arm = list(joint_names), self.limits.names
        if len(set(names)) != len(names):
            raise InvalidJoints(f'joint names repeat: {names}')
        unknown = [n for n in names if n not in arm]
        missing = [n for n in arm if n not in names and n not in self.limits.optional]
        if unknown:
            raise InvalidJoints(f'unknown joints {unknown} (this arm has {list(arm)})')
        if missing:
            raise InvalidJoints(f'missing joints {missing}')
        return [names.index(n) if n in names else -1 for n in arm]

    def block(self, values, m, k, order, what, optional=False, held=None):
        """The ``(m, n)`` array of one field of the points in the arm's order (None for an optional field
        not given); the columns of joints left out hold ``held`` (positions) or 0."""
        given = _rows(values, m, k, what, optional)
        if given is None:
            return None
        if not np.all(np.isfinite(given)):
            raise ValueError(f'{what} must be finite')
        arr = given[:, np.maximum(order, 0)]
        left_out = np.array(order) < 0
        if left_out.any():
            arr[:, left_out] = held[left_out] if what == 'positions' else 0.0
        return arr

    def check_points(self, pos, vel, acc, times, slack=1e-6):
        """ValueError naming the first point beyond a limit (``times``: s from now, for the words)."""
        self._check(pos, vel, acc, slack, lambda i: f'point {i}', lambda i: f' at {times[i]:+.3f} s from now')

    def check_spline(self, traj):
        """The spline between the points must keep the position and velocity limits too."""
        t = np.union1d(np.linspace(0.0, traj.duration, max(50, 4 * len(traj.breaks))), traj.breaks - traj.start_time)
        q, qd, _ = traj.sample(t)
        self._check(q, qd, None, 1e-3, lambda i: f'between the points, {t[i]:+.3f} s after the splice (the spline '
                                                 'from the current reference through them)', lambda i: '')

    def _check(self, pos, vel, acc, slack, where, when):
        lim = self.limits
        for what, arr, lo, hi in (('position', pos, lim.lower, lim.upper),
                                  ('velocity', vel, -lim.max_velocity, lim.max_velocity),
                                  ('acceleration', acc, -lim.max_acceleration, lim.max_acceleration)):
            if arr is None:
                continue
            bad = (arr < lo - slack) | (arr > hi + slack)
            if bad.any():
                i, j = np.argwhere(bad)[0]
                raise ValueError(f'{where(i)}: {lim.names[j]} {what} {arr[i, j]:.4g} is beyond its limit '
                                 f'[{lo[j]:.4g}, {hi[j]:.4g}]{when(i)}')


def _rows(values, m, k, what, optional):
    """The message field ``values`` as an ``(m, k)`` float array; None for an optional one left empty."""
    if isinstance(values, np.ndarray) and values.ndim == 2:      # one row per point, already
        if optional and values.size == 0:
            return None
        if m == 0:
            raise ValueError('no points')
        if values.shape != (m, k):
            raise ValueError(f'every point needs {k} {what} (one per joint name)')
        return values.astype(float)
    rows = [np.asarray(v, float) for v in values]
    if optional and all(r.size == 0 for r in rows):
        return None
    if m == 0:
        raise ValueError('no points')
    if len(rows) != m or any(r.shape != (k,) for r in rows):
        raise ValueError(f'every point needs {k} {what} (one per joint name)')
    return np.array(rows)
