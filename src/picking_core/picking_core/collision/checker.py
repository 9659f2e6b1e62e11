"""Is a motion clear? The arm's capsules against a scene, a canopy and themselves (pure core).

The broad phase is numpy over every sample at once: each link capsule's box against each
obstacle's box, and its spheres against the canopy's distance field. Only the pairs it cannot
clear go to coal's narrow phase, in time order, so the first contact is found without checking
the rest; there a link given as a box or a mesh is its convex hull, its capsule only the bound the
broad phase clears with. Self-collision compares the arm's own capsules in closed form
(:func:`~picking_core.kinematics.capsules.capsule_distances`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import coal
import numpy as np

from ..kinematics.capsules import ArmCapsules, capsule_distances, segment_distances
from .scene import Scene, convex_hull, frames_along, transform

#: m: how near an obstacle a link may come, unless told.
CLEARANCE = 0.02
#: m: no point of a link moves further than this between two checked samples.
STEP = 0.01
#: s: the first sampling of a trajectory, refined until STEP holds.
FIRST_DT = 0.02
#: Samples of random configurations that find the link pairs always in contact (as MoveIt's setup
#: assistant does): those pairs are built to touch, and are not checked.
SELF_SAMPLES = 2000
ALWAYS = 0.95


def _allowed(allowed):
    """``allowed`` as a list of :class:`Allowed` regions."""
    return [] if allowed is None else ([allowed] if isinstance(allowed, Allowed) else list(allowed))


def _request(clearance):
    """coal's query: every contact closer than ``clearance`` m, with where and how deep."""
    request = coal.CollisionRequest()
    request.security_margin = clearance
    request.enable_contact = True
    request.num_max_contacts = 64
    return request


@dataclass(frozen=True)
class Contact:
    """A link closer than the clearance to an obstacle: at sample ``index`` (time ``time``, s, NaN
    for configurations given without times),
    ``link`` within ``distance`` m (negative: inside) of ``obstacle`` at ``point`` (m)."""

    index: int
    time: float
    link: str
    obstacle: str
    point: np.ndarray
    distance: float

    def __str__(self):
        x, y, z = self.point
        how = f'{-self.distance * 100:.1f} cm into' if self.distance < 0 else f'{self.distance * 100:.1f} cm from'
        when = '' if np.isnan(self.time) else f', t = {self.time:.3f} s'
        return f'{self.link} {how} {self.obstacle} at ({x:.3f}, {y:.3f}, {z:.3f}) m{when}'


@dataclass(frozen=True)
class Allowed:
    """A sphere (``center``, ``radius``, m) where touching is allowed: the apple being picked."""

    center: np.ndarray
    radius: float

    def holds(self, point):
        x, y, z = point
        cx, cy, cz = self.center
        return (x - cx) ** 2 + (y - cy) ** 2 + (z - cz) ** 2 <= self.radius ** 2


