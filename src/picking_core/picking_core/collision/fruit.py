"""Apples the arm is not picking: touched gently they only sway, hit fast they bruise (pure core).

The apples still on the tree are not obstacles: a cluster leaves no way to an apple that touches none
of its neighbours, and a finger brushing a neighbour at walking pace does no harm. What bruises is
speed: a link passing an apple faster than the bruising speed. :class:`Neighbours` finds, along a
motion, the first sample where a link within reach of an apple moves faster than ``speed``; a joint
move that does so goes around the apples (:func:`~picking_core.approaches.clear_plan`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kinematics.capsules import point_segment_distances

#: m: an apple's radius as the planner assumes it (the largest of the orchard's, 9 cm across).
RADIUS = 0.045
#: m: how near an apple counts as touching it (the capsules are the links' own size).
MARGIN = 0.01
#: The least speed allowed past a swaying apple, as a fraction of the speed allowed past a still one.
MIN_PASS = 0.25


@dataclass(frozen=True)
class FastTouch:
    """Link ``link`` passes apple ``apple`` (its index among the neighbours) at ``speed`` m/s at time ``time``,
    faster than ``limit``, the speed allowed past that apple (m/s)."""

    time: float
    apple: int
    link: str
    speed: float
    limit: float = np.inf

    def __str__(self):
        return f'{self.link} passes apple {self.apple} at {self.speed:.2f} m/s, t = {self.time:.3f} s'


class Neighbours:
    """The apples ``centres`` (n, 3), m in the arm's base, of radius ``radius``, seen by ``capsules``
    (an :class:`~picking_core.kinematics.capsules.ArmCapsules`), passed no faster than ``speed`` m/s (the
    pick cycle's ``apple_pass_speed``: below the 1 m/s an apple bruises at, with a margin for the servo's lag).
    ``sway`` (n, 2), for apples that sway: how far each strays from its centre (m) and its fastest (m/s), from
    :meth:`~picking_core.moving_pick.Follow.reach`: the arm keeps that much farther off to count as passing it,
    and passes it slower by its own speed (they meet at the sum of the two)."""

    def __init__(self, capsules, centres, speed, radius=RADIUS, margin=MARGIN, sway=None):
        self.capsules = capsules
        self.centres = np.asarray(centres, float).reshape(-1, 3)
        self.radius, self.speed, self.margin = float(radius), float(speed), float(margin)
        sway = np.zeros((len(self.centres), 2)) if sway is None else np.asarray(sway, float).reshape(-1, 2)
        self.reach = self.radius + self.margin + sway[:, 0]
        # (An apple swaying faster than the speed allowed is still passed, slowly.)
        self.limits = np.maximum(self.speed - sway[:, 1], MIN_PASS * self.speed)

    def __len__(self):
        return len(self.centres)

    def _touching(self, seg):
        """(N, n, K) True where capsule k at sample i is within the margin of apple a."""
        d = point_segment_distances(self.centres[None, :, None], seg[:, None, :, 0], seg[:, None, :, 1])
        return d < self.capsules.radius[None, None] + self.reach[None, :, None]

    def first_fast_touch(self, t, q, within=None):
        """The first :class:`FastTouch` along the samples ``t`` (N,), ``q`` (N, dof) of a motion (only at the
        samples where ``within`` (N,) is True, if given), or None."""
        if not len(self.centres) or len(t) < 2:
            return None
        seg = self.capsules.segments(q)                                   # (N, K, 2, 3)
        touching = self._touching(seg)
        if within is not None:
            touching &= np.asarray(within, bool)[:, None, None]
        if not touching.any():
            return None
        speed = np.linalg.norm(np.gradient(seg, np.asarray(t, float), axis=0), axis=-1).max(axis=-1)   # (N, K)
        fast = touching & (speed[:, None, :] > self.limits[None, :, None])
        if not fast.any():
            return None
        i, a, k = (int(x[0]) for x in np.nonzero(fast))
        return FastTouch(float(t[i]), a, self.capsules.links[k], float(speed[i, k]), float(self.limits[a]))

    def touching(self, q, ignore=()):
        """(N,) True where the arm at ``q`` (N, dof) touches an apple other than those of ``ignore`` (indices)."""
        keep = np.ones(len(self.centres), bool)
        keep[np.asarray(ignore, int)] = False
        return self._touching(self.capsules.segments(q))[:, keep].any(axis=(1, 2))

    def touched_at(self, q):
        """Indices of the apples the arm touches at ``q`` (N, dof) anywhere."""
        return np.flatnonzero(self._touching(self.capsules.segments(q)).any(axis=(0, 2)))
