"""Messages the planner sends often, encoded straight to CDR bytes.

rclpy's message classes check every field as it is set and convert it again
to serialise it: a JointTrajectory of a few hundred points, or the Path of its
tool poses, costs milliseconds to tens of milliseconds that way, on the way
from a goal to its trajectory and its answer. :func:`joint_trajectory` and
:func:`path` write the same bytes (XCDR1, little endian: what
``serialize_message`` gives with the default middleware) for
``Publisher.publish``, which sends bytes as they are. :func:`check` reads both
back once, so that a node can fall back to the message classes should a
middleware serialise differently.
"""

from __future__ import annotations

import functools
import struct

import numpy as np

_HEADER = b'\x00\x01\x00\x00'           # encapsulation: CDR, little endian
_U32 = struct.Struct('<I')
_STAMP = struct.Struct('<iI')


class _Writer:
    """Appends CDR primitives, aligned relative to the end of the encapsulation header."""

    def __init__(self):
        self.buf = bytearray(_HEADER)

    def align(self, n):
        pad = -(len(self.buf) - 4) % n
        if pad:
            self.buf += bytes(pad)

    def u32(self, value):
        self.align(4)
        self.buf += _U32.pack(value)

    def string(self, text):
        data = text.encode('utf-8')
        self.u32(len(data) + 1)
        self.buf += data + b'\x00'

    def doubles(self, row):
        """A sequence<double> from a contiguous float64 array."""
        self.u32(row.size)
        if row.size:
            self.align(8)
            self.buf += row.tobytes()


