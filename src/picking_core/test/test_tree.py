"""RobotTree: every link's frame from the joint positions, as robot_state_publisher computes them."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from picking_core.kinematics import ArmModel
from picking_core.kinematics.tree import RobotTree
from picking_description import default_urdf

URDF = open(default_urdf()).read()
TREE = RobotTree.from_urdf(URDF)
ARM = ArmModel.from_urdf(default_urdf())


def chain(transforms, tip):
    """The 4x4 pose of ``tip`` in the root, composed link by link up the tree."""
    parent_of = {child: (parent, T) for parent, child, T in transforms}
    T = np.eye(4)
    while tip in parent_of:
        tip, step = parent_of[tip]
        T = step @ T
    assert tip == TREE.root
    return T


@pytest.mark.parametrize('seed', range(5))
def test_the_links_composed_from_the_root_to_the_tool_are_the_arms_fk(seed):
    q = np.random.default_rng(seed).uniform(-2.5, 2.5, 6)
    positions = dict(zip(ARM.joint_names, q)) | {'gripper_finger_joint': 0.03}
    transforms = TREE.transforms(positions) + TREE.static_transforms()
    assert chain(transforms, 'tool0') == pytest.approx(ARM.fk(q), abs=1e-12)


def test_poses_are_the_transforms_as_translations_and_unit_quaternions():
    q = np.linspace(-1.0, 1.0, len(TREE.joint_names))
    translations, quaternions = TREE.poses(q)
    assert np.linalg.norm(quaternions, axis=1) == pytest.approx(1.0)
    for (parent, child, T), xyz, quat in zip(TREE.transforms(dict(zip(TREE.joint_names, q))), translations,
                                             quaternions):
        assert T[:3, 3] == pytest.approx(xyz) and T[:3, :3] == pytest.approx(Rotation.from_quat(quat).as_matrix())


def test_a_prismatic_joint_slides_its_child_along_its_axis():
    (finger,) = [i for i, link in enumerate(TREE.moving) if link.type == 'prismatic']
    q = np.zeros(len(TREE.joint_names))
    closed = TREE.poses(q)[0][finger]
    q[finger] = 0.04
    opened, quaternion = TREE.poses(q)[0][finger], TREE.poses(q)[1][finger]
    link = TREE.moving[finger]
    assert opened - closed == pytest.approx(link.origin[:3, :3] @ link.axis * 0.04)
    assert Rotation.from_quat(quaternion).as_matrix() == pytest.approx(link.origin[:3, :3])


def test_a_joint_without_a_finite_position_is_left_out():
    positions = dict(zip(ARM.joint_names, np.zeros(6))) | {'elbow_joint': float('nan')}
    children = [child for _, child, _ in TREE.transforms(positions)]
    assert 'forearm_link' not in children and 'gripper_finger_link' not in children and 'wrist_1_link' in children


def test_a_urdf_with_two_roots_is_refused():
    with pytest.raises(ValueError, match='one root'):
        RobotTree.from_urdf(URDF.replace('<parent link="base_link"/>', '<parent link="stand"/>', 1)
                            .replace('</robot>', '<link name="stand"/><link name="other"/><joint name="x" '
                                     'type="fixed"><parent link="other"/><child link="lonely"/></joint>'
                                     '<link name="lonely"/></robot>'))
