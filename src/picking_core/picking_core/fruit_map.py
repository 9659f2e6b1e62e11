"""The apples a camera reports, fused into targets (pure core): what the planner harvests instead of the truth.

Each frame's detections (centres with their covariance, in the arm's base frame) are associated with the
tracks so far, nearest first within ``gate`` (less than half the spacing of apples on a tree; a swaying apple
stays within it of where it hangs); an associated detection refines its track (a Kalman update of a point
that may drift slowly: the estimate is where the apple hangs, the centre of any sway), any other starts a
tentative track. A track seen ``confirm_hits`` times is confirmed: a target. A tentative track not seen for
``tentative_for`` s is dropped (a false positive seldom repeats), a confirmed one after ``forget_after`` s (the
apple left the tree, or stays hidden).

Each track also fits how its apple moves (:class:`~picking_core.sway.SwayFit`: a sway about where it hangs, from
the detections' own stamps), so that :meth:`FruitMap.predict` says where it will be at a later time.

Detections the map cannot use are counted with the reason: a frame with more than ``max_per_frame`` (a flood),
a score below ``min_score``, a centre inside a branch.
"""

from __future__ import annotations

import collections
import copy
import itertools
from collections import Counter
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from .harvest import SIDEWAYS
from .kinematics.capsules import point_segment_distances
from .moving_pick import APPLE_WIDTH, Follow
from .sway import SwayFit, SwaySettings


#: m: the farthest an apple hanging still is seen from where it is lately (a camera's 3 mm noise, four deviations).
STILL = 0.012
#: s: a track last seen this long before the newest frame is seen lately (a few frames at a camera's 30 Hz).
LATELY = 0.1
#: The share of a camera's frames a settled apple was seen in.
SEEN_MOST = 0.8


@dataclass(frozen=True)
class MapSettings:
    """``gate`` m (the farthest a detection joins a track), ``drift`` m/√s (how fast where an apple hangs may
    change: the position's process noise), ``sway`` m (how far about where it hangs a detection may find it: a
    standard deviation added to each detection's), ``confirm_hits``, ``tentative_for`` and ``forget_after`` s,
    ``max_per_frame``, ``min_score``."""

    gate: float = 0.04
    drift: float = 0.002
    sway: float = 0.01
    confirm_hits: int = 5
    tentative_for: float = 0.5
    forget_after: float = 5.0
    max_per_frame: int = 60
    min_score: float = 0.5


@dataclass
class Track:
    """An apple seen: ``id``, its position estimate ``x`` (3,) and covariance ``P`` (3, 3) (base frame, m: where
    it hangs), its diameter (m), ``hits``, when first and last seen (s), and ``motion``, how it moves."""

    id: int
    x: np.ndarray
    P: np.ndarray
    diameter: float
    hits: int
    first: float
    last: float
    confirmed: bool = False
    motion: SwayFit = field(default_factory=SwayFit)

    def settled(self, t, within, frames):
        """Whether it has been seen for ``t`` s or more, in nearly all of the ``frames`` the camera sent in the last
        ``t`` s, its detections then within ``within`` m of their mean: an apple hanging still (one the arm carries
        past, holds over the box or knocked swinging on its stem is not; nor is a track that took now and then a
        detection of another apple passing by)."""
        n, spread = self.motion.recent(self.last - t)
        return self.last - self.first >= t and n >= SEEN_MOST * frames and spread <= within


