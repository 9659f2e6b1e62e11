"""Validation of Cartesian inputs."""

from __future__ import annotations

import numpy as np


def as_point(p, name: str) -> np.ndarray:
    """A finite 3-vector (m)."""
    try:
        arr = np.array(p, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f'{name} must be three numbers (x, y, z)') from exc
    if arr.shape != (3,):
        raise ValueError(f'{name} must be three numbers (x, y, z), got shape {arr.shape}')
    if not np.isfinite(arr).all():
        raise ValueError(f'{name} must be finite, got {arr.tolist()}')
    return arr


def as_lengths(s) -> np.ndarray:
    """Path parameters (arc lengths) as a finite 1-D array."""
    arr = np.array(s, dtype=float)
    if arr.ndim == 0:
        arr = arr.reshape(1)
    if arr.ndim != 1 or not np.isfinite(arr).all():
        raise ValueError('path parameter s must be a finite number or 1-D sequence')
    return arr


def as_count(n, minimum: int = 2) -> int:
    """A whole number of points, at least ``minimum``."""
    if isinstance(n, bool) or int(n) != n or n < minimum:
        raise ValueError(f'number of points must be a whole number >= {minimum}, got {n!r}')
    return int(n)
