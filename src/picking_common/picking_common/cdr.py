"""Messages the nodes send and read often, encoded straight to and from CDR bytes.

rclpy's message classes check every field as it is set and convert it again
to serialise it: a JointTrajectory of a few hundred points, or the Path of its
tool poses, costs milliseconds to tens of milliseconds that way, on the way
from a goal to its trajectory and its answer; a JointState costs tens of
microseconds each way, at 1 kHz in the controller and the simulator.
:func:`joint_trajectory`, :func:`path` and :class:`JointStateWriter` write the
same bytes (XCDR1, little endian: what ``serialize_message`` gives with the
default middleware) for ``Publisher.publish``, which sends bytes as they are;
:class:`JointStateReader` reads a JointState taken raw. :func:`check` tries
them all once against the middleware's own (de)serialiser, so that a node can
fall back to the message classes should a middleware serialise differently.
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


def _aligned(offset, n):
    """``offset`` (in the bytes, header included) moved up to a multiple of ``n`` after the header."""
    return offset + (-(offset - 4) % n)


class JointStateWriter:
    """The CDR bytes of sensor_msgs/JointState messages with fixed joint names.

    Everything but the stamp and the values is the same in every message, so the
    bytes are laid out once and each message writes only those into them:
    ``write(stamp_ns, position, velocity, effort)`` (each of the names' length).
    """

    def __init__(self, names, frame_id=''):
        self.n = n = len(names)
        w = _Writer()
        w.buf += _STAMP.pack(0, 0)
        w.string(frame_id)
        w.u32(n)
        for name in names:
            w.string(name)
        offsets = []
        for _ in range(3):                            # position, velocity, effort
            w.u32(n)
            if n:
                w.align(8)
            offsets.append(len(w.buf))
            w.buf += bytes(8 * n)
        self._buf = w.buf
        self._values = [np.frombuffer(self._buf, dtype='<f8', count=n, offset=o) for o in offsets]

    def write(self, stamp_ns, position, velocity, effort):
        _STAMP.pack_into(self._buf, 4, *divmod(int(stamp_ns), 1_000_000_000))
        for view, values in zip(self._values, (position, velocity, effort)):
            view[:] = values
        return bytes(self._buf)


class TransformWriter:
    """The CDR bytes of tf2_msgs/TFMessage messages whose transforms have fixed frame names.

    Laid out once as :class:`JointStateWriter`: ``write(stamp_ns, translations, quaternions)`` (N, 3 and N, 4 as
    x, y, z, w, one row per ``(parent, child)`` pair) writes only the stamps and the numbers. Each
    TransformStamped's seven doubles start on a multiple of 8, so its numbers are one aligned row.
    """

    def __init__(self, pairs):
        self.n = n = len(pairs)
        w = _Writer()
        w.u32(n)
        stamps, rows = [], []
        for parent, child in pairs:
            w.align(4)
            stamps.append(len(w.buf))
            w.buf += _STAMP.pack(0, 0)
            w.string(parent)
            w.string(child)
            w.align(8)
            rows.append(len(w.buf))
            w.buf += bytes(56)
        self._buf = w.buf
        # Views of the whole payload (4 bytes in, where CDR's alignment counts from) place every stamp and row.
        words = (len(w.buf) - 4) // 4
        self._sec = np.frombuffer(self._buf, dtype='<i4', count=words, offset=4)
        self._nanosec = np.frombuffer(self._buf, dtype='<u4', count=words, offset=4)
        self._doubles = np.frombuffer(self._buf, dtype='<f8', count=words // 2, offset=4)
        self._stamp_at = (np.array(stamps, int) - 4) // 4
        self._rows = (np.array(rows, int)[:, None] - 4) // 8 + np.arange(7)

    def write(self, stamp_ns, translations, quaternions):
        sec, nanosec = divmod(int(stamp_ns), 1_000_000_000)
        self._sec[self._stamp_at], self._nanosec[self._stamp_at + 1] = sec, nanosec
        self._doubles[self._rows[:, :3]] = translations
        self._doubles[self._rows[:, 3:]] = quaternions
        return bytes(self._buf)


_TRANSFORM = struct.Struct('<7d')


def read_transforms(data):
    """The transforms of a tf2_msgs/TFMessage's CDR bytes (little endian, as taken raw): a list of ``(parent, child,
    (x, y, z), (qx, qy, qz, qw), stamp)``, the stamp in s, as :meth:`picking_core.frames.TransformBuffer.set_transforms`
    takes them. ValueError for bytes it cannot read (big endian, truncated, malformed)."""
    try:
        if data[:4] != _HEADER:
            raise ValueError('not little-endian CDR')
        (count,) = _U32.unpack_from(data, 4)
        offset, rows = 8, []
        for _ in range(count):
            offset = _aligned(offset, 4)
            sec, nanosec = _STAMP.unpack_from(data, offset)
            offset, parent = _string(data, offset + 8)
            offset, child = _string(data, _aligned(offset, 4))
            offset = _aligned(offset, 8)
            v = _TRANSFORM.unpack_from(data, offset)
            offset += 56
            rows.append((parent, child, v[:3], v[3:], sec + nanosec * 1e-9))
    except struct.error as exc:
        raise ValueError(f'malformed TFMessage bytes: {exc}') from None
    return rows


def _string(data, offset):
    """``(end, text)``: the CDR string at ``offset``."""
    (size,) = _U32.unpack_from(data, offset)
    if size == 0 or offset + 4 + size > len(data):
        raise ValueError('malformed string')
    return offset + 4 + size, data[offset + 4:offset + 3 + size].decode('utf-8')


class _Stamp:
    __slots__ = ('sec', 'nanosec')

    def __init__(self, sec, nanosec):
        self.sec, self.nanosec = sec, nanosec


class _Header:
    __slots__ = ('stamp', 'frame_id')

    def __init__(self, stamp, frame_id):
        self.stamp, self.frame_id = stamp, frame_id


class JointStateData:
    """A JointState read from CDR bytes: the message's fields (``header.stamp.sec``,
    ``name`` as a tuple, ``position``, ``velocity``, ``effort`` as read-only float arrays)."""

    __slots__ = ('header', 'name', 'position', 'velocity', 'effort')

    def __init__(self, header, name, position, velocity, effort):
        self.header, self.name, self.position, self.velocity, self.effort = header, name, position, velocity, effort


class JointStateReader:
    """Reads the CDR bytes of sensor_msgs/JointState (little endian, as taken raw).

    A stream repeats its frame and joint names, so their bytes are compared with
    the last message's and decoded only when they change. ``read`` raises
    ValueError for bytes it cannot read (big endian, truncated, malformed).
    """

    def __init__(self):
        self._prefix = None          # the bytes of frame_id and names last decoded ...
        self._decoded = None         # ... their (frame_id, names)

    def read(self, data):
        try:
            if data[:4] != _HEADER:
                raise ValueError('not little-endian CDR')
            sec, nanosec = _STAMP.unpack_from(data, 4)
            end = self._names_end(data)
            arrays = []
            for _ in range(3):
                end = _aligned(end, 4)
                (count,) = _U32.unpack_from(data, end)
                end += 4
                if count:
                    end = _aligned(end, 8)
                if end + 8 * count > len(data):
                    raise ValueError('truncated')
                arrays.append(np.frombuffer(data, dtype='<f8', count=count, offset=end))
                end += 8 * count
        except struct.error as exc:
            raise ValueError(f'malformed JointState bytes: {exc}') from None
        frame_id, names = self._decoded
        return JointStateData(_Header(_Stamp(sec, nanosec), frame_id), names, *arrays)

    def _names_end(self, data):
        """Where the names end; decodes the frame and the names if they changed."""
        prefix = self._prefix
        if prefix is not None and data.startswith(prefix, 12):
            return 12 + len(prefix)
        offset, frame_id, names = _strings(data, 12)
        self._prefix, self._decoded = bytes(data[12:offset]), (frame_id, names)
        return offset


class JointTrajectoryData:
    """A JointTrajectory read from CDR bytes: ``header`` (``stamp.sec``, ``stamp.nanosec``,
    ``frame_id``), ``joint_names`` (a tuple) and, one row per point, ``times``
    (time_from_start, s, shape (N,)), ``positions``, ``velocities``,
    ``accelerations``, ``effort`` (each shape (N, its length in every point))."""

    __slots__ = ('header', 'joint_names', 'times', 'positions', 'velocities', 'accelerations', 'effort')

    def __init__(self, header, joint_names, times, positions, velocities, accelerations, effort):
        self.header, self.joint_names, self.times = header, joint_names, times
        self.positions, self.velocities, self.accelerations, self.effort = positions, velocities, accelerations, effort


def _point_layout(start, counts):
    """Where a JointTrajectoryPoint starting at byte ``start`` keeps its four sequences
    (``(count offset, values offset)`` each, for the given lengths), its time, and where it ends."""
    fields, offset = [], start
    for count in counts:
        offset = _aligned(offset, 4)
        at = offset
        offset += 4
        if count:
            offset = _aligned(offset, 8)
        fields.append((at, offset))
        offset += 8 * count
    offset = _aligned(offset, 4)
    return fields, offset, offset + 8


def read_joint_trajectory(data):
    """A :class:`JointTrajectoryData` from the CDR bytes of a trajectory_msgs/JointTrajectory.

    Every point is read at once (strided views of the bytes, no Python object per
    point) when all points give the same number of positions, velocities,
    accelerations and efforts as the first, which is what a trajectory that can be
    run has. Raises ValueError otherwise (points of other lengths, big endian,
    truncated or malformed bytes): read those with the message class.
    """
    try:
        if data[:4] != _HEADER:
            raise ValueError('not little-endian CDR')
        sec, nanosec = _STAMP.unpack_from(data, 4)
        offset, frame_id, names = _strings(data, 12)
        offset = _aligned(offset, 4)
        (n_points,) = _U32.unpack_from(data, offset)
        offset += 4
        if n_points == 0:
            empty = np.zeros((0, len(names)))
            return JointTrajectoryData(_Header(_Stamp(sec, nanosec), frame_id), names, np.zeros(0), empty,
                                       empty, empty, empty)
        counts, at = [], offset                    # the first point's lengths
        for _ in range(4):
            at = _aligned(at, 4)
            (count,) = _U32.unpack_from(data, at)
            counts.append(count)
            at = (_aligned(at + 4, 8) if count else at + 4) + 8 * count
        # The first point's layout, then the second's: from there every point starts at the
        # same alignment (its size a multiple of 8), so all share the second's offsets.
        starts, layouts = [offset], []
        for _ in range(min(n_points, 2)):
            layouts.append(_point_layout(starts[-1], counts))
            starts.append(layouts[-1][2])
        stride = starts[2] - starts[1] if n_points > 1 else 8
        if stride % 8 or starts[1] + stride * (n_points - 1) > len(data):
            raise ValueError('irregular or truncated points')
        columns = [[] for _ in range(6)]           # 4 sequences, sec, nanosec
        for first, count, layout in ((starts[0], 1, layouts[0]), (starts[1], n_points - 1, layouts[-1])):
            if count == 0:
                continue
            fields, time_at, _ = layout
            for i, ((count_at, values_at), k) in enumerate(zip(fields, counts)):
                lengths = np.ndarray((count,), '<u4', data, count_at, (stride,))
                if np.any(lengths != k):
                    raise ValueError('points of different lengths')
                columns[i].append(np.ndarray((count, k), '<f8', data, values_at, (stride, 8)))
            columns[4].append(np.ndarray((count,), '<i4', data, time_at, (stride,)))
            columns[5].append(np.ndarray((count,), '<u4', data, time_at + 4, (stride,)))
    except (struct.error, TypeError) as exc:
        raise ValueError(f'malformed JointTrajectory bytes: {exc}') from None
    q, qd, qdd, effort, secs, nanos = (np.concatenate(c) for c in columns)
    return JointTrajectoryData(_Header(_Stamp(sec, nanosec), frame_id), names, secs + nanos * 1e-9,
                               q, qd, qdd, effort)


def _strings(data, offset):
    """``(end, frame_id, names)``: a header's frame id then a sequence of strings, from ``offset``."""
    offset, frame_id = _string(data, offset)
    offset = _aligned(offset, 4)
    (count,) = _U32.unpack_from(data, offset)
    offset += 4
    names = []
    for _ in range(count):
        offset, name = _string(data, _aligned(offset, 4))
        names.append(name)
    return offset, frame_id, tuple(names)


