"""Trajectories and tool paths written straight to CDR bytes read back as the same messages."""

import numpy as np
import pytest
from nav_msgs.msg import Path
from rclpy.serialization import deserialize_message
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from picking_common import cdr


def _classic(stamp_ns, frame_id, names, t, q, qd, qdd):
    msg = JointTrajectory()
    msg.header.frame_id = frame_id
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
    msg.joint_names = names
    for i in range(len(t)):
        p = JointTrajectoryPoint(positions=q[i].tolist(), velocities=qd[i].tolist(), accelerations=qdd[i].tolist())
        p.time_from_start.sec, p.time_from_start.nanosec = divmod(round(t[i] * 1e9), 1_000_000_000)
        msg.points.append(p)
    return msg


@pytest.mark.parametrize('joints, points, frame', [(7, 300, ''), (6, 1, 'base_link'), (1, 5, 'b'), (3, 0, 'wörld'),
                                                     (8, 17, 'abc'), (0, 4, 'x')]
                         # Frames of every length mod 8: the points start at either alignment.
                         + [(6, 20, 'f' * k) for k in range(8)])
def test_a_trajectory_in_cdr_bytes_reads_back_as_the_message_the_classes_build(joints, points, frame):
    rng = np.random.default_rng(joints * 100 + points)
    names = [f'joint_{i}' * (i % 3 + 1) for i in range(joints)]
    t = np.cumsum(rng.uniform(0.001, 0.5, points))
    q, qd, qdd = (rng.normal(0, 3, (points, joints)) for _ in range(3))
    stamp = 1_795_000_000_987_654_321
    fast = deserialize_message(cdr.joint_trajectory(stamp, frame, names, t, q, qd, qdd), JointTrajectory)
    assert fast == _classic(stamp, frame, names, t, q, qd, qdd)


@pytest.mark.parametrize('poses, frame', [(0, 'base_link'), (1, 'base_link'), (2, 'base_link'), (3, 'base_link'),
                                          (150, 'base_link')] + [(5, 'f' * k) for k in range(8)])
