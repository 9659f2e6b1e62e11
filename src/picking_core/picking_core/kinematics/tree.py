"""Every link of a robot as a frame: each joint's transform from its parent link to its child link, as
robot_state_publisher computes them from a URDF and the joint positions (pure core).

Fixed joints give transforms that never change (``/tf_static``); the others move with their joint
(``/tf``): revolute and continuous joints turn about their axis, prismatic ones slide along it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from .urdf import parse_urdf


@dataclass(frozen=True)
class Link:
    """One joint as a frame transform: ``parent`` and ``child`` link names, the joint's ``name`` and ``type``, its
    ``origin`` (4x4, parent -> joint frame) and unit ``axis``."""

    name: str
    type: str
    parent: str
    child: str
    origin: np.ndarray
    axis: np.ndarray


class RobotTree:
    """The links of a URDF: :attr:`fixed` and :attr:`moving` joints, :attr:`root` the link no joint moves."""

    def __init__(self, joints, name=''):
        links = [Link(j.name, j.type, j.parent, j.child, j.origin, j.axis) for j in joints]
        self.name = name
        self.fixed = [link for link in links if link.type == 'fixed']
        self.moving = [link for link in links if link.type != 'fixed']
        children = {link.child for link in links}
        roots = sorted({link.parent for link in links} - children)
        if len(roots) != 1:
            raise ValueError(f'a robot has one root link, this one has {roots or "none"}')
        self.root = roots[0]
        # Each moving joint's origin as a translation, a rotation matrix and a quaternion, kept as arrays so that
        # every joint's pose comes from one pass of numpy.
        origins = np.array([link.origin for link in self.moving]).reshape(-1, 4, 4)
        self._origin_t = origins[:, :3, 3]
        self._origin_q = Rotation.from_matrix(origins[:, :3, :3]).as_quat() if self.moving else np.zeros((0, 4))
        self._axes = np.array([link.axis for link in self.moving], float).reshape(-1, 3)
        self._prismatic = np.array([link.type == 'prismatic' for link in self.moving], bool)
        #: Each prismatic joint's axis in its parent link (zero for the others): its child's slide per metre.
        self._slide = np.einsum('nij,nj->ni', origins[:, :3, :3], self._axes) * self._prismatic[:, None]

    @classmethod
    def from_urdf(cls, text):
        name, _, joints = parse_urdf(text)
        return cls(list(joints.values()), name)

    @property
    def joint_names(self):
        return [link.name for link in self.moving]

    @property
    def pairs(self):
        """``[(parent, child)]`` of the moving joints, in :attr:`joint_names`' order."""
        return [(link.parent, link.child) for link in self.moving]

    def static_transforms(self):
        """``[(parent, child, 4x4)]`` of the fixed joints."""
        return [(link.parent, link.child, link.origin) for link in self.fixed]

    def poses(self, positions):
        """``(translations (N, 3), quaternions (N, 4) as x, y, z, w)``: each moving joint's child link in its parent
        link at ``positions`` (N, in :attr:`joint_names`' order; rad, or m for a prismatic joint)."""
        q = np.asarray(positions, float).reshape(len(self.moving))
        turn = np.where(self._prismatic, 0.0, q) / 2.0
        motion = np.empty((len(q), 4))
        motion[:, :3], motion[:, 3] = self._axes * np.sin(turn)[:, None], np.cos(turn)
        return self._origin_t + self._slide * q[:, None], _multiply(self._origin_q, motion)

    def transforms(self, positions):
        """``[(parent, child, 4x4)]`` of the moving joints at ``positions`` (``{joint: rad or m}``); a joint with no
        finite position is left out (a driver that does not report it)."""
        q = np.array([positions.get(name, np.nan) for name in self.joint_names], float)
        known = np.isfinite(q)
        translations, quaternions = self.poses(np.where(known, q, 0.0))
        out = []
        for i in np.flatnonzero(known):
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = Rotation.from_quat(quaternions[i]).as_matrix(), translations[i]
            out.append((self.moving[i].parent, self.moving[i].child, T))
        return out


def _multiply(a, b):
    """The Hamilton products ``a * b`` of quaternions row by row (x, y, z, w)."""
    ax, ay, az, aw = a.T
    bx, by, bz, bw = b.T
    return np.stack([aw * bx + bw * ax + ay * bz - az * by, aw * by + bw * ay + az * bx - ax * bz,
                     aw * bz + bw * az + ax * by - ay * bx, aw * bw - ax * bx - ay * by - az * bz], axis=1)
