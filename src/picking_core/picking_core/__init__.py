"""The picking arm's pure core: trajectories, geometry, kinematics, planning, collision, the pick cycle,
harvests, several arms, the goal policy and lifecycle. It imports numpy, scipy, numba, ruckig and coal,
never ROS: it runs in a notebook, is tested without a node and is benchmarked.

>>> from picking_core import trajectory, geometry, kinematics
"""

from . import geometry, kinematics, trajectory

__all__ = ['geometry', 'kinematics', 'trajectory']
