"""Input validation shared by the trajectory constructors.

Every public function turns its arguments into float arrays here, so that a bad
input is refused with a ValueError that names the argument, before any maths.
"""

from __future__ import annotations

import numpy as np


def as_joint_vector(x, name: str, n: int | None = None) -> np.ndarray:
    """A finite 1-D float array (a scalar becomes one joint).

    Parameters
    ----------
    x : float or array_like
    name : str
        Argument name for the error message.
    n : int, optional
        Required length; a scalar is broadcast to it.
    """
    try:
        arr = np.array(x, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f'{name} must be a number or a sequence of numbers') from exc
    if arr.ndim == 0:
        arr = np.full(1 if n is None else n, float(arr))
    if arr.ndim != 1 or arr.size == 0:
        raise ValueError(f'{name} must be a number or a non-empty 1-D sequence, got shape {arr.shape}')
    if n is not None and arr.size != n:
        raise ValueError(f'{name} has {arr.size} values, expected {n} (one per joint)')
    if not (np.abs(arr) <= MAX_MAGNITUDE).all():
        raise ValueError(f'{name} must be finite and within ±{MAX_MAGNITUDE:g}, got {arr.tolist()}')
    return arr


#: Joint values (positions, velocities, accelerations, limits) beyond this magnitude are input
#: errors: no joint turns a billion radians, and the polynomials of such values overflow.
MAX_MAGNITUDE = 1e9
#: Durations outside this range (s) are input errors, not motions: shorter than a microsecond
#: or longer than about eleven days, their powers under- or overflow in the polynomials.
MIN_DURATION, MAX_DURATION = 1e-6, 1e6


def as_duration(duration, name: str = 'duration') -> float:
    """A finite number of seconds in [MIN_DURATION, MAX_DURATION]."""
    try:
        value = float(duration)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f'{name} must be a number of seconds') from exc
    if not MIN_DURATION <= value <= MAX_DURATION:
        raise ValueError(f'{name} must be a number of seconds between {MIN_DURATION:g} and {MAX_DURATION:g}, '
                         f'got {duration!r}')
    return value


def as_time_array(t) -> np.ndarray:
    """Sample times as a finite 1-D float array."""
    return time_array_and_extremes(t)[0]


def time_array_and_extremes(t):
    """Sample times as a finite 1-D float array, with its smallest and largest values
    (``nan`` for no times): the two passes over the times that the finiteness check costs,
    shared with a sampler that needs the extremes too.
    """
    try:
        arr = np.asarray(t, dtype=float)            # not copied: only read
    except (TypeError, ValueError) as exc:
        raise ValueError('t must be a number or a 1-D sequence of times') from exc
    if arr.ndim == 0:
        arr = arr.reshape(1)
    if arr.ndim != 1:
        raise ValueError(f't must be a number or a 1-D sequence, got shape {arr.shape}')
    if not arr.size:
        return arr, np.nan, np.nan
    # The extremes are NaN if any time is (and infinite if any is): no mask as long as t.
    lo, hi = float(arr.min()), float(arr.max())
    if not (np.isfinite(lo) and np.isfinite(hi)):
        raise ValueError('t must be finite')
    return arr, lo, hi


def as_points(points, name: str = 'points', min_points: int = 2) -> np.ndarray:
    """Way points as a finite (m, n_joints) array; a 1-D input is one joint."""
    try:
        arr = np.array(points, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f'{name} must be a sequence of joint positions') from exc
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2 or arr.shape[0] < min_points or arr.shape[1] < 1:
        raise ValueError(f'{name} must have at least {min_points} rows of joint positions, '
                         f'got shape {arr.shape}')
    if not (np.abs(arr) <= MAX_MAGNITUDE).all():
        raise ValueError(f'{name} must be finite and within ±{MAX_MAGNITUDE:g}')
    return arr


def as_durations(durations, m: int) -> np.ndarray:
    """``m`` finite, strictly positive segment durations (a scalar is repeated)."""
    try:
        arr = np.array(durations, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError('durations must be numbers of seconds') from exc
    if arr.ndim == 0:
        arr = np.full(m, float(arr))
    if arr.ndim != 1 or arr.size != m:
        raise ValueError(f'durations must have one value per segment ({m}), got shape {arr.shape}')
    if not ((arr >= MIN_DURATION) & (arr <= MAX_DURATION)).all():
        raise ValueError(f'durations must be between {MIN_DURATION:g} and {MAX_DURATION:g} s, got {arr.tolist()}')
    return arr

