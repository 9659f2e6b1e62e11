"""What a trajectory must be to be run: its joints, the shape of its points, and every limit at its
points and along the spline through them (part of :class:`~picking_controller.core.ControllerCore`)."""

from __future__ import annotations

import numpy as np

from .goals import InvalidJoints


class Validation:
    """Checks of a trajectory's message content against the arm."""

    def _order(self, joint_names):
        names = list(joint_names)
        if len(set(names)) != len(names):
            raise InvalidJoints(f'joint names repeat: {names}')
        unknown = [n for n in names if n not in self.names]
        missing = [n for n in self.names if n not in names and n not in self.optional]
        if unknown:
            raise InvalidJoints(f'unknown joints {unknown} (this arm has {self.names})')
        if missing:
            raise InvalidJoints(f'missing joints {missing}')
        return [names.index(n) if n in names else -1 for n in self.names]

    def _block(self, values, m, k, order, what, optional=False, held=None):
        if isinstance(values, np.ndarray) and values.ndim == 2:      # one row per point, already
            if optional and values.size == 0:
                return None
            if m == 0:
                raise ValueError('no points')
            if values.shape != (m, k):
                raise ValueError(f'every point needs {k} {what} (one per joint name)')
            given = values.astype(float)
        else:
            rows = [np.asarray(v, float) for v in values]
            if optional and all(r.size == 0 for r in rows):
                return None
            if m == 0:
                raise ValueError('no points')
            if len(rows) != m or any(r.shape != (k,) for r in rows):
                raise ValueError(f'every point needs {k} {what} (one per joint name)')
            given = np.array(rows)
        if not np.all(np.isfinite(given)):
            raise ValueError(f'{what} must be finite')
        arr = given[:, np.maximum(order, 0)]
        left_out = np.array(order) < 0
        if left_out.any():
            # Joints the trajectory leaves out hold where their reference is.
            arr[:, left_out] = held[left_out] if what == 'positions' else 0.0
        return arr

    def _check_limits(self, pos, vel, acc, slack=1e-6, times=None, spline=False):
        """ValueError naming the first point (or, ``spline``, the time on the spline) beyond a limit."""
        for what, arr, lo, hi in (('position', pos, self.lower, self.upper),
                                  ('velocity', vel, -self.max_velocity, self.max_velocity),
                                  ('acceleration', acc, -self.max_acceleration, self.max_acceleration)):
            if arr is None:
                continue
            bad = (arr < lo - slack) | (arr > hi + slack)
            if bad.any():
                i, j = np.argwhere(bad)[0]
                where = (f'between the points, {times[i]:+.3f} s after the splice (the spline from the current '
                         'reference through them)' if spline else f'point {i}')
                raise ValueError(f'{where}: {self.names[j]} {what} {arr[i, j]:.4g} is beyond its limit '
                                 f'[{lo[j]:.4g}, {hi[j]:.4g}]'
                                 + (f' at {times[i]:+.3f} s from now' if times is not None and not spline else ''))

    def _check_spline(self, traj):
        """The spline between the points must respect the position and velocity limits too."""
        t = np.union1d(np.linspace(0.0, traj.duration, max(50, 4 * len(traj.breaks))), traj.breaks - traj.start_time)
        q, qd, _ = traj.sample(t)
        self._check_limits(q, qd, None, slack=1e-3, times=t, spline=True)