def joint_trajectory(stamp_ns, frame_id, names, t, q, qd, qdd):
    """The CDR bytes of a trajectory_msgs/JointTrajectory.

    ``stamp_ns`` is the header stamp in integer nanoseconds; ``t`` (N,) the points'
    time_from_start in s; ``q``, ``qd``, ``qdd`` (N, len(names)) positions,
    velocities and accelerations; efforts are left empty.
    """
    w = _Writer()
    w.buf += _STAMP.pack(*divmod(int(stamp_ns), 1_000_000_000))
    w.string(frame_id)
    w.u32(len(names))
    for name in names:
        w.string(name)
    ns = np.round(np.asarray(t, float) * 1e9).astype(np.int64)
    secs, nanos = (ns // 1_000_000_000).tolist(), (ns % 1_000_000_000).tolist()
    q, qd, qdd = (np.ascontiguousarray(x, dtype='<f8') for x in (q, qd, qdd))
    w.u32(len(secs))
    first = 0
    if len(names) == 0 or (len(w.buf) - 4) % 8 == 0:
        # A point that starts 8-aligned pads differently from the rest (and points without
        # joints have no padding at all): written one by one.
        first = len(secs) if len(names) == 0 else min(1, len(secs))
        for i in range(first):
            w.doubles(q[i])
            w.doubles(qd[i])
            w.doubles(qdd[i])
            w.u32(0)                                  # effort: none
            w.buf += _STAMP.pack(secs[i], nanos[i])   # time_from_start (4-aligned here)
    if first < len(secs):
        # Every other point starts at 4 mod 8 and has the same layout: written at once.
        points = np.zeros(len(secs) - first, dtype=_point_dtype(len(names)))
        points['n_q'] = points['n_qd'] = points['n_qdd'] = len(names)
        points['q'], points['qd'], points['qdd'] = q[first:], qd[first:], qdd[first:]
        points['sec'], points['nanosec'] = secs[first:], nanos[first:]
        w.buf += points.tobytes()
    return bytes(w.buf)


@functools.lru_cache(maxsize=16)
def _point_dtype(n):
    """A JointTrajectoryPoint of ``n`` joints starting at 4 mod 8: each sequence's length, then
    (padded to 8) its doubles; an empty effort; time_from_start."""
    return np.dtype({
        'names': ['n_q', 'q', 'n_qd', 'qd', 'n_qdd', 'qdd', 'n_effort', 'sec', 'nanosec'],
        'formats': ['<u4', ('<f8', n), '<u4', ('<f8', n), '<u4', ('<f8', n), '<u4', '<i4', '<u4'],
        'offsets': [0, 4, 4 + 8 * n, 12 + 8 * n, 12 + 16 * n, 20 + 16 * n, 20 + 24 * n, 24 + 24 * n,
                    28 + 24 * n],
        'itemsize': 32 + 24 * n})


def path(stamp_ns, frame_id, positions, quaternions):
    """The CDR bytes of a nav_msgs/Path whose poses (N, 3 and N, 4 as x, y, z, w) all
    carry the path's header."""
    positions = np.asarray(positions, float)
    quaternions = np.asarray(quaternions, float)
    poses = np.ascontiguousarray(np.hstack([positions, quaternions]), dtype='<f8')
    stamp = _STAMP.pack(*divmod(int(stamp_ns), 1_000_000_000))
    w = _Writer()
    w.buf += stamp
    w.string(frame_id)
    w.u32(len(poses))
    # Each PoseStamped: the header (stamp, frame), padding to 8, seven doubles. Its size is a
    # multiple of 8 from the second pose on, so the rest repeat the second's bytes but for the
    # pose: written at once.
    first = min(2, len(poses))
    for row in poses[:first]:
        w.align(4)
        start = len(w.buf)
        w.buf += stamp
        w.string(frame_id)
        w.align(8)
        header = bytes(w.buf[start:])
        w.buf += row.tobytes()
    if len(poses) > first:
        rest = np.empty((len(poses) - first, len(header) + 56), dtype=np.uint8)
        rest[:, :len(header)] = np.frombuffer(header, dtype=np.uint8)
        rest[:, len(header):] = poses[first:].view(np.uint8).reshape(len(rest), 56)
        w.buf += rest.tobytes()
    return bytes(w.buf)


def check():
    """True when :func:`joint_trajectory` gives what this middleware's serialiser reads back
    as the same message."""
    from nav_msgs.msg import Path
    from rclpy.serialization import deserialize_message
    from trajectory_msgs.msg import JointTrajectory

    names = ['a', 'bc', 'def']
    t = np.array([0.0, 0.01, 1.5])
    q = np.arange(9.0).reshape(3, 3) / 7.0
    xyz, quat = q[:, :3] + 0.5, np.array([[0.0, 0.0, 0.0, 1.0], [0.5, 0.5, 0.5, 0.5], [1.0, 0.0, 0.0, 0.0]])
    try:
        msg = deserialize_message(joint_trajectory(1_700_000_000_123_456_789, 'base_link', names, t, q, -q, 2 * q),
                                  JointTrajectory)
        tool = deserialize_message(path(1_700_000_000_123_456_789, 'base', xyz, quat), Path)
    except Exception:  # noqa: BLE001 - any failure to read it back means: do not use it
        return False
    return (len(tool.poses) == 3 and tool.header.frame_id == 'base' and tool.header.stamp.nanosec == 123_456_789
            and all(p.header == tool.header and [p.pose.position.x, p.pose.position.y, p.pose.position.z] == list(xyz[i])
                    and [p.pose.orientation.x, p.pose.orientation.y, p.pose.orientation.z, p.pose.orientation.w]
                    == list(quat[i]) for i, p in enumerate(tool.poses))
            and msg.header.stamp.sec == 1_700_000_000 and msg.header.stamp.nanosec == 123_456_789
            and msg.header.frame_id == 'base_link' and list(msg.joint_names) == names
            and len(msg.points) == 3
            and all(np.array_equal(p.positions, q[i]) and np.array_equal(p.velocities, -q[i])
                    and np.array_equal(p.accelerations, 2 * q[i]) and len(p.effort) == 0
                    and p.time_from_start.sec == int(t[i])
                    and p.time_from_start.nanosec == round((t[i] - int(t[i])) * 1e9)
                    for i, p in enumerate(msg.points)))
