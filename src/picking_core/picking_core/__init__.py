"""The picking arm's pure core: trajectories, geometry, kinematics, planning, collision, the pick cycle,
harvests, several arms, the goal policy and lifecycle. It imports numpy, scipy, numba, ruckig and coal,
never ROS: it runs in a notebook, is tested without a node and is benchmarked.

>>> from picking_core import trajectory, geometry, kinematics
"""

import importlib

__all__ = ['geometry', 'kinematics', 'trajectory']


def __getattr__(name):
    # Subpackages load on first use: a tool that needs only a constant (picking_core.methods) starts fast.
    if name in __all__:
        return importlib.import_module(f'.{name}', __name__)
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
