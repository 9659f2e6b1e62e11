"""Apples the arm is not picking: touched gently they only sway, hit fast they bruise (pure core).

The apples still on the tree are not obstacles: a cluster leaves no way to an apple that touches none
of its neighbours, and a finger brushing a neighbour at walking pace does no harm. What bruises is
speed: a link passing an apple faster than the bruising speed. What tears an apple off, at any speed,
is a link pressing down into it from above, between it and its branch: the apple cannot swing out of its
way, and its stem is stretched. :class:`Neighbours` finds, along a motion, the first sample where a link
within reach of an apple moves faster than ``speed``, or one pressing on an apple from above moves at all;
a joint move that does so goes around the apples (:func:`~picking_core.approaches.clear_plan`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..fruit import ArmBodies
from ..kinematics.capsules import point_segment_distances

#: m: an apple's radius as the planner assumes it (the largest of the orchard's, 9 cm across).
RADIUS = 0.045
#: m: how near an apple counts as touching it (the capsules are the links' own size).
MARGIN = 0.01
#: m: how far a link may press an apple away from its branch (half the stretch that takes one off its stem).
PULL = 0.01
#: m/s: a link pressing on an apple slower than this is at rest there (a move's ends), not dragging it.
AT_REST = 0.02
#: The least speed allowed past a swaying apple, as a fraction of the speed allowed past a still one.
MIN_PASS = 0.25


@dataclass(frozen=True)
class FastTouch:
    """Link ``link`` passes apple ``apple`` (its index among the neighbours) at ``speed`` m/s at time ``time``,
    faster than ``limit``, the speed allowed past that apple (m/s); ``stem``: pressing it away from its branch,
    where no speed is allowed (slowing the move does not help)."""

    time: float
    apple: int
    link: str
    speed: float
    limit: float = np.inf
    stem: bool = False

    def __str__(self):
        where = f'presses apple {self.apple} off its stem' if self.stem else f'passes apple {self.apple}'
        return f'{self.link} {where} at {self.speed:.2f} m/s, t = {self.time:.3f} s'


class Neighbours:
    """The apples ``centres`` (n, 3), m in the arm's base, of radius ``radius``, touched by the arm of ``capsules``
    (an :class:`~picking_core.kinematics.capsules.ArmCapsules`, whose coarse capsules bound the gripper and the
    apple it holds; and the bodies the simulator's world judges touches by, the gripper's wrist and fingers among
    them: :class:`~picking_core.fruit.ArmBodies`, the only ones that tell which way they press an apple), passed
    no faster than ``speed`` m/s (the pick cycle's ``apple_pass_speed``: below the 1 m/s an apple bruises at, with
    a margin for the servo's lag).
    ``sway`` (n, 2), for apples that sway: how far each strays from its centre (m) and its fastest (m/s), from
    :meth:`~picking_core.moving_pick.Follow.reach`: the arm keeps that much farther off to count as passing it,
    and passes it slower by its own speed (they meet at the sum of the two). Each apple hangs straight down (-z of
    the arm's base) from its branch: no moving link may press it more than PULL away from it."""

    def __init__(self, capsules, centres, speed, radius=RADIUS, margin=MARGIN, sway=None):
        self.capsules, self.bodies = capsules, ArmBodies(capsules)
        # Every body, the coarse capsules then the gripper's own: their radii and names, and which of them are the
        # world's (``fine``: the links before the wrist's last joint and the gripper's; ArmBodies' order).
        self.radii = np.concatenate([capsules.radius, self.bodies.gripper_radii])
        self.names = [*capsules.links, *self.bodies.gripper_names]
        gripper = np.ones(len(self.bodies.gripper_radii), bool)
        self.fine = np.concatenate([capsules.frame != capsules.arm.dof, gripper])
        self.centres = np.asarray(centres, float).reshape(-1, 3)
        self.radius, self.speed, self.margin = float(radius), float(speed), float(margin)
        sway = np.zeros((len(self.centres), 2)) if sway is None else np.asarray(sway, float).reshape(-1, 2)
        self.reach = self.radius + self.margin + sway[:, 0]
        # (An apple swaying faster than the speed allowed is still passed, slowly.)
        self.limits = np.maximum(self.speed - sway[:, 1], MIN_PASS * self.speed)
        self.depth = self.radius + sway[:, 0]            # how far a link may reach into an apple, pressing it

    def __len__(self):
        return len(self.centres)

    def _segments(self, q):
        """(N, K, 2, 3): the capsules and the bodies at ``q`` (N, dof), or (N, dof + 1) with the fingers' opening
        last."""
        q = np.atleast_2d(np.asarray(q, float))
        dof = self.bodies.arm.dof
        tools = self.bodies.arm.joint_frames(q[:, :dof])[:, -1]
        gripper = self.bodies.gripper(tools, q[:, dof] if q.shape[1] > dof else None)
        return np.concatenate([self.capsules.segments(q[:, :dof]), gripper], axis=1)

    def _touching(self, seg):
        """(N, n, K) True where body k at sample i is within the margin of apple a."""
        d = point_segment_distances(self.centres[None, :, None], seg[:, None, :, 0], seg[:, None, :, 1])
        return d < self.radii[None, None] + self.reach[None, :, None]

    def _pressing(self, seg):
        """(N, n, K) True where body k at sample i would press apple a more than PULL away from its branch:
        it reaches that far into the apple along the stem's line, down from above."""
        a, b = seg[:, None, :, 0], seg[:, None, :, 1]                    # (N, 1, K, 3)
        ab, ac = b - a, self.centres[None, :, None] - a
        s = np.clip(np.einsum('...i,...i', ac, ab) / np.maximum(np.einsum('...i,...i', ab, ab), 1e-18), 0.0, 1.0)
        above = a + s[..., None] * ab - self.centres[None, :, None]      # from the centre to the link's axis
        dist = np.maximum(np.linalg.norm(above, axis=-1), 1e-9)
        into = self.radii[None, None] + self.depth[None, :, None] - dist
        return (into * above[..., 2] / dist > PULL) & self.fine[None, None]

    def first_fast_touch(self, t, q, within=None, pressing=True, spare=(), fast=True):
        """The first :class:`FastTouch` along the samples ``t`` (N,), ``q`` (N, dof or dof + 1: see
        :meth:`touching`) of a motion (only at the samples where ``within`` (N,) is True, if given): with ``fast``,
        a link passing an apple faster than allowed; with ``pressing``, a link pressing an apple off its stem, but
        for the apples ``spare`` (indices); or None."""
        if not len(self.centres) or len(t) < 2:
            return None
        seg = self._segments(q)                                           # (N, K, 2, 3)
        touching = self._touching(seg)
        if within is not None:
            touching &= np.asarray(within, bool)[:, None, None]
        if not touching.any():
            return None
        pressing = touching & self._pressing(seg) if pressing else np.zeros_like(touching)
        pressing[:, np.asarray(spare, int)] = False
        speed = np.linalg.norm(np.gradient(seg, np.asarray(t, float), axis=0), axis=-1).max(axis=-1)   # (N, K)
        passing = touching & (speed[:, None, :] > self.limits[None, :, None]) if fast else np.zeros_like(touching)
        found = passing | (pressing & (speed[:, None, :] > AT_REST))
        if not found.any():
            return None
        i, a, k = (int(x[0]) for x in np.nonzero(found))
        if not passing[i, a, k]:
            return FastTouch(float(t[i]), a, self.names[k], float(speed[i, k]), 0.0, stem=True)
        return FastTouch(float(t[i]), a, self.names[k], float(speed[i, k]), float(self.limits[a]))

    def touching(self, q, ignore=()):
        """(N,) True where the arm at ``q`` (N, dof; or dof + 1, the fingers' opening last, else they are open)
        touches an apple other than those of ``ignore`` (indices)."""
        keep = np.ones(len(self.centres), bool)
        keep[np.asarray(ignore, int)] = False
        return self._touching(self._segments(q))[:, keep].any(axis=(1, 2))

    def pressing(self, q, ignore=()):
        """(N,) True where the arm at ``q`` (as for :meth:`touching`) presses an apple other than those of
        ``ignore`` off its stem."""
        keep = np.ones(len(self.centres), bool)
        keep[np.asarray(ignore, int)] = False
        seg = self._segments(q)
        return (self._touching(seg) & self._pressing(seg))[:, keep].any(axis=(1, 2))

    def touched_at(self, q):
        """Indices of the apples the arm touches at ``q`` (as for :meth:`touching`) anywhere."""
        return np.flatnonzero(self._touching(self._segments(q)).any(axis=(0, 2)))