class CollisionChecker:
    """Checks arm configurations against ``scene``, a ``canopy`` (:class:`~.scene.Canopy` or None)
    and the arm itself, keeping ``clearance`` m from obstacles (links of the arm only must not touch)."""

    def __init__(self, capsules: ArmCapsules, scene=None, canopy=None, clearance=CLEARANCE, self_check=True):
        if not clearance >= 0.0:
            raise ValueError(f'clearance must be >= 0 m, got {clearance}')
        self.capsules, self.arm = capsules, capsules.arm
        self.scene = scene if scene is not None else Scene()
        self.canopy = canopy
        self.clearance = float(clearance)
        self.request = _request(self.clearance)
        self.pairs = self._self_pairs() if self_check else np.zeros((0, 2), int)
        # Links that move: the base's own capsule stands where the arm is mounted, on the platform.
        self.moving = np.nonzero(capsules.frame > 0)[0]
        # A box's or a mesh's hull for the narrow phase; its capsule, a bound, decides nothing as too near.
        self.hulls = [None if h is None else convex_hull(h) for h in capsules.hulls] or [None] * len(capsules.links)
        self.bounds_only = np.array([h is not None for h in self.hulls], bool)

    def replaced(self, scene=None, canopy=None, clearance=None):
        """The same arm's checker with another scene, canopy or clearance (the self-collision pairs,
        found once, kept)."""
        other = object.__new__(CollisionChecker)
        other.__dict__.update(self.__dict__)
        if scene is not None:
            other.scene = scene
        if canopy is not None:
            other.canopy = canopy
        if clearance is not None:
            if not clearance >= 0.0:
                raise ValueError(f'clearance must be >= 0 m, got {clearance}')
            other.clearance = float(clearance)
            other.request = _request(other.clearance)
        return other

    def _self_pairs(self):
        """Link capsule pairs to check against each other: not on neighbouring frames, and not in
        contact in nearly every configuration (built to touch)."""
        c = self.capsules
        k = np.arange(len(c.links))
        a, b = np.triu_indices(len(k), 1)
        apart = np.abs(c.frame[a] - c.frame[b]) > 1
        a, b = a[apart], b[apart]
        rng = np.random.default_rng(0)
        q = rng.uniform(self.arm.lower, self.arm.upper, (SELF_SAMPLES, self.arm.dof))
        seg = c.segments(q)
        d = capsule_distances(seg, c.radius, seg, c.radius)[:, a, b]
        keep = (d < 0.0).mean(axis=0) < ALWAYS
        return np.stack([a[keep], b[keep]], axis=1)

    # -- configurations ------------------------------------------------------------------------------------------

    def first_contact(self, q, times=None, allowed=None):
        """The earliest :class:`Contact` over the configurations ``q`` (N, dof) at ``times`` (s;
        none by default), or None when all are clear. Touches inside ``allowed``
        (:class:`Allowed`, or a list of them) do not count."""
        q = np.atleast_2d(np.asarray(q, float))[:, :self.arm.dof]
        times = np.full(len(q), np.nan) if times is None else np.asarray(times, float)
        for n in np.nonzero(self.colliding(q, allowed))[0]:
            contact = self._contacts(q[n:n + 1], times[n:n + 1], allowed, first=True)[0]
            if contact is not None:
                return dataclasses.replace(contact, index=int(n))
        return None

    def contacts(self, q, allowed=None):
        """For each configuration of ``q`` (N, dof), a :class:`Contact` (one of its contacts) or None."""
        q = np.atleast_2d(np.asarray(q, float))[:, :self.arm.dof]
        found = [None] * len(q)
        for n in np.nonzero(self.colliding(q, allowed))[0]:
            found[n] = self._contacts(q[n:n + 1], None, allowed, first=True)[0]
            if found[n] is not None:
                found[n] = dataclasses.replace(found[n], index=int(n))
        return found

    def colliding(self, q, allowed=None):
        """(N,) bool: which configurations of ``q`` (N, dof) come within the clearance of an obstacle
        or touch themselves. The broad phase decides what it can both ways (a link surely clear, or
        surely too near: a branch's capsule measured exactly, the canopy's distance field); coal
        decides the rest."""
        q = np.atleast_2d(np.asarray(q, float))[:, :self.arm.dof]
        allowed = _allowed(allowed)
        seg = self.capsules.segments(q)
        hit = np.array([c is not None for c in self._self_contacts(seg, np.zeros(len(q)))], bool)
        triples, certain = self._candidates(seg, decide=True)
        if allowed and certain.any():
            # A link near an allowed region may touch inside it only: coal decides those.
            ends = seg[triples[:, 0], triples[:, 1]]
            r = self.capsules.radius[triples[:, 1]] + self.clearance
            for a in allowed:
                d = segment_distances(ends[:, 0], ends[:, 1], a.center, a.center)
                certain &= d > a.radius + r
        hit[triples[certain, 0]] = True
        triples = triples[~certain]
        triples = triples[~hit[triples[:, 0]]]
        if len(triples):
            frames, lengths = self._placed(q, seg, triples)
            for m, (n, k, o) in enumerate(triples):
                if not hit[n]:
                    hit[n] = self._narrow(frames[m], lengths[m], k, o, n, 0.0, allowed) is not None
        return hit

    def every_contact(self, q, times=None):
        """For each configuration of ``q`` (N, dof), the list of every link's contacts, one per
        link and obstacle (the arm's own links included only with self-collision on)."""
        q = np.atleast_2d(np.asarray(q, float))[:, :self.arm.dof]
        times = np.full(len(q), np.nan) if times is None else np.asarray(times, float)
        seg = self.capsules.segments(q)
        out = [[c] if c is not None else [] for c in self._self_contacts(seg, times)]
        triples, _ = self._candidates(seg)
        if len(triples):
            frames, lengths = self._placed(q, seg, triples)
            for m, (n, k, o) in enumerate(triples):
                contact = self._narrow(frames[m], lengths[m], k, o, n, times[n], [])
                if contact is not None:
                    out[n].append(contact)
        return out

    def _contacts(self, q, times, allowed, first):
        q = np.atleast_2d(np.asarray(q, float))[:, :self.arm.dof]
        times = np.full(len(q), np.nan) if times is None else np.asarray(times, float)
        allowed = _allowed(allowed)
        seg = self.capsules.segments(q)                                   # (N, K, 2, 3)
        found = self._self_contacts(seg, times)
        earliest = next((n for n, c in enumerate(found) if c is not None), len(q))
        triples, _ = self._candidates(seg)
        if not len(triples):
            return found
        frames, lengths = self._placed(q, seg, triples)
        for m, (n, k, o) in enumerate(triples):                           # in time order
            if first and n > earliest:
                break
            if found[n] is None:
                found[n] = self._narrow(frames[m], lengths[m], k, o, n, times[n], allowed)
                if found[n] is not None:
                    earliest = min(earliest, n)
        return found

    def _candidates(self, seg, decide=False):
        """``(triples, certain)``: the ``(sample, link, obstacle)`` triples the broad phase cannot
        clear, sorted by sample (obstacle: an index into the scene, or -1 for the canopy), and, with
        ``decide``, which of them it finds surely too near (no narrow phase needed)."""
        moving = self.moving
        seg = seg[:, moving]
        radius = self.capsules.radius[moving]
        r = radius[None, :, None] + self.clearance
        lo, hi = seg.min(axis=2) - r, seg.max(axis=2) + r                 # (N, K, 3)
        found, sure = [], []
        if self.scene.obstacles:
            o_lo, o_hi, o_ends, o_radius, o_branch = self.scene.arrays
            # Every link's box against every obstacle's at once, as (sample, obstacle, link).
            overlap = np.all((lo[:, None] <= o_hi[None, :, None]) & (hi[:, None] >= o_lo[None, :, None]), axis=-1)
            n, i, k = np.nonzero(overlap)
            near = np.zeros(len(n), bool)
            rods = np.nonzero(~np.isnan(o_ends[i, 0, 0]))[0]
            if len(rods):
                # A branch's capsule distance is the true one; a wire's (a cylinder) bounds it from below.
                nr, ir, kr = n[rods], i[rods], k[rods]
                d = (segment_distances(seg[nr, kr, 0], seg[nr, kr, 1], o_ends[ir, 0], o_ends[ir, 1])
                     - radius[kr] - o_radius[ir])
                keep = np.ones(len(n), bool)
                keep[rods] = d < self.clearance
                if decide:
                    near[rods] = (d < self.clearance - 1e-9) & o_branch[ir]
                n, i, k, near = n[keep], i[keep], k[keep], near[keep]
            found.append(np.stack([n, moving[k], i], axis=1))
            sure.append(near)
        if self.canopy is not None:
            maybe, surely = self._near_canopy(seg, radius)
            n, k = np.nonzero(maybe)
            found.append(np.stack([n, moving[k], np.full_like(n, -1)], axis=1))
            sure.append(surely[n, k] if decide else np.zeros(len(n), bool))
        if not found:
            return np.zeros((0, 3), int), np.zeros(0, bool)
        triples, certain = np.concatenate(found), np.concatenate(sure)
        certain &= ~self.bounds_only[triples[:, 1]]
        order = np.argsort(triples[:, 0], kind='stable')
        return triples[order], certain[order]

    def _near_canopy(self, seg, radius):
        """``(maybe, surely)``, (N, K) each: where a capsule (ends ``seg``, ``radius``) may come, and
        surely comes, within the clearance of the canopy's voxels: its segment covered by spheres,
        each checked against the distance field's bounds."""
        length = np.linalg.norm(seg[:, :, 1] - seg[:, :, 0], axis=-1).max(axis=0)          # (K,)
        m = int(np.ceil((length / np.maximum(radius, 0.01)).max())) + 1                  # spheres per capsule
        s = np.linspace(0.0, 1.0, m)
        centers = seg[:, :, None, 0] + s[None, None, :, None] * (seg[:, :, None, 1] - seg[:, :, None, 0])
        lower, upper = self.canopy.bounds(centers)
        # A sphere at each sample point covers the segment up to half the spacing on either side; a point of
        # the axis within radius + clearance of a voxel makes the capsule too near.
        reach = (radius + self.clearance)[None, :, None]
        maybe = (lower < reach + 0.5 * length[None, :, None] / max(m - 1, 1)).any(axis=-1)
        surely = (upper < reach - 1e-9).any(axis=-1)
        return maybe, surely

    def _placed(self, q, seg, triples):
        """Where the narrow phase places each ``(sample, link, obstacle)`` triple's shape: ``(frames, lengths)``,
        a capsule's frame along its segment, or a hull's frame (the frame its link moves with)."""
        n, k = triples[:, 0], triples[:, 1]
        frames, lengths = frames_along(seg[n, k, 0], seg[n, k, 1])
        hull = self.bounds_only[k]
        if hull.any():
            frames[hull] = self.capsules.frames(q[n[hull]])[np.arange(hull.sum()), k[hull]]
        return frames, lengths

    def _narrow(self, frame, length, k, o, n, t, allowed):
        """coal's answer for link shape ``k`` (placed at ``frame``; a capsule ``length`` m long, or a hull)
        against obstacle ``o`` (-1: the canopy)."""
        shape = (self.hulls[k] if self.hulls[k] is not None else
                 coal.Capsule(float(self.capsules.radius[k]), max(float(length), 1e-9)))
        if o < 0:
            other, pose, name = self.canopy.octree, coal.Transform3s(), 'the canopy'
        else:
            ob = self.scene.obstacles[o]
            other, pose, name = ob.shape, ob.placed, ob.name
        result = coal.CollisionResult()
        coal.collide(shape, transform(frame), other, pose, self.request, result)
        if not result.isCollision():
            return None
        worst = None
        for c in result.getContacts():
            if any(a.holds(c.pos) for a in allowed):
                continue
            if worst is None or c.penetration_depth < worst.penetration_depth:
                worst = c
        if worst is None:
            return None
        return Contact(int(n), float(t), self.capsules.links[k], name, np.array(worst.pos, float),
                       float(worst.penetration_depth))

    def _self_contacts(self, seg, times):
        """Per sample, a contact between two of the arm's own capsules (not built to touch), or None."""
        found = [None] * len(seg)
        if not len(self.pairs):
            return found
        a, b = self.pairs[:, 0], self.pairs[:, 1]
        r = self.capsules.radius
        d = segment_distances(seg[:, a, 0], seg[:, a, 1], seg[:, b, 0], seg[:, b, 1]) - r[a] - r[b]   # (N, P)
        links = self.capsules.links
        for n in np.nonzero((d < 0.0).any(axis=1))[0]:
            p = int(np.argmin(d[n]))
            found[n] = Contact(int(n), float(times[n]), links[a[p]], f'the arm\'s {links[b[p]]}',
                               seg[n, a[p]].mean(axis=0), float(d[n, p]))
        return found

    # -- trajectories --------------------------------------------------------------------------------------------

    def samples(self, trajectory, step=STEP):
        """Times (s) and configurations of ``trajectory`` (anything with ``duration`` and
        ``sample(t) -> (q, ...)``) dense enough that no capsule end moves more than ``step`` m
        between two of them (along its way: sampled evenly, dense enough for the fastest part,
        then thinned where the arm moves slowly or rests, each kept configuration the last within
        ``step`` of travel from the one before)."""
        duration = float(trajectory.duration)
        t = np.linspace(0.0, duration, max(2, int(np.ceil(duration / FIRST_DT)) + 1))
        q = np.asarray(trajectory.sample(t)[0])
        while (moved := self._moves(q)).max(initial=0.0) > step:
            t = np.linspace(0.0, duration, int(np.ceil((len(t) - 1) * moved.max() / step * 1.1)) + 1)
            q = np.asarray(trajectory.sample(t)[0])
        keep = _thinned(moved, step)
        return t[keep], q[keep]

    def _moves(self, q):
        """The longest move of a capsule end between each two consecutive configurations of ``q`` (m), (N - 1,)."""
        if len(q) < 2:
            return np.zeros(0)
        seg = self.capsules.segments(q)
        return np.linalg.norm(np.diff(seg, axis=0), axis=-1).max(axis=(1, 2))

    def check(self, trajectory, allowed=None, step=STEP):
        """The first contact along ``trajectory``, or None (sampled by :meth:`samples`)."""
        t, q = self.samples(trajectory, step)
        return self.first_contact(q, t, allowed)


def _thinned(moves, step):
    """Indices of the samples to keep (the first and the last among them) when consecutive samples are
    ``moves`` (m) apart at most: each kept one the last within ``step`` of travel from the one kept before."""
    keep, travel = [0], 0.0
    for i, d in enumerate(moves.tolist()):
        if travel + d > step:
            keep.append(i)
            travel = d
        else:
            travel += d
    if keep[-1] != len(moves):
        keep.append(len(moves))
    return np.array(keep)
