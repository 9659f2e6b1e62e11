"""What the arm must not touch: a scene of primitives and a canopy point cloud (pure core).

The geometry is coal's (the maintained successor of FCL, as MoveIt and Pinocchio use): every
obstacle is a coal shape with its pose, and its axis-aligned box is kept beside it for numpy's
broad phase. The canopy is a coal octree of the cloud, with a distance field beside it
(scipy's Euclidean distance transform) that clears most arm configurations without a coal call.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path

import coal
import numpy as np
import yaml
from scipy.ndimage import distance_transform_edt
from scipy.spatial.transform import Rotation

#: Kinds of obstacle a scene file lists, each a list of entries.
KINDS = ('branches', 'wires', 'boxes')
#: m: the canopy's voxel edge unless told.
RESOLUTION = 0.02
#: m: how far around the cloud its distance field reaches (beyond it, the distance to the cloud's box).
FIELD_PAD = 0.15


def transform(T):
    """A coal transform of the 4x4 pose ``T``."""
    T = np.asarray(T, float)
    return coal.Transform3s(np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]))


def convex_hull(points):
    """coal's convex hull of ``points`` (N, 3), m: the exact shape of a box or a convex mesh, and the tightest
    convex shape around any other mesh."""
    vertices = coal.StdVec_Vec3s()
    for p in np.asarray(points, float):
        vertices.append(p)
    return coal.Convex.convexHull(vertices, False, None)


def frames_along(p0, p1):
    """Poses (M, 4, 4) whose z axes run from ``p0`` to ``p1`` (M, 3), centred between them (a coal
    capsule's or cylinder's frame: round about z, so any x will do), and the lengths (M,)."""
    p0, p1 = np.asarray(p0, float).reshape(-1, 3), np.asarray(p1, float).reshape(-1, 3)
    axis = p1 - p0
    length = np.linalg.norm(axis, axis=1)
    z = np.where(length[:, None] > 0.0, axis / np.maximum(length, 1e-300)[:, None], [0.0, 0.0, 1.0])
    helper = np.where(np.abs(z[:, :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x, axis=1)[:, None]
    T = np.zeros((len(z), 4, 4))
    T[:, :3, 0], T[:, :3, 1], T[:, :3, 2], T[:, :3, 3] = x, np.cross(z, x), z, (p0 + p1) / 2
    T[:, 3, 3] = 1.0
    return T, length


def along(p0, p1):
    """:func:`frames_along` of one segment: ``(pose, length)``."""
    T, length = frames_along(p0, p1)
    return T[0], float(length[0])


@dataclass(frozen=True)
class Obstacle:
    """One obstacle: ``kind`` (branch, wire, box, ground), its coal ``shape`` at ``pose`` (4x4, the
    scene's frame), the box ``lo``-``hi`` that bounds it (m), and what drew it: ``ends`` and
    ``radius`` of a branch or wire, ``size`` of a box."""

    name: str
    kind: str
    shape: object
    pose: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    ends: np.ndarray = None
    radius: float = 0.0
    size: np.ndarray = None

    @property
    def placed(self):
        return transform(self.pose)


def _finite(values, n, what):
    a = np.asarray(values, float)
    if a.shape != (n,) or not np.all(np.isfinite(a)):
        raise ValueError(f'{what} must be {n} finite numbers, got {values!r}')
    return a


def rod(name, kind, p0, p1, radius):
    """A branch (a capsule: a segment swept by a sphere) or a wire (a thin cylinder) from ``p0``
    to ``p1``, m."""
    p0 = _finite(p0, 3, f'{name} from')
    p1 = _finite(p1, 3, f'{name} to')
    if not (radius > 0.0 and math.isfinite(radius)):
        raise ValueError(f'{name}: radius must be a positive number of m, got {radius!r}')
    T, length = along(p0, p1)
    if length <= 0.0:
        raise ValueError(f'{name}: its two ends are the same point')
    shape = coal.Capsule(radius, length) if kind == 'branch' else coal.Cylinder(radius, length)
    return Obstacle(name, kind, shape, T, np.minimum(p0, p1) - radius, np.maximum(p0, p1) + radius,
                    ends=np.array([p0, p1]), radius=float(radius))


def box(name, center, size, rpy=(0.0, 0.0, 0.0)):
    """A box of edges ``size`` (m) centred at ``center``, turned by roll-pitch-yaw ``rpy`` (rad)."""
    center, size = _finite(center, 3, f'{name} center'), _finite(size, 3, f'{name} size')
    if np.any(size <= 0.0):
        raise ValueError(f'{name}: every edge must be longer than 0 m, got {size.tolist()}')
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler('xyz', _finite(rpy, 3, f'{name} rpy')).as_matrix()
    T[:3, 3] = center
    half = np.abs(T[:3, :3]) @ (size / 2)
    return Obstacle(name, 'box', coal.Box(*size), T, center - half, center + half, size=size)


def ground(z):
    """The ground: everything below height ``z`` (m)."""
    big = 1e9
    return Obstacle('ground', 'ground', coal.Halfspace(np.array([0.0, 0.0, 1.0]), float(z)), np.eye(4),
                    np.array([-big, -big, -big]), np.array([big, big, float(z)]))


@dataclass(frozen=True)
class Scene:
    """The obstacles the planner knows, in ``frame`` (the arm's base frame)."""

    obstacles: tuple = ()
    frame: str = 'base_link'

    @functools.cached_property
    def arrays(self):
        """The obstacles as arrays for a broad phase: ``(lo, hi, ends, radius, branch)``: their bounding
        boxes (M, 3) each, the axis ends of the rods (M, 2, 3), NaN for others, their radii (M,) and
        which are branches (M,) (a branch's capsule distance is exact, a wire's bounds it from below)."""
        m = len(self.obstacles)
        lo = np.array([o.lo for o in self.obstacles], float).reshape(m, 3)
        hi = np.array([o.hi for o in self.obstacles], float).reshape(m, 3)
        ends = np.full((m, 2, 3), np.nan)
        for i, o in enumerate(self.obstacles):
            if o.ends is not None:
                ends[i] = o.ends
        radius = np.array([o.radius for o in self.obstacles], float)
        branch = np.array([o.kind == 'branch' for o in self.obstacles], bool)
        return lo, hi, ends, radius, branch

    def rods(self):
        """The branches and wires: ``(ends (M, 2, 3), radii (M,))``, m."""
        rods = [o for o in self.obstacles if o.ends is not None]
        return np.array([o.ends for o in rods], float).reshape(-1, 2, 3), np.array([o.radius for o in rods], float)

    @classmethod
    def from_dict(cls, d, where='scene'):
        """From a scene file's mapping: ``frame``, ``ground_z`` (m, or absent), and lists
        ``branches`` / ``wires`` (``from``, ``to``: m; ``radius``: m) and ``boxes`` (``center``,
        ``size``: m; ``rpy_deg``), each entry with an optional ``name``."""
        if not isinstance(d, dict):
            raise ValueError(f'{where}: expected a mapping, got {type(d).__name__}')
        unknown = set(d) - {'frame', 'ground_z', 'include', *KINDS}
        if unknown:
            raise ValueError(f'{where}: unknown keys {sorted(unknown)} (known: frame, ground_z, include, '
                             f'{", ".join(KINDS)})')
        if d.get('include'):
            raise ValueError(f'{where}: include is read from a file (Scene.from_yaml), relative to it')
        obstacles = []
        if d.get('ground_z') is not None:
            obstacles.append(ground(float(d['ground_z'])))
        for kind in KINDS:
            for i, e in enumerate(d.get(kind) or []):
                name = e.get('name', f'{kind[:-1] if kind != "branches" else "branch"} {i}')
                try:
                    if kind == 'boxes':
                        rpy = np.radians(e.get('rpy_deg', [0.0, 0.0, 0.0]))
                        obstacles.append(box(name, e['center'], e['size'], rpy))
                    else:
                        obstacles.append(rod(name, 'branch' if kind == 'branches' else 'wire', e['from'], e['to'],
                                             float(e['radius'])))
                except KeyError as exc:
                    raise ValueError(f'{where}: {kind}[{i}] ({name}) has no {exc}') from None
        names = [o.name for o in obstacles]
        if len(set(names)) != len(names):
            raise ValueError(f'{where}: obstacle names must differ: {sorted(n for n in names if names.count(n) > 1)}')
        return cls(tuple(obstacles), str(d.get('frame', 'base_link')))

    @classmethod
    def from_yaml(cls, path, _seen=()):
        """From a scene file; its ``include`` list names scene files (relative to it) whose
        obstacles come first."""
        path = Path(path).resolve()
        if path in _seen:
            raise ValueError(f'{path}: includes itself')
        with path.open() as f:
            d = yaml.safe_load(f) or {}
        if not isinstance(d, dict):
            raise ValueError(f'{path}: expected a mapping, got {type(d).__name__}')
        own = cls.from_dict({k: v for k, v in d.items() if k != 'include'}, str(path))
        obstacles = []
        for name in d.get('include') or []:
            obstacles += cls.from_yaml(path.parent / name, (*_seen, path)).obstacles
        return own.merged(obstacles, str(path))

    def merged(self, first, where='scene'):
        """This scene with the obstacles ``first`` before its own (names must stay distinct)."""
        obstacles = tuple(first) + self.obstacles
        names = [o.name for o in obstacles]
        if len(set(names)) != len(names):
            raise ValueError(f'{where}: obstacle names must differ: {sorted({n for n in names if names.count(n) > 1})}')
        return Scene(obstacles, self.frame)

    def __len__(self):
        return len(self.obstacles)


class Canopy:
    """A point cloud of the canopy (N, 3), m, in the arm's base frame: a coal octree of voxels of
    edge ``resolution`` and, for the broad phase, a distance field on the same grid in cells of half
    that edge (every cell of an occupied voxel occupied)."""

    #: Field cells per voxel edge.
    SUB = 2

    def __init__(self, points, resolution=RESOLUTION):
        points = np.asarray(points, float).reshape(-1, 3)
        points = points[np.all(np.isfinite(points), axis=1)]       # a depth camera's holes are NaN
        if not len(points):
            raise ValueError('a canopy needs at least one finite point')
        if not resolution > 0.0:
            raise ValueError(f'resolution must be positive, got {resolution}')
        self.points, self.resolution = points, float(resolution)
        self.octree = coal.makeOctree(np.ascontiguousarray(points), self.resolution)
        # The octree's voxels are the cubes [k, k + 1) * resolution holding a point: the field's grid is aligned
        # with them, so that its occupied cells are the voxels exactly.
        voxels = np.unique(np.floor(points / self.resolution).astype(np.int64), axis=0)
        pad = int(np.ceil(FIELD_PAD / self.resolution))
        first = voxels.min(axis=0) - pad
        self.cell = self.resolution / self.SUB
        self.origin = first * self.resolution
        shape = (voxels.max(axis=0) - first + pad + 1) * self.SUB
        free = np.ones(shape, bool)
        for offset in np.ndindex(self.SUB, self.SUB, self.SUB):
            free[tuple(((voxels - first) * self.SUB + offset).T)] = False
        self.field = distance_transform_edt(free, sampling=self.cell)    # cell centre to the nearest occupied one
        self.lo, self.hi = voxels.min(axis=0) * self.resolution, (voxels.max(axis=0) + 1) * self.resolution

    def __len__(self):
        return len(self.points)

    def bounds(self, centers):
        """``(lower, upper)`` bounds of the distance (m) from each point of ``centers`` (..., 3) to the
        canopy's voxels: the field at the point's cell less (plus) the cell's half diagonal twice (once);
        outside the field, the distance to the voxels' box and infinity."""
        centers = np.asarray(centers, float)
        outside = np.linalg.norm(np.maximum(0.0, np.maximum(self.lo - centers, centers - self.hi)), axis=-1)
        cell = np.floor((centers - self.origin) / self.cell).astype(np.int64)
        inside = np.all((cell >= 0) & (cell < self.field.shape), axis=-1)
        lower, upper = outside.copy(), np.full(outside.shape, np.inf)
        value = self.field[tuple(cell[inside].T)]
        half = 0.5 * math.sqrt(3.0) * self.cell
        lower[inside] = np.maximum(value - 2.0 * half, 0.0)
        upper[inside] = value + half
        return lower, upper

    def lower_bound(self, centers):
        """A lower bound of the distance (m) from each point of ``centers`` (..., 3) to the canopy's voxels."""
        return self.bounds(centers)[0]
