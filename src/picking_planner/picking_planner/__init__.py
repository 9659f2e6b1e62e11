"""Picking-arm planner: the pure core (no ROS) and the planner node.

The core modules ``trajectory``, ``geometry`` and ``kinematics`` import only
numpy and scipy; the ROS node lives in ``picking_planner.node``.
"""

from . import geometry, kinematics, trajectory

__all__ = ['geometry', 'kinematics', 'trajectory']
