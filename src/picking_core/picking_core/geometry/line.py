"""Straight-line Cartesian segment."""

from __future__ import annotations

import numpy as np

from ._checks import as_count, as_lengths, as_point


class Line:
    """The straight segment from ``start`` to ``end`` (m), parameterised by arc length.

    A zero-length line is allowed: with an orientation change it is a pure
    re-orientation of the tool about a fixed point.
    """

    __slots__ = ('start', 'end', 'length', 'direction')

    def __init__(self, start, end):
        self.start = as_point(start, 'start')
        self.end = as_point(end, 'end')
        delta = self.end - self.start
        self.length = float(np.linalg.norm(delta))
        self.direction = delta / self.length if self.length > 0.0 else np.zeros(3)
        for a in (self.start, self.end, self.direction):
            a.flags.writeable = False

    def __repr__(self) -> str:
        return f'Line(start={self.start.tolist()}, end={self.end.tolist()}, length={self.length:.6g})'

    def at(self, s):
        """Point, first and second derivative with respect to arc length.

        Parameters
        ----------
        s : float or array_like, shape (N,)
            Arc length from ``start``, m, clipped to ``[0, length]``.

        Returns
        -------
        p, dp_ds, d2p_ds2 : ndarray, each shape (N, 3)
        """
        s = np.clip(as_lengths(s), 0.0, self.length)
        p = self.start + s[:, None] * self.direction
        return p, np.broadcast_to(self.direction, p.shape).copy(), np.zeros_like(p)

    def points(self, n):
        """``n`` equally spaced points, ``start`` first and ``end`` last, shape (n, 3)."""
        n = as_count(n)
        return self.at(np.linspace(0.0, self.length, n))[0]
