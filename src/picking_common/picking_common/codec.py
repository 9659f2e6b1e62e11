"""The messages the nodes send and read often, as CDR bytes where the middleware agrees, else
as message classes: one object decides once and every caller goes through it.

rclpy's message classes check every field as it is set and convert it again to serialise
it, which costs a trajectory of a few hundred points milliseconds and a 1 kHz JointState
stream a large share of a core. :mod:`.cdr` writes and reads the same bytes directly.
:class:`Codec` checks those bytes once against the middleware's own serialiser and, should a
middleware serialise differently (or ``raw=False`` is asked for), builds and reads the
message classes instead, with the same results for its callers.
"""

from __future__ import annotations

import os

import numpy as np
from geometry_msgs.msg import PoseStamped, TransformStamped
from nav_msgs.msg import Path
from rclpy.serialization import deserialize_message
from tf2_msgs.msg import TFMessage
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from . import cdr
from .joint_state import joint_state, seconds


class TrajectoryData:
    """A trajectory as a controller takes it: ``joint_names``, ``times`` (s from the start),
    ``positions``, ``velocities``, ``accelerations`` (one row per point: arrays when read from
    bytes, lists of lists from a message, where points may differ in length), ``start`` (the
    header stamp, s) and ``header``."""

    __slots__ = ('joint_names', 'times', 'positions', 'velocities', 'accelerations', 'start', 'header')

    def __init__(self, joint_names, times, positions, velocities, accelerations, header):
        self.joint_names, self.times = joint_names, times
        self.positions, self.velocities, self.accelerations = positions, velocities, accelerations
        self.header, self.start = header, seconds(header.stamp)

    def args(self):
        """``(joint_names, times, positions, velocities, accelerations, start)``."""
        return self.joint_names, self.times, self.positions, self.velocities, self.accelerations, self.start


class _MessageStateWriter:
    """JointState messages with fixed names, refilled (the fallback of :class:`cdr.JointStateWriter`)."""

    def __init__(self, names):
        self.msg = joint_state(names, None, [], [], [])

    def write(self, stamp_ns, position, velocity, effort):
        msg = self.msg
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(stamp_ns), 1_000_000_000)
        msg.position, msg.velocity, msg.effort = (np.asarray(x, float).tolist() for x in (position, velocity, effort))
        return msg


class _MessageTransformWriter:
    """TFMessages with fixed frame names, built anew (the fallback of :class:`cdr.TransformWriter`)."""

    def __init__(self, pairs):
        self.pairs = list(pairs)

    def write(self, stamp_ns, translations, quaternions):
        msg = TFMessage()
        sec, nanosec = divmod(int(stamp_ns), 1_000_000_000)
        for (parent, child), xyz, quat in zip(self.pairs, np.asarray(translations, float),
                                              np.asarray(quaternions, float)):
            t = TransformStamped(child_frame_id=child)
            t.header.frame_id, t.header.stamp.sec, t.header.stamp.nanosec = parent, sec, nanosec
            t.transform.translation.x, t.transform.translation.y, t.transform.translation.z = map(float, xyz)
            r = t.transform.rotation
            r.x, r.y, r.z, r.w = map(float, quat)
            msg.transforms.append(t)
        return msg


