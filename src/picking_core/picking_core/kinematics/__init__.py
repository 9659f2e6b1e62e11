"""Arm model from a URDF, forward and inverse kinematics, reachability, Cartesian paths.

>>> from picking_core import kinematics
>>> arm = kinematics.ArmModel.from_urdf(picking_description.default_urdf())
>>> T = arm.fk([0, 0.3, 1.2, 0, 0.5, 0])          # 4x4 tool pose in base_link
>>> q = arm.ik(T, seed=[0, 0.2, 1.1, 0, 0.4, 0])   # nearest valid solution
"""

from .errors import Unreachable
from .model import ArmModel, load_joint_limits
from .paths import JointPath, cartesian_to_joint, pose_matrix

__all__ = ['ArmModel', 'Unreachable', 'load_joint_limits', 'JointPath', 'cartesian_to_joint',
           'pose_matrix']
