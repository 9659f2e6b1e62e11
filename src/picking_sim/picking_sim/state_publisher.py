"""``picking-state-publisher``: the URDF on ``robot_description``, every link of the arm as a frame on ``/tf`` and
``/tf_static``.

As robot_state_publisher does from ``robot_description`` and ``joint_states``: each moving link on
``/tf`` for every joint state (stamped with it, sent ``update_rate`` times a second), the fixed joints once on ``/tf_static``
(transient local), every frame named with ``frame_prefix``; with ``parent_frame``, the arm's base in
that frame (a platform's) on ``/tf_static`` too. An apt-installed Jazzy's robot_state_publisher does
the same from the URDF (docs/deployment.md).
"""

from __future__ import annotations

import numpy as np
from geometry_msgs.msg import TransformStamped
from rclpy.node import Node
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage

from picking_common.codec import Codec
from picking_common.params import declare, usage
from picking_common.run import run_node
from picking_common.tf import TF_QOS
from picking_common.topics import LATCHED, LatestMessage
from picking_core.kinematics.tree import RobotTree
from picking_core.kinematics.urdf import origin_matrix
from picking_description import default_urdf

from .parameters import STATE_PUBLISHER as PARAMS

#: Joint states kept between two wakes (a 1 kHz stream at the slowest update_rate loses none).
STATES_KEPT = 1000


def transform_msg(parent, child, T, stamp):
    """A geometry_msgs/TransformStamped of the 4x4 ``T`` (parent <- child) stamped ``stamp`` (builtin Time)."""
    msg = TransformStamped()
    msg.header.stamp, msg.header.frame_id, msg.child_frame_id = stamp, parent, child
    t, q = msg.transform.translation, msg.transform.rotation
    t.x, t.y, t.z = (float(v) for v in T[:3, 3])
    q.x, q.y, q.z, q.w = (float(v) for v in Rotation.from_matrix(T[:3, :3]).as_quat())
    return msg


class StatePublisherNode(Node):
    """The arm's links on /tf and /tf_static."""

    def __init__(self, **kwargs):
        super().__init__('picking_state_publisher', **kwargs)
        p = declare(self, PARAMS)
        urdf = open(p['urdf_path'] or default_urdf()).read()
        self.tree = RobotTree.from_urdf(urdf)
        self.prefix = p['frame_prefix']
        self.codec = Codec()
        self._layouts = {}           # a JointState's names -> (indices of the tree's joints in it, writer)
        self.pub_tf = self.create_publisher(TFMessage, '/tf', TF_QOS)
        self.pub_static = self.create_publisher(TFMessage, '/tf_static', LATCHED)
        stamp = self.get_clock().now().to_msg()
        static = [transform_msg(self.prefix + a, self.prefix + b, T, stamp) for a, b, T in self.tree.static_transforms()]
        if p['parent_frame']:
            xyz, rpy = np.asarray(p['parent_xyz'], float), np.asarray(p['parent_rpy'], float)
            if xyz.shape != (3,) or rpy.shape != (3,) or not (np.all(np.isfinite(xyz)) and np.all(np.isfinite(rpy))):
                raise ValueError('parent_xyz and parent_rpy must be 3 finite numbers each')
            static.append(transform_msg(p['parent_frame'], self.prefix + self.tree.root, origin_matrix(xyz, rpy),
                                        stamp))
        self.pub_static.publish(TFMessage(transforms=static))
        self.pub_description = self.create_publisher(String, 'robot_description', LATCHED)
        self.pub_description.publish(String(data=urdf))
        self.states = LatestMessage(self, JointState, 'joint_states', self.codec.state_reader(), depth=STATES_KEPT)
        self.create_timer(1.0 / p['update_rate'], self._publish)
        self.get_logger().info(f'publishing {len(self.tree.moving)} moving and {len(static)} fixed frames of '
                               f'{self.tree.name} under {self.prefix + self.tree.root!r}')

    def _layout(self, names):
        """Where each of the tree's joints is in a JointState of ``names``, and the writer of the frames it moves
        (a joint it does not name is left off ``/tf``, as robot_state_publisher leaves it)."""
        layout = self._layouts.get(names)
        if layout is None:
            where = {name: i for i, name in enumerate(names)}
            index = np.array([where.get(name, -1) for name in self.tree.joint_names], int)
            pairs = [(self.prefix + a, self.prefix + b) for (a, b), i in zip(self.tree.pairs, index) if i >= 0]
            layout = self._layouts[names] = (index, self.codec.transform_writer(pairs))
        return layout

    def _publish(self):
        for state in self.states.take_all():
            self._publish_state(state)

    def _publish_state(self, state):
        index, writer = self._layout(tuple(state.name))
        known = index >= 0
        position = np.asarray(state.position, float)
        if not known.any() or index.max() >= len(position):
            return
        q = np.zeros(len(index))
        q[known] = position[index[known]]
        if not np.all(np.isfinite(q)):
            return                       # a frame from a NaN would poison every lookup through it
        translations, quaternions = self.tree.poses(q)
        stamp = state.header.stamp
        self.pub_tf.publish(writer.write(stamp.sec * 1_000_000_000 + stamp.nanosec, translations[known],
                                         quaternions[known]))


def main(args=None):
    return run_node(StatePublisherNode, args, help=usage('picking-state-publisher', __doc__, PARAMS))


if __name__ == '__main__':
    raise SystemExit(main())
