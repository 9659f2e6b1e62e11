"""Trajectories and tool paths written straight to CDR bytes read back as the same messages."""

import numpy as np
import pytest
from nav_msgs.msg import Path
from rclpy.serialization import deserialize_message
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from picking_planner import cdr


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
