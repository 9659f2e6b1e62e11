"""Poses as geometry_msgs carry them, to and from the core's 4x4 transforms."""

from __future__ import annotations

from geometry_msgs.msg import Pose
from scipy.spatial.transform import Rotation

from picking_core.kinematics import pose_matrix


def msg_pose(pose):
    """The 4x4 transform of a geometry_msgs/Pose; ValueError naming the field for a NaN or a zero quaternion."""
    p, o = pose.position, pose.orientation
    for name, value in (('position.x', p.x), ('position.y', p.y), ('position.z', p.z), ('orientation.x', o.x),
                        ('orientation.y', o.y), ('orientation.z', o.z), ('orientation.w', o.w)):
        if value != value or value in (float('inf'), float('-inf')):
            raise ValueError(f'the pose\'s {name} is {value}: every field must be a finite number')
    if o.x == o.y == o.z == o.w == 0.0:
        raise ValueError('the pose\'s orientation quaternion is zero (x = y = z = w = 0): give a unit quaternion, '
                         'e.g. w = 1 for the frame\'s own orientation')
    return pose_matrix([p.x, p.y, p.z], [o.x, o.y, o.z, o.w])


def pose_msg(T):
    """The geometry_msgs/Pose of a 4x4 transform."""
    x, y, z, w = (float(v) for v in Rotation.from_matrix(T[:3, :3]).as_quat())
    p = Pose()
    p.position.x, p.position.y, p.position.z = (float(v) for v in T[:3, 3])
    p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w = x, y, z, w
    return p
