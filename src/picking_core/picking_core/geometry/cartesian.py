"""A tool path in time: a Line or Arc traversed by a 1-D profile, orientation slerped.

The curve gives the position as a function of arc length s; a time profile
(cubic, quintic, LSPB -- the same ones the joints use) gives the progress
``u(t)`` from 0 to 1, and ``s = u * length``. The orientation is interpolated by
quaternion slerp between key orientations at chosen progress values.
"""

from __future__ import annotations

import functools

import numpy as np
from scipy.spatial.transform import Rotation

from .. import trajectory
from ..trajectory._checks import as_duration

PROFILES = ('cubic', 'quintic', 'lspb', 'optimal')
#: Key orientations whose rotation matrices agree to this (about as many radians) are one
#: orientation, held along the path.
SAME_ORIENTATION = 1e-12
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


# A scipy Rotation of proper rotation matrices that are checked already: recent scipy checks
# each again unless told not to (``assume_valid``); older versions have neither that check nor the flag.
try:
    Rotation.from_matrix(np.eye(3), assume_valid=True)
    _from_valid_matrices = functools.partial(Rotation.from_matrix, assume_valid=True)
except TypeError:
    _from_valid_matrices = Rotation.from_matrix


def _key_matrices(orientations):
    """Key orientations as rotation matrices (k, 3, 3), k >= 1, from a Rotation,
    quaternions (x, y, z, w) (k, 4), or proper rotation matrices (k, 3, 3)."""
    if isinstance(orientations, Rotation):
        return orientations.as_matrix().reshape(-1, 3, 3)
    arr = np.array(orientations, dtype=float)
    matrices = arr.ndim == 3 and arr.shape[1:] == (3, 3)
    if not (matrices or arr.ndim == 2 and arr.shape[1] == 4) or not len(arr):
        raise ValueError('orientations must be quaternions (x, y, z, w), shape (k, 4), or rotation matrices, '
                         'shape (k, 3, 3)')
    if not np.isfinite(arr).all():
        raise ValueError('orientations must be finite')
    if matrices:
        if np.abs(arr @ np.swapaxes(arr, 1, 2) - np.eye(3)).max() > 1e-6 or (np.linalg.det(arr) <= 0).any():
            raise ValueError('orientation matrices must be proper rotation matrices (orthonormal, determinant +1)')
        return arr
    scale = np.abs(arr).max(axis=1, keepdims=True)           # norms of huge quaternions overflow
    scaled = arr / np.maximum(scale, 1e-300)
    if np.any(scale[:, 0] * np.linalg.norm(scaled, axis=1) < 1e-9):
        raise ValueError('orientation quaternions must be finite and non-zero')
    return Rotation.from_quat(scaled).as_matrix()


class _Slerp:
    """Key orientations at progress keys, slerped between: the formula of scipy's ``Slerp``
    (each key turned by the rotation vector to the next, scaled), with scipy's conversions.

    Built from matrices and evaluated to matrices (what the poses need): scipy's ``Slerp``
    builds two ``Rotation`` objects per call and composes them through its array-API
    layers, which cost more than the arithmetic for a line's few dozen samples.
    """

    __slots__ = ('keys', 'spans', 'matrices', 'steps')

    def __init__(self, keys, matrices):
        self.keys, self.spans, self.matrices = keys, np.diff(keys), matrices
        turns = np.swapaxes(matrices[:-1], 1, 2) @ matrices[1:]       # key i -> key i + 1, in frame i
        self.steps = _from_valid_matrices(turns).as_rotvec()

    def __call__(self, u):
        """Rotation matrices (N, 3, 3) at progress ``u`` (N,) in [0, 1]."""
        i = np.clip(np.searchsorted(self.keys, u, side='right') - 1, 0, self.spans.size - 1)
        frac = (u - self.keys[i]) / self.spans[i]
        return self.matrices[i] @ Rotation.from_rotvec(self.steps[i] * frac[:, None]).as_matrix()


class CartesianPath:
    """Tool positions and orientations along a curve, over time.

    Parameters
    ----------
    curve : Line or Arc
        Anything with ``length`` and ``at(s) -> (p, dp/ds, d2p/ds2)``.
    profile : PiecewisePolynomial
        One joint, from 0 at its start to 1 at its end (see :func:`progress_profile`).
    orientations : Rotation, array_like of (x, y, z, w), or of 3x3 rotation matrices, optional
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
            matrices = _key_matrices(orientations)
            k = len(matrices)
            if k > 1 and keys is None:
                keys = np.linspace(0.0, 1.0, k)
            elif k > 1:
                keys = np.asarray(keys, float)
                if keys.shape != (k,) or not np.all(np.isfinite(keys)) \
                        or np.any(keys[1:] <= keys[:-1]) or keys[0] != 0.0 or keys[-1] != 1.0:
                    raise ValueError('orientation keys must increase strictly from 0 to 1, one per orientation')
            # Keys that agree to rounding (a line whose tool keeps its orientation, its start
            # pose from FK) hold the orientation: nothing to slerp at every sample.
            if k == 1 or np.abs(matrices[1:] - matrices[0]).max() <= SAME_ORIENTATION:
                self._fixed = matrices[0]
            else:
                self._slerp = _Slerp(keys, matrices)

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
        matrices = self._matrices_at(np.clip(self.profile.sample(t)[0][:, 0], 0.0, 1.0))
        return None if matrices is None else Rotation.from_matrix(matrices)

    def _matrices_at(self, u):
        """Rotation matrices (N, 3, 3) at progress ``u`` (in [0, 1]), or None if no orientation is set."""
        if self._slerp is not None:
            return self._slerp(u)
        if self._fixed is not None:
            return np.broadcast_to(self._fixed, (u.size, 3, 3))
        return None

    def poses(self, t):
        """4x4 tool poses at times ``t``, shape (N, 4, 4) (identity rotation if none set)."""
        u = np.clip(self.profile.sample(t)[0][:, 0], 0.0, 1.0)      # the progress, once for both
        p = self.curve.at(u * self.curve.length)[0]
        out = np.zeros((p.shape[0], 4, 4))
        out[:, :3, 3] = p
        out[:, 3, 3] = 1.0
        rots = self._matrices_at(u)
        out[:, :3, :3] = np.eye(3) if rots is None else rots
        return out
