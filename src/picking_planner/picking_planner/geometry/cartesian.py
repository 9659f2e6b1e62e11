"""A tool path in time: a Line or Arc traversed by a 1-D profile, orientation slerped.

The curve gives the position as a function of arc length s; a time profile
(cubic, quintic, LSPB -- the same ones the joints use) gives the progress
``u(t)`` from 0 to 1, and ``s = u * length``. The orientation is interpolated by
quaternion slerp between key orientations at chosen progress values.
"""

from __future__ import annotations

import functools

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from .. import trajectory
from ..trajectory._checks import as_duration

PROFILES = ('cubic', 'quintic', 'lspb', 'optimal')
#: Progress limits (velocity, acceleration, jerk, in 1/s^k) whose time-optimal profile is the
#: shape of ``optimal`` when no limits are given: jerk-bound, bang-bang jerk (the fastest shape
#: for a given peak jerk, 0.81 of a quintic's time).
JERK_BOUND = (1e3, 1e3, 1.0)


def optimal_progress(limits=JERK_BOUND):
    """The fastest progress from rest at 0 to rest at 1 within ``limits`` = (velocity,
    acceleration, jerk) of the progress (Ruckig: at most seven constant-jerk phases)."""
    v, a, j = (float(x) for x in limits)
    return trajectory.time_optimal([0.0], [1.0], v, a, j)


def progress_profile(duration, profile='quintic', accel=None, limits=None):
    """A one-joint profile from 0 to 1 in ``duration`` s.

    Parameters
    ----------
    duration : float
        s.
    profile : {'cubic', 'quintic', 'lspb', 'optimal'}
    accel : float, optional
        For LSPB, the blend acceleration of the progress, 1/s^2; default 1.5
        times the minimum of Eq. 20 (cruise over a third of the move).
    limits : (float, float, float), optional
        For ``optimal``, the progress limits whose time-optimal, jerk-limited
        profile gives the shape, stretched to ``duration`` (default: jerk-bound).
    """
    duration = as_duration(duration)
    if profile == 'optimal':
        shape = optimal_progress(JERK_BOUND if limits is None else limits)
        return shape.stretched(duration / shape.duration)
    if profile in ('cubic', 'quintic'):
        return _unit_profile(profile).stretched(duration)
    if profile == 'lspb':
        if accel is None:
            accel = 1.5 * 4.0 / duration**2
        return trajectory.lspb(0.0, 1.0, duration, accel)
    raise ValueError(f'unknown profile {profile!r}; choose one of {", ".join(PROFILES)}')


@functools.cache
def _unit_profile(name):
    """The cubic or quintic progress over 1 s, built once: any duration is it stretched (every
    Cartesian path times one, and stretching costs a fraction of building)."""
    return getattr(trajectory, name)(0.0, 1.0, 1.0)


def _as_rotations(orientations):
    if isinstance(orientations, Rotation):
        rots = orientations
    else:
        quats = np.array(orientations, dtype=float)
        if quats.ndim != 2 or quats.shape[1] != 4:
            raise ValueError('orientations must be quaternions (x, y, z, w), shape (k, 4)')
        norms = np.linalg.norm(quats, axis=1)
        if not np.all(np.isfinite(quats)) or np.any(norms < 1e-9):
            raise ValueError('orientation quaternions must be finite and non-zero')
        rots = Rotation.from_quat(quats)
    if rots.single or len(rots) < 1:
        rots = Rotation.concatenate([rots])
    return rots


class CartesianPath:
    """Tool positions and orientations along a curve, over time.

    Parameters
    ----------
    curve : Line or Arc
        Anything with ``length`` and ``at(s) -> (p, dp/ds, d2p/ds2)``.
    profile : PiecewisePolynomial
        One joint, from 0 at its start to 1 at its end (see :func:`progress_profile`).
    orientations : Rotation or array_like of (x, y, z, w), optional
        Key orientations; one holds the orientation fixed.
    keys : array_like, optional
        Progress (0..1) of each key orientation, increasing; default evenly
        spaced from 0 to 1.
    """

    __slots__ = ('curve', 'profile', '_slerp', '_fixed')

    def __init__(self, curve, profile, orientations=None, keys=None):
        if profile.n_joints != 1:
            raise ValueError('the progress profile must have exactly one joint')
        u0, _, _ = profile.start_state()
        u1, _, _ = profile.end_state()
        if abs(u0[0]) > 1e-9 or abs(u1[0] - 1.0) > 1e-9:
            raise ValueError('the progress profile must run from 0 to 1')
        self.curve = curve
        self.profile = profile
        self._slerp = None
        self._fixed = None
        if orientations is not None:
            rots = _as_rotations(orientations)
            if len(rots) == 1:
                self._fixed = rots
            else:
                keys = np.linspace(0.0, 1.0, len(rots)) if keys is None else np.asarray(keys, float)
                if keys.shape != (len(rots),) or not np.all(np.isfinite(keys)) \
                        or np.any(np.diff(keys) <= 0) or keys[0] != 0.0 or keys[-1] != 1.0:
                    raise ValueError('orientation keys must increase strictly from 0 to 1, one per orientation')
                self._slerp = Slerp(keys, rots)

    @classmethod
    def timed(cls, curve, duration, profile='quintic', accel=None, orientations=None, keys=None, limits=None):
        """Traverse ``curve`` in ``duration`` s with the named profile."""
        return cls(curve, progress_profile(duration, profile, accel, limits), orientations, keys)

    @property
    def duration(self) -> float:
        return self.profile.duration

    @property
    def oriented(self) -> bool:
        """True when the path sets the tool's orientation (else positions only)."""
        return self._slerp is not None or self._fixed is not None

    def stretched(self, factor):
        """The same path traversed ``factor`` times as slowly (the same poses, later)."""
        out = object.__new__(CartesianPath)
        out.curve, out.profile, out._slerp, out._fixed = self.curve, self.profile.stretched(factor), \
            self._slerp, self._fixed
        return out

    def sample(self, t):
        """Tool position, velocity and acceleration at times ``t``.

        Returns
        -------
        p, v, a : ndarray, each shape (N, 3)
            m, m/s, m/s^2 in the base frame.
        """
        u, ud, udd = (x[:, 0] for x in self.profile.sample(t))
        length = self.curve.length
        p, dp, ddp = self.curve.at(np.clip(u, 0.0, 1.0) * length)
        sd = (ud * length)[:, None]
        sdd = (udd * length)[:, None]
        return p, dp * sd, ddp * sd**2 + dp * sdd

    def orientations(self, t):
        """Tool orientations at times ``t`` (a scipy Rotation of N), or None if not set."""
        return self._orientations_at(self.profile.sample(t)[0][:, 0])

    def _orientations_at(self, u):
        u = np.clip(u, 0.0, 1.0)
        if self._slerp is not None:
            return self._slerp(u)
        if self._fixed is not None:
            return Rotation.from_quat(np.repeat(self._fixed.as_quat(), u.size, axis=0))
        return None

    def poses(self, t):
        """4x4 tool poses at times ``t``, shape (N, 4, 4) (identity rotation if none set)."""
        u = self.profile.sample(t)[0][:, 0]          # the progress, sampled once for both
        p = self.curve.at(np.clip(u, 0.0, 1.0) * self.curve.length)[0]
        out = np.zeros((p.shape[0], 4, 4))
        out[:, :3, 3] = p
        out[:, 3, 3] = 1.0
        rots = self._orientations_at(u)
        out[:, :3, :3] = np.eye(3) if rots is None else rots.as_matrix()
        return out
