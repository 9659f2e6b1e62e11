"""Spatial circular arc through three points (paper Sec. 2.3, Eq. 4-5, Figs. 3, 4, 13).

The paper's "three-step" method: build a frame {R} in the arc's plane (Eq. 4),
interpolate the circle in that plane, and map the points back to the base
frame. {R} has its origin at P1, Z_R along P1P3, Y_R along P1P3 x P1P2 and
X_R = Y_R x Z_R, so every point of the arc has y_R = 0.

The paper's Eq. 5, printed as the inverse of Eq. 4, is misprinted (its rotation
block is not transposed and its translation rows mix components); the inverse
of ``[R p; 0 1]`` is ``[R^T  -R^T p; 0 1]``, which :attr:`Arc.frame_inverse`
returns.
"""

from __future__ import annotations

import numpy as np

from ._checks import as_count, as_lengths, as_point

# sin of the smallest angle at P1 between P1P2 and P1P3 accepted as "not collinear".
_COLLINEAR_SIN = 1e-9


class Arc:
    """A circular arc from ``p1`` through ``p2`` to ``p3``; build it with :meth:`through`.

    Attributes
    ----------
    center : ndarray, shape (3,)
        Circle centre, m.
    radius : float
        m.
    normal : ndarray, shape (3,)
        Unit axis about which the arc turns (right-hand rule) from p1 to p3.
    sweep : float
        Angle from p1 through p2 to p3, rad, in (0, 2 pi): arcs beyond
        180 degrees are fine.
    frame : ndarray, shape (4, 4)
        The arc-plane frame of Eq. 4 (maps {R} coordinates to the base frame).
    frame_inverse : ndarray, shape (4, 4)
        Its inverse (the corrected Eq. 5).
    """

    __slots__ = ('p1', 'p2', 'p3', 'center', 'radius', 'normal', 'sweep', 'frame',
                 'frame_inverse', '_center_r', '_phi1')

    def __init__(self, *_):
        raise TypeError('build an Arc with Arc.through(p1, p2, p3)')

    @classmethod
    def through(cls, p1, p2, p3) -> 'Arc':
        """The arc that starts at ``p1``, passes ``p2`` and ends at ``p3``.

        Raises
        ------
        ValueError
            For non-finite, repeated or (nearly) collinear points.
        """
        p1, p2, p3 = (as_point(p, name) for p, name in ((p1, 'p1'), (p2, 'p2'), (p3, 'p3')))
        d12, d13, d23 = p2 - p1, p3 - p1, p3 - p2
        lengths = [np.linalg.norm(d) for d in (d12, d13, d23)]
        scale = max(max(lengths), float(np.max(np.abs(np.concatenate((p1, p2, p3))))), 1e-300)
        if min(lengths) <= 1e-12 * scale:
            raise ValueError('arc points must be distinct: two of p1, p2, p3 coincide')
        cross = np.cross(d13, d12)
        if np.linalg.norm(cross) <= _COLLINEAR_SIN * lengths[0] * lengths[1]:
            raise ValueError('arc points are collinear: p1, p2, p3 lie on one line, no circle '
                             'passes through them (use a straight line instead)')
        # Eq. 4: the arc-plane frame {R}.
        z_r = d13 / lengths[1]
        y_r = cross / np.linalg.norm(cross)
        x_r = np.cross(y_r, z_r)
        rot = np.column_stack((x_r, y_r, z_r))
        frame = np.eye(4)
        frame[:3, :3], frame[:3, 3] = rot, p1
        frame_inv = np.eye(4)
        frame_inv[:3, :3], frame_inv[:3, 3] = rot.T, -rot.T @ p1
        # Step 1: the circle in the (x_R, z_R) plane; p1 = (0, 0), p3 = (0, d).
        x2, z2 = x_r @ d12, z_r @ d12
        z_c = 0.5 * lengths[1]
        x_c = (x2 * x2 + z2 * z2 - 2.0 * z2 * z_c) / (2.0 * x2)
        radius = float(np.hypot(x_c, z_c))
        phi1 = np.arctan2(-z_c, -x_c)
        phi3 = np.arctan2(lengths[1] - z_c, -x_c)
        # Travel from p1 towards p2 turns about -Y_R, i.e. phi increases.
        sweep = float((phi3 - phi1) % (2.0 * np.pi))

        arc = object.__new__(cls)
        arc.p1, arc.p2, arc.p3 = p1, p2, p3
        arc._center_r = np.array([x_c, 0.0, z_c])
        arc._phi1 = float(phi1)
        arc.center = rot @ arc._center_r + p1
        arc.radius = radius
        arc.normal = -y_r
        arc.sweep = sweep
        arc.frame, arc.frame_inverse = frame, frame_inv
        for a in (p1, p2, p3, arc.center, arc.normal, frame, frame_inv, arc._center_r):
            a.flags.writeable = False
        return arc

    def __repr__(self) -> str:
        return (f'Arc(center={np.round(self.center, 9).tolist()}, radius={self.radius:.6g}, '
                f'sweep={np.degrees(self.sweep):.6g} deg)')

    @property
    def length(self) -> float:
        """Arc length, m."""
        return self.radius * self.sweep

    def at(self, s):
        """Point, first and second derivative with respect to arc length.

        The circle is evaluated in the arc plane {R} and mapped back with the
        frame of Eq. 4 (steps 1 and 2 of Fig. 4).

        Parameters
        ----------
        s : float or array_like, shape (N,)
            Arc length from ``p1``, m, clipped to ``[0, length]``.

        Returns
        -------
        p, dp_ds, d2p_ds2 : ndarray, each shape (N, 3)
        """
        s = np.clip(as_lengths(s), 0.0, self.length)
        phi = self._phi1 + s / self.radius
        c, sn = np.cos(phi), np.sin(phi)
        zero = np.zeros_like(phi)
        local = self._center_r + self.radius * np.column_stack((c, zero, sn))
        rot, origin = self.frame[:3, :3], self.frame[:3, 3]
        p = local @ rot.T + origin
        dp = np.column_stack((-sn, zero, c)) @ rot.T
        ddp = np.column_stack((-c, zero, -sn)) @ rot.T / self.radius
        return p, dp, ddp

    def points(self, n):
        """``n`` points at equal angle steps, ``p1`` first and ``p3`` last, shape (n, 3).

        ``points(47)`` gives the paper's 45 insertion points between P1 and P3.
        """
        n = as_count(n)
        return self.at(np.linspace(0.0, self.length, n))[0]

    def chord_error(self, n):
        """Largest distance between the polyline of ``n`` equal-angle points and the arc, m.

        Sec. 3.2: the sagitta ``r (1 - cos(dphi / 2))`` of each chord.
        """
        n = as_count(n)
        return self.radius * (1.0 - np.cos(self.sweep / (2.0 * (n - 1))))