@functools.cache
def check():
    """True when our bytes are what this middleware's serialiser writes and reads back as
    the same messages."""
    from nav_msgs.msg import Path
    from rclpy.serialization import deserialize_message, serialize_message
    from sensor_msgs.msg import JointState
    from tf2_msgs.msg import TFMessage
    from trajectory_msgs.msg import JointTrajectory

    names = ['a', 'bc', 'def']
    t = np.array([0.0, 0.01, 1.5])
    q = np.arange(9.0).reshape(3, 3) / 7.0
    xyz, quat = q[:, :3] + 0.5, np.array([[0.0, 0.0, 0.0, 1.0], [0.5, 0.5, 0.5, 0.5], [1.0, 0.0, 0.0, 0.0]])
    try:
        msg = deserialize_message(joint_trajectory(1_700_000_000_123_456_789, 'base_link', names, t, q, -q, 2 * q),
                                  JointTrajectory)
        tool = deserialize_message(path(1_700_000_000_123_456_789, 'base', xyz, quat), Path)
        state = JointState(name=names, position=q[0].tolist(), velocity=(-q[1]).tolist(), effort=q[2].tolist())
        state.header.stamp.sec, state.header.stamp.nanosec = 1_700_000_000, 123_456_789
        state.header.frame_id = 'base'
        # (Compared field by field: the serialiser leaves its padding bytes as they were.)
        written = deserialize_message(JointStateWriter(names, 'base').write(1_700_000_000_123_456_789, q[0], -q[1],
                                                                            q[2]), JointState)
        reader = JointStateReader()
        read = [reader.read(serialize_message(state)) for _ in range(2)]     # decoded, then cached
        trajectory = read_joint_trajectory(serialize_message(msg))
        frames = deserialize_message(TransformWriter([('base', 'a'), ('a', 'bc'), ('bc', 'def')]).write(
            1_700_000_000_123_456_789, xyz, quat), TFMessage).transforms
        rows = read_transforms(serialize_message(TFMessage(transforms=frames)))
    except Exception:  # noqa: BLE001 - any failure to read it back means: do not use it
        return False
    return (trajectory.header.stamp.sec == 1_700_000_000 and trajectory.header.stamp.nanosec == 123_456_789
            and trajectory.header.frame_id == 'base_link' and trajectory.joint_names == tuple(names)
            and np.array_equal(trajectory.positions, q) and np.array_equal(trajectory.velocities, -q)
            and np.array_equal(trajectory.accelerations, 2 * q) and trajectory.effort.shape == (3, 0)
            and np.allclose(trajectory.times, t, rtol=0.0, atol=1e-9)
            and written.header == state.header and written.name == state.name
            and all(np.array_equal(getattr(written, f), getattr(state, f)) for f in ('position', 'velocity', 'effort'))
            and all(r.header.stamp.sec == 1_700_000_000 and r.header.stamp.nanosec == 123_456_789
                    and r.header.frame_id == 'base' and r.name == tuple(names) and np.array_equal(r.position, q[0])
                    and np.array_equal(r.velocity, -q[1]) and np.array_equal(r.effort, q[2]) for r in read)
            and len(tool.poses) == 3 and tool.header.frame_id == 'base' and tool.header.stamp.nanosec == 123_456_789
            and all(p.header == tool.header and [p.pose.position.x, p.pose.position.y, p.pose.position.z] == list(xyz[i])
                    and [p.pose.orientation.x, p.pose.orientation.y, p.pose.orientation.z, p.pose.orientation.w]
                    == list(quat[i]) for i, p in enumerate(tool.poses))
            and [(f.header.frame_id, f.child_frame_id) for f in frames] == [('base', 'a'), ('a', 'bc'), ('bc', 'def')]
            and rows == [(p, c, tuple(xyz[i]), tuple(quat[i]), 1_700_000_000.123456789)
                         for i, (p, c) in enumerate([('base', 'a'), ('a', 'bc'), ('bc', 'def')])]
            and all(f.header.stamp.sec == 1_700_000_000 and f.header.stamp.nanosec == 123_456_789
                    and [f.transform.translation.x, f.transform.translation.y, f.transform.translation.z] == list(xyz[i])
                    and [f.transform.rotation.x, f.transform.rotation.y, f.transform.rotation.z, f.transform.rotation.w]
                    == list(quat[i]) for i, f in enumerate(frames))
            and msg.header.stamp.sec == 1_700_000_000 and msg.header.stamp.nanosec == 123_456_789
            and msg.header.frame_id == 'base_link' and list(msg.joint_names) == names
            and len(msg.points) == 3
            and all(np.array_equal(p.positions, q[i]) and np.array_equal(p.velocities, -q[i])
                    and np.array_equal(p.accelerations, 2 * q[i]) and len(p.effort) == 0
                    and p.time_from_start.sec == int(t[i])
                    and p.time_from_start.nanosec == round((t[i] - int(t[i])) * 1e9)
                    for i, p in enumerate(msg.points)))
