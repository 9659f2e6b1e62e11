"""A small, strict URDF reader for serial chains (links, joints, origins, axes, limits).

URDF is plain XML; the standard library parses it, and we read only what
kinematics needs. Nothing in a URDF is executed. Errors name the joint or link.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

JOINT_TYPES = ('revolute', 'continuous', 'prismatic', 'fixed')


@dataclass(frozen=True)
class UrdfJoint:
    """One URDF joint. Angles in rad, lengths in m."""

    name: str
    type: str
    parent: str
    child: str
    origin: np.ndarray          # 4x4 transform parent -> joint frame
    axis: np.ndarray            # unit axis in the joint frame
    lower: float
    upper: float
    velocity: float             # max |velocity|, rad/s or m/s (inf if not given)
    effort: float


def _floats(text, n, what):
    try:
        values = [float(v) for v in (text or '').split()]
    except ValueError as exc:
        raise ValueError(f'{what}: not numbers: {text!r}') from exc
    if len(values) != n or not np.all(np.isfinite(values)):
        raise ValueError(f'{what}: expected {n} finite numbers, got {text!r}')
    return np.array(values)


def origin_matrix(xyz, rpy):
    """4x4 transform from URDF ``xyz`` and fixed-axis roll-pitch-yaw ``rpy``."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler('xyz', rpy).as_matrix()
    T[:3, 3] = xyz
    return T


def parse_urdf(text: str):
    """Parse URDF text.

    Returns
    -------
    name : str
        The robot's name.
    links : list of str
    joints : dict of str to UrdfJoint, keyed by child link
    """
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise ValueError(f'URDF is not well-formed XML: {exc}') from exc
    if root.tag != 'robot':
        raise ValueError(f'URDF root element must be <robot>, got <{root.tag}>')
    links = [link.get('name') for link in root.findall('link')]
    if not links or None in links:
        raise ValueError('URDF needs <link name="..."> elements')
    joints = {}
    for el in root.findall('joint'):
        name = el.get('name')
        jtype = el.get('type')
        if not name or jtype not in JOINT_TYPES + ('floating', 'planar'):
            raise ValueError(f'joint {name!r}: unknown type {jtype!r}')
        if jtype in ('floating', 'planar'):
            raise ValueError(f'joint {name!r}: type {jtype!r} is not supported in a serial arm')
        parent, child = el.find('parent'), el.find('child')
        if parent is None or child is None:
            raise ValueError(f'joint {name!r}: needs <parent link=...> and <child link=...>')
        o = el.find('origin')
        xyz = _floats(o.get('xyz', '0 0 0'), 3, f'joint {name!r} origin xyz') if o is not None else np.zeros(3)
        rpy = _floats(o.get('rpy', '0 0 0'), 3, f'joint {name!r} origin rpy') if o is not None else np.zeros(3)
        a = el.find('axis')
        axis = _floats(a.get('xyz', '1 0 0'), 3, f'joint {name!r} axis') if a is not None else np.array([1., 0, 0])
        if jtype != 'fixed':
            norm = np.linalg.norm(axis)
            if norm < 1e-12:
                raise ValueError(f'joint {name!r}: axis must not be zero')
            axis = axis / norm
        lim = el.find('limit')
        lower, upper, vel, effort = -np.inf, np.inf, np.inf, np.inf
        if lim is not None:
            vel = float(lim.get('velocity', 'inf'))
            effort = float(lim.get('effort', 'inf'))
            if jtype != 'continuous':
                lower = float(lim.get('lower', '0'))
                upper = float(lim.get('upper', '0'))
        elif jtype in ('revolute', 'prismatic'):
            raise ValueError(f'joint {name!r}: a {jtype} joint needs <limit lower upper velocity effort>')
        if jtype in ('revolute', 'prismatic') and not lower <= upper:
            raise ValueError(f'joint {name!r}: lower limit {lower} is above upper limit {upper}')
        if not vel > 0:
            raise ValueError(f'joint {name!r}: velocity limit must be > 0, got {vel}')
        joints[child.get('link')] = UrdfJoint(name, jtype, parent.get('link'), child.get('link'),
                                              origin_matrix(xyz, rpy), axis, lower, upper, vel, effort)
    return root.get('name', ''), links, joints


def chain(joints, base: str, tip: str):
    """The joints from ``base`` to ``tip``, base first."""
    out = []
    link = tip
    while link != base:
        if link not in joints:
            raise ValueError(f'no chain of joints from {base!r} to {tip!r} (stuck at link {link!r})')
        joint = joints[link]
        out.append(joint)
        link = joint.parent
        if len(out) > len(joints):
            raise ValueError('URDF joints form a loop')
    return out[::-1]


def default_tip(links, joints, base: str):
    """The only leaf link below ``base`` (a serial arm has exactly one)."""
    parents = {j.parent for j in joints.values()}
    leaves = [link for link in links if link not in parents and link != base]
    below = []
    for leaf in leaves:
        try:
            chain(joints, base, leaf)
            below.append(leaf)
        except ValueError:
            pass
    if len(below) != 1:
        raise ValueError(f'cannot pick the tool link: leaves below {base!r} are {below}; name it with tip=')
    return below[0]


@dataclass(frozen=True)
class UrdfCapsule:
    """A link's collision cylinder (read as a capsule along its axis) or sphere (a capsule of length 0), or the
    capsule that bounds its box or mesh, m; a box's corners or a mesh's vertices in ``points`` (the capsule's
    frame), whose convex hull is the shape itself."""

    link: str
    origin: np.ndarray          # 4x4 transform link -> shape; the capsule's axis is its z
    radius: float
    length: float
    points: np.ndarray | None = None


