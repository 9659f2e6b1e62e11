"""The arm's collision capsules from the URDF, placed by forward kinematics, and the distances
between two sets of capsules (pure numpy, batched over time samples).

A capsule is a segment swept by a sphere; the distance between two is the distance between their
segments less both radii. Segment to segment distance has a closed form (the clamped closest
points of two lines), so whole trajectories are compared in a few array operations.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .urdf import chain, parse_collisions, parse_urdf


@dataclass(frozen=True)
class ArmCapsules:
    """The collision capsules of an :class:`~picking_core.kinematics.ArmModel`.

    ``frame[k]`` is the index of the frame capsule k moves with in ``[base] + joint_frames(q)``;
    ``ends[k]`` its two end points (homogeneous) in that frame; ``radius[k]`` m. A capsule that bounds a box
    or a mesh has that shape's points in that frame in ``hulls[k]`` (None for a cylinder or a sphere).
    """

    arm: object
    links: tuple
    frame: np.ndarray
    ends: np.ndarray
    radius: np.ndarray
    hulls: tuple = ()

    @classmethod
    def from_arm(cls, arm):
        """The capsules of ``arm``'s URDF. Links moved by joints outside the base-to-tool chain (the
        gripper's fingers) cannot carry one (ValueError): give it to the link they hang from."""
        _, _, joints = parse_urdf(arm.urdf)
        where = {arm.base_frame: (0, np.eye(4))}           # link -> (frame index, offset in that frame)
        k = 0
        for joint in chain(joints, arm.base_frame, arm.tool_frame):
            if joint.type == 'fixed':
                f, offset = where[joint.parent]
                where[joint.child] = (f, offset @ joint.origin)
            else:
                k += 1
                where[joint.child] = (k, np.eye(4))
        # Links hanging from the chain by fixed joints (a camera, a bracket) move with their parent.
        changed = True
        while changed:
            changed = False
            for joint in joints.values():
                if joint.type == 'fixed' and joint.parent in where and joint.child not in where:
                    f, offset = where[joint.parent]
                    where[joint.child] = (f, offset @ joint.origin)
                    changed = True
        links, frame, ends, radius, hulls = [], [], [], [], []
        for c in parse_collisions(arm.urdf, arm.urdf_dir):
            if c.link not in where:
                raise ValueError(f'link {c.link!r} has collision geometry but does not move with the arm\'s chain '
                                 'from base to tool: bound it within the link it hangs from')
            f, offset = where[c.link]
            T = offset @ c.origin
            half = np.array([[0, 0, -c.length / 2, 1], [0, 0, c.length / 2, 1]])
            links.append(c.link)
            frame.append(f)
            ends.append(half @ T.T)
            radius.append(c.radius)
            hulls.append(None if c.points is None else c.points @ T[:3, :3].T + T[:3, 3])
        if not links:
            raise ValueError('the URDF has no collision geometry')
        return cls(arm, tuple(links), np.array(frame), np.array(ends), np.array(radius), tuple(hulls))

    def segments(self, q, base=None):
        """The capsules' end points at joint positions ``q`` (N, dof): (N, K, 2, 3), m, in the arm's
        base frame, or in the frame ``base`` (4x4, the arm's base pose there) places it in."""
        T = self.frames(q, base)
        return np.einsum('nkij,kej->nkei', T[..., :3, :], self.ends)

    def frames(self, q, base=None):
        """The frame each capsule moves with at joint positions ``q`` (N, dof): (N, K, 4, 4), in the arm's base
        frame, or in the frame ``base`` places it in."""
        q = np.atleast_2d(np.asarray(q, float))[:, :self.arm.dof]
        frames = self.arm.joint_frames(q)                               # (N, dof + 1, 4, 4)
        if base is not None:
            frames = np.asarray(base, float) @ frames
            first = np.broadcast_to(np.asarray(base, float), (len(q), 1, 4, 4))
        else:
            first = np.broadcast_to(np.eye(4), (len(q), 1, 4, 4))
        frames = np.concatenate([first, frames[:, :-1]], axis=1)       # [base, joint 1 .. joint dof]
        # tool0 and anything after the last movable joint sits at that joint's frame with an offset.
        return frames[:, self.frame]


def segment_distances(p0, p1, q0, q1):
    """The distances between segments ``p0``-``p1`` and ``q0``-``q1`` (arrays of points, (..., 3),
    broadcast against each other), m."""
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a = np.einsum('...i,...i', d1, d1)
    e = np.einsum('...i,...i', d2, d2)
    f = np.einsum('...i,...i', d2, r)
    c = np.einsum('...i,...i', d1, r)
    b = np.einsum('...i,...i', d1, d2)
    tiny = 1e-12
    denom = a * e - b * b
    with np.errstate(divide='ignore', invalid='ignore'):
        # s on the first segment: the lines' closest point (parallel lines: its start), clamped.
        s = np.where(denom > tiny, np.clip((b * f - c * e) / denom, 0.0, 1.0), 0.0)
        s = np.where(a > tiny, s, 0.0)
        # A second segment that is a point: the first's closest point to it.
        s = np.where((e <= tiny) & (a > tiny), np.clip(-c / a, 0.0, 1.0), s)
        t = np.where(e > tiny, (b * s + f) / e, 0.0)
        # t out of the second segment: clamp it and find s again for the clamped t.
        t_c = np.clip(t, 0.0, 1.0)
        s = np.where((t != t_c) & (a > tiny), np.clip((b * t_c - c) / a, 0.0, 1.0), s)
    gap = (p0 + s[..., None] * d1) - (q0 + t_c[..., None] * d2)
    return np.sqrt(np.einsum('...i,...i', gap, gap))


def point_segment_distances(p, a, b):
    """The distances from points ``p`` to the segments ``a``-``b`` (arrays (..., 3), broadcast), m: fewer steps
    than :func:`segment_distances` where one side is a point."""
    ab, ap = b - a, p - a
    s = np.clip(np.einsum('...i,...i', ap, ab) / np.maximum(np.einsum('...i,...i', ab, ab), 1e-18), 0.0, 1.0)
    gap = ap - s[..., None] * ab
    return np.sqrt(np.einsum('...i,...i', gap, gap))


def capsule_distances(A, ra, B, rb):
    """Surface distances (negative: overlap, m) between every capsule of ``A`` (..., Ka, 2, 3) and of
    ``B`` (..., Kb, 2, 3), radii ``ra`` (Ka,), ``rb`` (Kb,): shape (..., Ka, Kb)."""
    a, b = A[..., :, None, :, :], B[..., None, :, :, :]
    return segment_distances(a[..., 0, :], a[..., 1, :], b[..., 0, :], b[..., 1, :]) - ra[:, None] - rb[None, :]