def test_a_tool_path_in_cdr_bytes_reads_back_with_every_pose(poses, frame):
    rng = np.random.default_rng(poses)
    xyz = rng.normal(0, 1, (poses, 3))
    quat = rng.normal(0, 1, (poses, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True) if poses else 1.0
    msg = deserialize_message(cdr.path(12_000_000_005, frame, xyz, quat), Path)
    assert msg.header.frame_id == frame and (msg.header.stamp.sec, msg.header.stamp.nanosec) == (12, 5)
    assert len(msg.poses) == poses
    for i, p in enumerate(msg.poses):
        assert p.header == msg.header
        assert [p.pose.position.x, p.pose.position.y, p.pose.position.z] == xyz[i].tolist()
        assert [p.pose.orientation.x, p.pose.orientation.y, p.pose.orientation.z, p.pose.orientation.w] \
            == quat[i].tolist()


def test_the_middleware_reads_our_bytes_back():
    assert cdr.check()


def _state(names, frame, stamp_ns, position, velocity, effort):
    from sensor_msgs.msg import JointState
    msg = JointState(name=names, position=list(position), velocity=list(velocity), effort=list(effort))
    msg.header.frame_id = frame
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
    return msg


@pytest.mark.parametrize('joints, frame', [(7, ''), (6, 'base_link'), (1, 'b'), (0, 'wörld'), (3, 'abc')]
                         + [(2, 'f' * k) for k in range(8)])
def test_joint_states_written_and_read_as_cdr_bytes_match_the_message_classes(joints, frame):
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState
    rng = np.random.default_rng(joints)
    names = [f'j{i}' * (i % 4 + 1) for i in range(joints)]
    writer, reader = cdr.JointStateWriter(names, frame), cdr.JointStateReader()
    for stamp_ns in (0, 1_700_000_000_999_999_999, 42):          # the template is rewritten each time
        values = rng.normal(size=(3, joints))
        msg = _state(names, frame, stamp_ns, *values)
        assert deserialize_message(writer.write(stamp_ns, *values), JointState) == msg
        for data in (serialize_message(msg), writer.write(stamp_ns, *values)):
            got = reader.read(data)
            assert (got.header.stamp.sec, got.header.stamp.nanosec) == divmod(stamp_ns, 1_000_000_000)
            assert got.header.frame_id == frame and got.name == tuple(names)
            for a, b in zip((got.position, got.velocity, got.effort), values):
                assert np.array_equal(a, b)


def test_the_joint_state_reader_follows_changing_names_and_empty_fields():
    from rclpy.serialization import serialize_message
    reader = cdr.JointStateReader()
    first = reader.read(serialize_message(_state(['a', 'b'], '', 5, [1.0, 2.0], [], [])))
    assert first.name == ('a', 'b') and list(first.position) == [1.0, 2.0] and first.velocity.size == 0
    second = reader.read(serialize_message(_state(['b', 'a', 'c'], 'w', 6, [3.0, 4.0, 5.0], [0.1] * 3, [])))
    assert second.name == ('b', 'a', 'c') and second.header.frame_id == 'w' and list(second.velocity) == [0.1] * 3
    assert first.name == ('a', 'b')                              # a read message stays as it was read


@pytest.mark.parametrize('damage', ['truncate', 'big_endian', 'names'])
def test_the_joint_state_reader_refuses_bytes_it_cannot_read(damage):
    from rclpy.serialization import serialize_message
    data = serialize_message(_state(['a', 'b'], 'base', 5, [1.0, 2.0], [3.0, 4.0], [5.0, 6.0]))
    if damage == 'truncate':
        data = data[:-9]
    elif damage == 'big_endian':
        data = b'\x00\x00' + data[2:]
    else:
        data = data[:28] + b'\xff\xff\xff\x7f' + data[32:]            # the first name's length
    with pytest.raises(ValueError):
        cdr.JointStateReader().read(data)


@pytest.mark.parametrize('joints, points, frame', [(7, 300, ''), (6, 1, 'base_link'), (1, 2, 'b'), (3, 0, 'wörld'),
                                                     (0, 4, 'x')] + [(6, 3, 'f' * k) for k in range(8)])
@pytest.mark.parametrize('given', ['q qd qdd', 'q', 'q qd qdd effort', 'q effort'])
def test_a_trajectory_read_from_cdr_bytes_has_every_points_values(joints, points, frame, given):
    """What the controller reads with numpy is what the message class holds, whichever fields the
    points give (each layout aligns its points differently)."""
    from rclpy.serialization import serialize_message
    rng = np.random.default_rng(joints * 100 + points)
    names = [f'joint_{i}' * (i % 3 + 1) for i in range(joints)]
    t = np.cumsum(rng.uniform(0.001, 0.5, points))
    values = {k: rng.normal(0, 3, (points, joints)) for k in ('q', 'qd', 'qdd', 'effort')}
    msg = _classic(1_795_000_000_987_654_321, frame, names, t, values['q'], values['qd'], values['qdd'])
    for p, i in zip(msg.points, range(points)):
        p.velocities = values['qd'][i].tolist() if 'qd' in given.split() else []
        p.accelerations = values['qdd'][i].tolist() if 'qdd' in given.split() else []
        p.effort = values['effort'][i].tolist() if 'effort' in given.split() else []
    got = cdr.read_joint_trajectory(serialize_message(msg))
    assert (got.header.stamp.sec, got.header.stamp.nanosec, got.header.frame_id) == (1_795_000_000, 987_654_321, frame)
    assert got.joint_names == tuple(names)
    assert got.times == pytest.approx([p.time_from_start.sec + p.time_from_start.nanosec * 1e-9 for p in msg.points])
    for field, key in (('positions', 'q'), ('velocities', 'qd'), ('accelerations', 'qdd'), ('effort', 'effort')):
        want = np.array([getattr(p, field) for p in msg.points]).reshape(points, -1) if points \
            else np.zeros((0, joints))
        assert getattr(got, field).shape == (want.shape if points else (0, joints))
        assert np.array_equal(getattr(got, field), want), field


@pytest.mark.parametrize('damage', ['lengths', 'truncate', 'big_endian', 'count'])
def test_a_trajectory_the_reader_cannot_read_at_once_is_refused(damage):
    """Points of different lengths (the controller then reads the message class, and refuses the
    trajectory with its reason) and broken bytes are a ValueError, never wrong values."""
    from rclpy.serialization import serialize_message
    msg = _classic(5, '', ['a', 'b'], np.array([0.1, 0.2, 0.3]), *(np.ones((3, 2)) for _ in range(3)))
    if damage == 'lengths':
        msg.points[2].velocities = [1.0]
    data = serialize_message(msg)
    if damage == 'truncate':                    # (our bytes: the serialiser's may carry spare bytes after the end)
        data = cdr.joint_trajectory(5, '', ['a', 'b'], np.array([0.1, 0.2, 0.3]), *(np.ones((3, 2)) for _ in range(3)))
        assert cdr.read_joint_trajectory(data).times.size == 3
        data = data[:-5]
    elif damage == 'big_endian':
        data = b'\x00\x00' + data[2:]
    elif damage == 'count':
        data = data[:40] + b'\xff\xff\xff\x0f' + data[44:]            # the number of points
    with pytest.raises(ValueError):
        cdr.read_joint_trajectory(data)


@pytest.mark.parametrize('frames', [0, 1, 2, 8])
@pytest.mark.parametrize('prefix', ['', 'a/', 'arm2/', 'wörld/', 'p' * 7])
def test_transforms_in_cdr_bytes_read_back_as_the_message_the_classes_build(frames, prefix):
    from rclpy.serialization import deserialize_message
    from tf2_msgs.msg import TFMessage

    from picking_common.codec import Codec
    rng = np.random.default_rng(frames)
    # Names of every length mod 8: each transform's numbers start at either alignment.
    pairs = [(prefix + 'l' * i, prefix + 'c' * (2 * i + 1)) for i in range(frames)]
    fast, classes = cdr.TransformWriter(pairs), Codec(raw=False).transform_writer(pairs)
    for stamp_ns in (1_700_000_000_999_999_999, 42):                # the template is rewritten each time
        xyz, quat = rng.normal(size=(frames, 3)), rng.normal(size=(frames, 4))
        assert deserialize_message(fast.write(stamp_ns, xyz, quat), TFMessage) == classes.write(stamp_ns, xyz, quat)


@pytest.mark.parametrize('frames', [0, 1, 2, 8])
@pytest.mark.parametrize('prefix', ['', 'a/', 'wörld/', 'p' * 7])
def test_transforms_read_from_cdr_bytes_are_the_messages_transforms(frames, prefix):
    """What the pip route's TF listener takes /tf with: every transform of a TFMessage the middleware serialised."""
    from rclpy.serialization import serialize_message

    from picking_common.codec import Codec
    rng = np.random.default_rng(frames)
    pairs = [(prefix + 'l' * i, prefix + 'c' * (2 * i + 1)) for i in range(frames)]
    xyz, quat = rng.normal(size=(frames, 3)), rng.normal(size=(frames, 4))
    msg = Codec(raw=False).transform_writer(pairs).write(1_700_000_000_999_999_999, xyz, quat)
    rows = cdr.read_transforms(serialize_message(msg))
    assert rows == Codec(raw=False).read_transforms(msg)
    assert [(p, c) for p, c, *_ in rows] == pairs
    for (_, _, t, r, stamp), x, q in zip(rows, xyz, quat):
        assert t == tuple(x) and r == tuple(q) and stamp == pytest.approx(1_700_000_000.999999999, abs=1e-6)


@pytest.mark.parametrize('damage', ['truncate', 'big_endian', 'name', 'count'])
def test_the_transform_reader_refuses_bytes_it_cannot_read(damage):
    from rclpy.serialization import serialize_message

    from picking_common.codec import Codec
    msg = Codec(raw=False).transform_writer([('base', 'link1'), ('link1', 'link2')]).write(5, np.ones((2, 3)),
                                                                                         np.ones((2, 4)))
    data = serialize_message(msg)
    if damage == 'truncate':
        data = data[:-9]
    elif damage == 'big_endian':
        data = b'\x00\x00' + data[2:]
    elif damage == 'name':
        data = data[:16] + b'\xff\xff\xff\x7f' + data[20:]            # the first parent's length
    else:
        data = data[:4] + b'\x03\x00\x00\x00' + data[8:]              # one transform more than the bytes hold
    with pytest.raises(ValueError):
        cdr.read_transforms(data)
    assert len(Codec().read_transforms(serialize_message(msg))) == 2   # (the codec reads what it can)
