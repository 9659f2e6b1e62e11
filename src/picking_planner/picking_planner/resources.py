"""Where the shipped configuration lives (URDFs, joint limits, parameter files).

Looked up in this order: the ``PICKING_ARM_CONFIG`` environment variable (a
folder), the ``share/picking_planner/config`` folder of a colcon install, and
the ``config/`` folder of the source tree (pip editable installs).
"""

from __future__ import annotations

import os
from pathlib import Path

#: The default arm's home, rad: P0 of the pick cycle (tool level, facing the tree), where the simulator
#: starts; and its gripper's opening when open, m.
HOME_POSITIONS = (0.0, 0.2, 1.6, 0.0, -0.23, 0.0)
GRIPPER_OPEN = 0.09
#: The gripper's joint in the pick cycle's plans (its finger opening, m).
GRIPPER_JOINT = 'gripper_joint'


def config_dir() -> Path:
    """The folder holding ``picking_arm.urdf`` and the nodes' YAML files."""
    env = os.environ.get('PICKING_ARM_CONFIG')
    if env:
        return Path(env)
    try:
        from ament_index_python.packages import get_package_share_directory
        share = Path(get_package_share_directory('picking_planner')) / 'config'
        if (share / 'picking_arm.urdf').exists():
            return share
    except Exception:  # noqa: BLE001 - no ament index (plain pip install): fall through
        pass
    for parent in Path(__file__).resolve().parents:
        if (parent / 'config' / 'picking_arm.urdf').exists():
            return parent / 'config'
    raise FileNotFoundError('cannot find the config folder with picking_arm.urdf; '
                            'set PICKING_ARM_CONFIG to it')


def default_urdf() -> Path:
    return config_dir() / 'picking_arm.urdf'