class FruitMap:
    """Tracks of the apples seen (see the module); ``branches``: ``(ends (M, 2, 3), radii (M,))`` a centre inside
    which is refused."""

    def __init__(self, settings=MapSettings(), branches=None):
        self.settings = settings
        self.tracks = []
        self.branches = branches
        self.refused = Counter()
        self.frames = self.detections = 0
        self._ids = itertools.count(1)
        self._t = None
        self._stamps = collections.deque()     # the stamps of the frames of the last window (SwaySettings.window)

    def update(self, t, positions, covariances, diameters=None, scores=None):
        """One frame at ``t`` (s): ``positions`` (N, 3) and ``covariances`` (N, 3, 3), base frame; returns the
        reasons of the detections it refused (a Counter)."""
        s = self.settings
        positions = np.asarray(positions, float).reshape(-1, 3)
        covariances = np.asarray(covariances, float).reshape(-1, 3, 3)
        n = len(positions)
        diameters = np.full(n, np.nan) if diameters is None else np.asarray(diameters, float)
        scores = np.ones(n) if scores is None else np.asarray(scores, float)
        self.frames += 1
        self.detections += n
        refused = Counter()
        self._predict(t)
        self._stamps.append(t)
        while self._stamps[0] < self._t - SwaySettings.window:
            self._stamps.popleft()
        if n > s.max_per_frame:
            refused[f'a frame of more than {s.max_per_frame} detections (a flood): the frame ignored'] += n
            self.refused.update(refused)
            self._expire(t)
            return refused
        keep = np.ones(n, bool)
        low = scores < s.min_score
        refused[f'a score below {s.min_score:g}'] += int(low.sum())
        keep &= ~low
        if self.branches is not None and len(self.branches[0]) and keep.any():
            inside = self._inside_branch(positions)
            refused['a centre inside a branch'] += int((inside & keep).sum())
            keep &= ~inside
        self._associate(t, positions[keep], covariances[keep], diameters[keep])
        self._expire(t)
        refused = +refused
        self.refused.update(refused)
        return refused

    def targets(self, settled=0.0):
        """The confirmed tracks, oldest first; with ``settled`` s, only those :meth:`Track.settled` that long and
        seen in the newest frames (one hidden since may have moved: knocked, picked)."""
        if settled <= 0.0:
            return [k for k in self.tracks if k.confirmed]
        frames = sum(1 for t in self._stamps if t >= self._t - settled)
        return [k for k in self.tracks
                if k.confirmed and self._t - k.last <= LATELY and k.settled(settled, STILL, frames)]

    def grasp_poses(self, rpy=SIDEWAYS, settled=0.0):
        """The confirmed apples (``settled`` as :meth:`targets` takes it) as a harvest's grasp poses (4x4, base
        frame): each at its centre estimate, the gripper turned by roll-pitch-yaw ``rpy`` (rad)."""
        targets = self.targets(settled)
        T = np.tile(np.eye(4), (len(targets), 1, 1))
        T[:, :3, :3] = Rotation.from_euler('xyz', rpy).as_matrix()
        T[:, :3, 3] = np.array([k.x for k in targets]).reshape(-1, 3)
        return list(T)

    def predict(self, track_id, t):
        """``(mean (3,), covariance (3, 3))`` of where the apple of track ``track_id`` will be at ``t`` s (base frame,
        m), from its motion; None for a track the map no longer holds."""
        track = next((k for k in self.tracks if k.id == track_id), None)
        return None if track is None else track.motion.predict(t)

    def follow(self, p):
        """The :class:`~picking_core.moving_pick.Follow` of the confirmed apple hanging nearest ``p`` (3,), m, within
        ``gate``, if it sways: its motion as fitted now (later detections do not change it) and its width; None for
        a still apple or none there."""
        p = np.asarray(p, float)
        near = [k for k in self.targets() if np.linalg.norm(k.x - p) <= self.settings.gate]
        if not near:
            return None
        track = min(near, key=lambda k: np.linalg.norm(k.x - p))
        fit = track.motion.fit()
        if fit is None or fit.frequency <= 0.0:
            return None
        motion = copy.deepcopy(track.motion)
        return Follow(motion.predict, track.diameter if np.isfinite(track.diameter) else APPLE_WIDTH)

    def counts(self):
        return {'frames': self.frames, 'detections': self.detections, 'tracks': len(self.tracks),
                'confirmed': len(self.targets()), 'refused': sum(self.refused.values())}

    # -- inside ---------------------------------------------------------------------------------------------
    def _predict(self, t):
        if self._t is not None and t > self._t:
            grow = self.settings.drift ** 2 * (t - self._t) * np.eye(3)
            for k in self.tracks:
                k.P = k.P + grow
        self._t = t if self._t is None else max(self._t, t)

    def _associate(self, t, z, R, diameters):
        s = self.settings
        free = list(range(len(z)))
        if self.tracks and len(z):
            X = np.array([k.x for k in self.tracks])
            dist = np.linalg.norm(z[:, None] - X[None], axis=2)                 # (N, T)
            # A swaying apple is found where it was lately seen too: a frame on it lies within noise and a sway's
            # step of the one before, while the centre of a wide sway may lie beyond the gate.
            newest = np.array([k.motion.newest if t - k.last <= LATELY else k.x for k in self.tracks])
            dist = np.minimum(dist, np.linalg.norm(z[:, None] - newest[None], axis=2))
            cost = np.where(dist <= s.gate, dist, np.inf)
            used_tracks = set()
            for flat in np.argsort(cost, axis=None):
                i, j = np.unravel_index(flat, cost.shape)
                if not np.isfinite(cost[i, j]):
                    break
                if i not in free or j in used_tracks:
                    continue
                self._refine(self.tracks[j], t, z[i], R[i], diameters[i])
                free.remove(i)
                used_tracks.add(j)
        for i in free:
            self.tracks.append(Track(next(self._ids), z[i].copy(), R[i].copy(), float(diameters[i]), 1, t, t,
                                     s.confirm_hits <= 1))
            self.tracks[-1].motion.update(t, z[i], R[i])

    def _refine(self, k, t, z, R, diameter):
        K = k.P @ np.linalg.inv(k.P + R + self.settings.sway ** 2 * np.eye(3))
        k.x = k.x + K @ (z - k.x)
        k.P = (np.eye(3) - K) @ k.P
        k.hits += 1
        k.last = t
        k.motion.update(t, z, R)
        if np.isfinite(diameter):
            k.diameter = diameter if not np.isfinite(k.diameter) else k.diameter + (diameter - k.diameter) / k.hits
        k.confirmed = k.confirmed or k.hits >= self.settings.confirm_hits

    def _expire(self, t):
        s = self.settings
        self.tracks = [k for k in self.tracks
                       if t - k.last <= (s.forget_after if k.confirmed else s.tentative_for)]

    def _inside_branch(self, p):
        ends, radii = self.branches
        d = point_segment_distances(p[:, None], ends[None, :, 0], ends[None, :, 1])
        return (d < radii[None]).any(axis=1)