class Codec:
    """Builds and reads JointTrajectory, Path, JointState and TFMessage for publishers and subscriptions.

    ``raw`` None: CDR bytes where :func:`cdr.check` finds this middleware agrees with them, unless
    the environment sets ``PICKING_CODEC=messages``; False: always the message classes (what the
    fallback runs). What it builds is handed to
    ``Publisher.publish`` as it is (bytes or a message); a subscription created with
    ``raw=codec.raw`` delivers what :meth:`read_trajectory` and :meth:`state_reader` take.
    """

    def __init__(self, raw=None):
        if raw is None:
            raw = os.environ.get('PICKING_CODEC', 'cdr') != 'messages'
        self.raw = bool(raw) and cdr.check()

    def joint_trajectory(self, stamp_ns, frame_id, names, t, q, qd, qdd):
        """A JointTrajectory stamped ``stamp_ns`` (integer ns): points at ``t`` (s) with positions,
        velocities and accelerations, one row per point."""
        if self.raw:
            return cdr.joint_trajectory(stamp_ns, frame_id, names, t, q, qd, qdd)
        msg = JointTrajectory()
        msg.joint_names = list(names)
        msg.header.frame_id = frame_id
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(stamp_ns), 1_000_000_000)
        for i in range(len(t)):
            p = JointTrajectoryPoint(positions=np.asarray(q[i], float).tolist(),
                                     velocities=np.asarray(qd[i], float).tolist(),
                                     accelerations=np.asarray(qdd[i], float).tolist())
            p.time_from_start.sec, p.time_from_start.nanosec = divmod(round(float(t[i]) * 1e9), 1_000_000_000)
            msg.points.append(p)
        return msg

    def path(self, stamp_ns, frame_id, positions, quaternions):
        """A nav_msgs/Path of poses (positions (N, 3) m, quaternions (N, 4) x y z w)."""
        if self.raw:
            return cdr.path(stamp_ns, frame_id, positions, quaternions)
        path = Path()
        path.header.frame_id = frame_id
        path.header.stamp.sec, path.header.stamp.nanosec = divmod(int(stamp_ns), 1_000_000_000)
        for xyz, quat in zip(np.asarray(positions, float), np.asarray(quaternions, float)):
            ps = PoseStamped(header=path.header)
            ps.pose.position.x, ps.pose.position.y, ps.pose.position.z = map(float, xyz)
            (ps.pose.orientation.x, ps.pose.orientation.y, ps.pose.orientation.z,
             ps.pose.orientation.w) = map(float, quat)
            path.poses.append(ps)
        return path

    def joint_state_writer(self, names):
        """An object whose ``write(stamp_ns, position, velocity, effort)`` gives a JointState
        with ``names`` to publish (its bytes, or a message refilled at every call)."""
        return cdr.JointStateWriter(names) if self.raw else _MessageStateWriter(names)

    def transform_writer(self, pairs):
        """An object whose ``write(stamp_ns, translations, quaternions)`` gives a tf2_msgs/TFMessage of the
        ``(parent, child)`` pairs to publish (its bytes, or a message)."""
        return cdr.TransformWriter(pairs) if self.raw else _MessageTransformWriter(pairs)

    def state_reader(self):
        """A reader of JointState bytes for :class:`~picking_common.topics.LatestMessage`, or None
        (then it takes message classes)."""
        return cdr.JointStateReader().read if self.raw else None

    def read_transforms(self, msg):
        """The transforms of what a TFMessage subscription delivered (bytes, or a message) as rows of ``(parent,
        child, (x, y, z), (qx, qy, qz, qw), stamp s)``; bytes our reader refuses are read by the message class."""
        if isinstance(msg, (bytes, bytearray)):
            try:
                return cdr.read_transforms(msg)
            except ValueError:
                msg = deserialize_message(bytes(msg), TFMessage)
        return [(tf.header.frame_id, tf.child_frame_id,
                 (tf.transform.translation.x, tf.transform.translation.y, tf.transform.translation.z),
                 (tf.transform.rotation.x, tf.transform.rotation.y, tf.transform.rotation.z, tf.transform.rotation.w),
                 seconds(tf.header.stamp)) for tf in msg.transforms]

    def read_trajectory(self, msg):
        """A :class:`TrajectoryData` from what a JointTrajectory subscription delivered: bytes
        (read with numpy; points of differing lengths through the message class) or a message."""
        if isinstance(msg, (bytes, bytearray)):
            try:
                read = cdr.read_joint_trajectory(msg)
            except ValueError:
                msg = deserialize_message(bytes(msg), JointTrajectory)
            else:
                return TrajectoryData(read.joint_names, read.times, read.positions, read.velocities,
                                      read.accelerations, read.header)
        pts = msg.points
        return TrajectoryData(tuple(msg.joint_names), [seconds(p.time_from_start) for p in pts],
                              [list(p.positions) for p in pts], [list(p.velocities) for p in pts],
                              [list(p.accelerations) for p in pts], msg.header)
