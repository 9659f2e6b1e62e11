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
    """A link's collision cylinder (read as a capsule along its axis) or sphere (a capsule of length 0), m."""

    link: str
    origin: np.ndarray          # 4x4 transform link -> shape; the capsule's axis is its z
    radius: float
    length: float


def parse_collisions(text: str):
    """Every ``<collision>`` cylinder and sphere of the URDF's links, as :class:`UrdfCapsule`.
    Other shapes (box, mesh) raise ValueError: bound them with a cylinder."""
    root = ET.fromstring(text)
    out = []
    for link in root.findall('link'):
        name = link.get('name')
        for el in link.findall('collision'):
            o = el.find('origin')
            xyz = _floats(o.get('xyz', '0 0 0'), 3, f'link {name!r} collision origin xyz') if o is not None else np.zeros(3)
            rpy = _floats(o.get('rpy', '0 0 0'), 3, f'link {name!r} collision origin rpy') if o is not None else np.zeros(3)
            geometry = el.find('geometry')
            shape = geometry[0] if geometry is not None and len(geometry) else None
            if shape is None or shape.tag not in ('cylinder', 'sphere'):
                raise ValueError(f'link {name!r}: collision geometry must be a cylinder or a sphere, '
                                 f'got {None if shape is None else shape.tag!r}')
            radius = float(shape.get('radius', 'nan'))
            length = float(shape.get('length', '0')) if shape.tag == 'cylinder' else 0.0
            if not (radius > 0 and length >= 0):
                raise ValueError(f'link {name!r}: collision {shape.tag} needs radius > 0 (and length >= 0), m')
            out.append(UrdfCapsule(name, origin_matrix(xyz, rpy), radius, length))
    return out
