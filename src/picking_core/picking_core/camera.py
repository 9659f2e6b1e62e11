"""A simulated depth camera that detects apples (pure core): what a perception pipeline would report.

The camera sits on a fixed mount (its optical frame: z forward, x right, y down, REP 103) and sees an
apple when its centre is in the field of view and range and the line of sight to it passes no branch,
arm link or other apple. Each detection is the apple's centre with Gaussian noise, its diameter, a
score and the position covariance; a frame may also hold false positives anywhere in view.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .kinematics.capsules import segment_distances


@dataclass(frozen=True)
class CameraSettings:
    """``rate`` Hz, ``latency`` s from capture to publication, ``noise`` m (σ of each coordinate),
    ``fov_h``/``fov_v`` rad (full angles), ``near``/``far`` m, ``false_positives`` (mean a frame),
    ``occlusion`` (False: sees through everything), ``seed``."""

    rate: float = 30.0
    latency: float = 0.05
    noise: float = 0.003
    fov_h: float = np.radians(87.0)
    fov_v: float = np.radians(58.0)
    near: float = 0.2
    far: float = 3.0
    false_positives: float = 0.0
    occlusion: bool = True
    seed: int = 0

    def __post_init__(self):
        for name in ('rate', 'fov_h', 'fov_v', 'far'):
            if not (np.isfinite(getattr(self, name)) and getattr(self, name) > 0):
                raise ValueError(f'camera {name} must be a positive number, got {getattr(self, name)!r}')
        for name in ('latency', 'noise', 'near', 'false_positives'):
            if not (np.isfinite(getattr(self, name)) and getattr(self, name) >= 0):
                raise ValueError(f'camera {name} must be a number >= 0, got {getattr(self, name)!r}')
        if self.near >= self.far:
            raise ValueError(f'camera near ({self.near} m) must be below far ({self.far} m)')


@dataclass(frozen=True)
class Detection:
    """An apple seen: its centre (3,) and diameter, m, in the camera frame; ``score``; ``sigma`` m (the
    position's standard deviation per coordinate); ``truth`` the apple's index (-1 for a false positive:
    for tests only, never published)."""

    position: np.ndarray
    diameter: float
    score: float
    sigma: float
    truth: int


class DepthCamera:
    """A camera at ``mount`` (4x4, its optical frame in the arm's base frame) with ``settings``."""

    def __init__(self, mount, settings=CameraSettings()):
        self.mount = np.asarray(mount, float)
        self.settings = settings
        self.rng = np.random.default_rng(settings.seed)
        self.origin = self.mount[:3, 3]

    def in_view(self, points):
        """Which ``points`` (N, 3, base frame) are in the field of view and range."""
        local = (np.asarray(points, float).reshape(-1, 3) - self.origin) @ self.mount[:3, :3]
        z = local[:, 2]
        s = self.settings
        with np.errstate(divide='ignore', invalid='ignore'):
            return (z >= s.near) & (z <= s.far) & (np.abs(local[:, 0] / z) <= np.tan(s.fov_h / 2)) & \
                (np.abs(local[:, 1] / z) <= np.tan(s.fov_v / 2))

    def visible(self, centres, radii, present, blockers=np.empty((0, 2, 3)), blocker_radii=np.empty(0)):
        """Which apples (``centres`` (N, 3), ``radii`` (N,), those ``present`` to be seen) the camera sees: in
        view, and (with occlusion) the line of sight to the centre clear of the capsules ``blockers`` (M, 2, 3)
        with ``blocker_radii`` and of the other apples."""
        centres = np.asarray(centres, float).reshape(-1, 3)
        seen = np.asarray(present, bool) & self.in_view(centres)
        if not self.settings.occlusion or not seen.any():
            return seen
        idx = np.flatnonzero(seen)
        # The line of sight ends at the apple's near surface.
        ray = centres[idx] - self.origin
        length = np.linalg.norm(ray, axis=1)
        ends = self.origin + ray * ((length - radii[idx]) / length)[:, None]
        starts = np.broadcast_to(self.origin, ends.shape)
        blocked = np.zeros(len(idx), bool)
        if len(blockers):
            d = segment_distances(starts[:, None], ends[:, None], blockers[None, :, 0], blockers[None, :, 1])
            blocked |= (d < np.asarray(blocker_radii)[None]).any(axis=1)
        others = np.flatnonzero(np.asarray(present, bool))
        if len(others) > 1:
            d = segment_distances(starts[:, None], ends[:, None], centres[None, others], centres[None, others])
            hides = d < radii[None, others]
            hides[idx[:, None] == others[None]] = False
            blocked |= hides.any(axis=1)
        seen[idx[blocked]] = False
        return seen

    def capture(self, centres, radii, present, blockers=np.empty((0, 2, 3)), blocker_radii=np.empty(0)):
        """One frame's detections (in the camera frame) of the apples the camera sees, and its false
        positives."""
        s = self.settings
        seen = self.visible(centres, radii, present, blockers, blocker_radii)
        out = []
        R, o = self.mount[:3, :3], self.origin
        for i in np.flatnonzero(seen):
            local = (centres[i] - o) @ R + self.rng.normal(0.0, s.noise, 3)
            diameter = 2 * radii[i] + self.rng.normal(0.0, s.noise)
            out.append(Detection(local, float(diameter), float(self.rng.uniform(0.8, 0.99)), s.noise, int(i)))
        for _ in range(self.rng.poisson(s.false_positives) if s.false_positives > 0 else 0):
            z = self.rng.uniform(s.near, min(s.far, 2.0))
            x = z * np.tan(s.fov_h / 2) * self.rng.uniform(-1, 1)
            y = z * np.tan(s.fov_v / 2) * self.rng.uniform(-1, 1)
            out.append(Detection(np.array([x, y, z]), float(self.rng.uniform(0.05, 0.1)),
                                 float(self.rng.uniform(0.3, 0.7)), s.noise, -1))
        return out


def look_at(eye, target, up=(0.0, 0.0, 1.0)):
    """The optical frame (4x4) of a camera at ``eye`` looking at ``target`` (z forward, x right, y down)."""
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, np.asarray(up, float))
    if np.linalg.norm(x) < 1e-9:
        raise ValueError('the camera looks along its up direction: give another up')
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, y, z])
    T[:3, 3] = eye
    return T