def parse_collisions(text: str, base_dir=None):
    """Every ``<collision>`` of the URDF's links, as :class:`UrdfCapsule`: cylinders and spheres as they are, boxes
    and meshes bounded by the smallest capsule along their longest extent that holds every corner or vertex. A
    mesh's file is found as ROS finds it (``package://`` in the package's share folder, ``file://``, or a path
    relative to ``base_dir``, the URDF's folder); ValueError names a file that is not there."""
    root = ET.fromstring(text)
    out = []
    for link in root.findall('link'):
        name = link.get('name')
        for el in link.findall('collision'):
            o = el.find('origin')
            xyz = _floats(o.get('xyz', '0 0 0'), 3, f'link {name!r} collision origin xyz') if o is not None else np.zeros(3)
            rpy = _floats(o.get('rpy', '0 0 0'), 3, f'link {name!r} collision origin rpy') if o is not None else np.zeros(3)
            origin = origin_matrix(xyz, rpy)
            geometry = el.find('geometry')
            shape = geometry[0] if geometry is not None and len(geometry) else None
            if shape is not None and shape.tag in ('box', 'mesh'):
                points = (_box_corners(shape, name) if shape.tag == 'box' else _mesh_vertices(shape, name, base_dir))
                frame, radius, length = bounding_capsule(points)
                inside = (points - frame[:3, 3]) @ frame[:3, :3]
                out.append(UrdfCapsule(name, origin @ frame, radius, length, inside))
                continue
            if shape is None or shape.tag not in ('cylinder', 'sphere'):
                raise ValueError(f'link {name!r}: collision geometry must be a cylinder, sphere, box or mesh, '
                                 f'got {None if shape is None else shape.tag!r}')
            radius = float(shape.get('radius', 'nan'))
            length = float(shape.get('length', '0')) if shape.tag == 'cylinder' else 0.0
            if not (radius > 0 and length >= 0):
                raise ValueError(f'link {name!r}: collision {shape.tag} needs radius > 0 (and length >= 0), m')
            out.append(UrdfCapsule(name, origin, radius, length))
    return out


def _box_corners(shape, link):
    size = _floats(shape.get('size', ''), 3, f'link {link!r} collision box size')
    if not np.all(size > 0):
        raise ValueError(f'link {link!r}: a collision box needs sizes > 0, m')
    return np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float) * size / 2.0


def resolve_mesh(filename, base_dir=None):
    """The file a URDF's mesh ``filename`` names, as ROS resolves it; ValueError naming where it looked."""
    import os
    from pathlib import Path
    if filename.startswith('package://'):
        package, _, rest = filename[len('package://'):].partition('/')
        # The ament index (a package is registered by a marker file under its prefix), then ROS_PACKAGE_PATH.
        prefixes = [Path(d) for d in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if d]
        places = [p / 'share' / package for p in prefixes
                  if (p / 'share' / 'ament_index' / 'resource_index' / 'packages' / package).exists()]
        places += [Path(d) / package for d in os.environ.get('ROS_PACKAGE_PATH', '').split(os.pathsep) if d]
        for place in places:
            if (place / rest).is_file():
                return place / rest
        raise ValueError(f'mesh {filename!r} not found: package {package!r} is '
                         + (f'not holding {rest!r} in {", ".join(map(str, places))}' if places else
                            'in neither the ament index nor ROS_PACKAGE_PATH'))
    path = Path(filename[len('file://'):] if filename.startswith('file://') else filename)
    if not path.is_absolute() and base_dir is not None:
        path = Path(base_dir) / path
    if not path.is_file():
        raise ValueError(f'mesh {filename!r} not found (looked for {path})')
    return path


def _mesh_vertices(shape, link, base_dir):
    import coal
    filename = shape.get('filename', '')
    scale = _floats(shape.get('scale', '1 1 1'), 3, f'link {link!r} collision mesh scale')
    path = resolve_mesh(filename, base_dir)
    try:
        model = coal.MeshLoader().load(str(path), np.asarray(scale, float))
    except ValueError as exc:
        raise ValueError(f'link {link!r}: mesh {filename!r} could not be read ({str(exc).splitlines()[-2:]})') from None
    points = np.array(model.vertices(), float)
    if len(points) == 0:
        raise ValueError(f'link {link!r}: mesh {filename!r} has no vertices')
    return points


def bounding_capsule(points):
    """``(frame, radius, length)``: a capsule along the points' longest extent (its axis the frame's z, its middle
    the frame's origin) that holds every point, m."""
    points = np.asarray(points, float)
    centre = points.mean(axis=0)
    spread = points - centre
    axis = np.linalg.svd(spread, full_matrices=False)[2][0] if len(points) > 1 else np.array([0.0, 0.0, 1.0])
    t = spread @ axis
    off = np.linalg.norm(spread - t[:, None] * axis, axis=1)
    radius = max(float(off.max()), 1e-6)
    # The segment as short as the caps allow: each point within the radius of its end.
    reach = np.sqrt(np.maximum(radius ** 2 - off ** 2, 0.0))
    hi, lo = float(np.max(t - reach)), float(np.min(t + reach))
    if lo > hi:
        lo = hi = 0.5 * (lo + hi)
    frame = np.eye(4)
    z = axis / np.linalg.norm(axis)
    x = np.cross(z, [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    frame[:3, 0], frame[:3, 1], frame[:3, 2] = x, np.cross(z, x), z
    frame[:3, 3] = centre + 0.5 * (lo + hi) * z
    return frame, radius, hi - lo
