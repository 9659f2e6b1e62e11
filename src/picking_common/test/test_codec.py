"""The codec gives its callers the same messages whether it writes CDR bytes or falls back to the
message classes: a plan, a tool path and a joint-state stream, both ways."""

import numpy as np
import pytest
from nav_msgs.msg import Path
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

from picking_common.codec import Codec

NAMES = ['shoulder_pan_joint', 'elbow_joint', 'gripper_joint']


def as_message(built, msg_type):
    """What a subscriber of ``msg_type`` receives for what the codec built."""
    return deserialize_message(built if isinstance(built, bytes) else serialize_message(built), msg_type)


@pytest.fixture(params=[None, False], ids=['cdr', 'message-classes'])
def codec(request):
    return Codec(raw=request.param)


def test_the_fallback_is_forced_by_raw_false_and_by_the_environment(monkeypatch):
    assert Codec().raw and not Codec(raw=False).raw
    monkeypatch.setenv('PICKING_CODEC', 'messages')
    assert not Codec().raw


def test_a_plan_goes_through_either_way_unchanged(codec):
    t = np.array([0.0, 0.01, 0.02, 1.5])
    q = np.random.default_rng(3).normal(size=(4, 3))
    built = codec.joint_trajectory(1_700_000_000_250_000_000, 'base_link', NAMES, t, q, -q, 2 * q)
    assert isinstance(built, bytes) == codec.raw
    msg = as_message(built, JointTrajectory)
    assert list(msg.joint_names) == NAMES and msg.header.frame_id == 'base_link'
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1_700_000_000, 250_000_000)
    assert np.array_equal([p.positions for p in msg.points], q)
    # Read back as a controller takes it: from bytes (a raw subscription) or from the message.
    delivered = serialize_message(msg) if codec.raw else msg
    read = codec.read_trajectory(delivered)
    names, times, pos, vel, acc, start = read.args()
    assert tuple(names) == tuple(NAMES) and start == pytest.approx(1_700_000_000.25)
    assert np.allclose(times, t, atol=1e-9)
    assert np.array_equal(np.asarray(pos), q) and np.array_equal(np.asarray(vel), -q)
    assert np.array_equal(np.asarray(acc), 2 * q)


def test_points_of_different_lengths_are_read_through_the_message_class(codec):
    msg = as_message(codec.joint_trajectory(5, '', NAMES[:2], [0.0, 1.0], np.ones((2, 2)), np.ones((2, 2)),
                                            np.ones((2, 2))), JointTrajectory)
    msg.points[1].velocities = [1.0]
    read = codec.read_trajectory(serialize_message(msg))
    assert read.velocities == [[1.0, 1.0], [1.0]]


def test_a_tool_path_goes_through_either_way_unchanged(codec):
    xyz = np.array([[0.1, 0.2, 0.3], [0.4, 0.5, 0.6]])
    quat = np.array([[0.0, 0.0, 0.0, 1.0], [1.0, 0.0, 0.0, 0.0]])
    msg = as_message(codec.path(3_000_000_007, 'base_link', xyz, quat), Path)
    assert msg.header.frame_id == 'base_link' and msg.header.stamp.nanosec == 7
    assert [[p.pose.position.x, p.pose.position.y, p.pose.position.z] for p in msg.poses] == xyz.tolist()
    assert [p.pose.orientation.w for p in msg.poses] == [1.0, 0.0]


def test_a_joint_state_stream_goes_through_either_way_unchanged(codec):
    writer, reader = codec.joint_state_writer(NAMES), codec.state_reader()
    assert (reader is not None) == codec.raw
    for k in range(3):
        q = np.arange(3.0) + k
        msg = as_message(writer.write(k * 1_000_000_001, q, -q, 2 * q), JointState)
        assert list(msg.name) == NAMES and msg.header.stamp.sec == k
        assert list(msg.position) == q.tolist() and list(msg.effort) == (2 * q).tolist()
        if reader is not None:
            read = reader(serialize_message(msg))
            assert np.array_equal(read.velocity, -q) and read.name == tuple(NAMES)
