import pathlib

import pytest

from picking_core import kinematics
from picking_core.platform import load_harvest
from picking_core.testing import pytest_configure  # noqa: F401  (hypothesis profiles, the fuzz marker)
from picking_description import scene_path, urdf_path

#: The workspace's parameter files (the shipped planner settings the pick-cycle tests plan with).
CONFIG = pathlib.Path(__file__).resolve().parents[3] / 'config'
URDF = urdf_path()


def shipped_harvest(**overrides):
    """The Harvest the shipped planner plans with (config/planner.yaml and pick_cycle.yaml)."""
    return load_harvest(URDF, [CONFIG / 'planner.yaml', CONFIG / 'pick_cycle.yaml'], **overrides)


def shipped_orchard(n, seed):
    from picking_core.collision import Scene
    from picking_core.orchard import orchard_tree
    from picking_core.pick_cycle import HOME_POSITIONS
    return orchard_tree(n, seed, kinematics.ArmModel.from_urdf(URDF), Scene.from_yaml(scene_path('workcell')),
                        HOME_POSITIONS)


@pytest.fixture(scope='session')
def arm():
    return kinematics.ArmModel.from_urdf(URDF)


@pytest.fixture(scope='session')
def ur5e():
    return kinematics.ArmModel.from_urdf(urdf_path('ur5e'))


@pytest.fixture(scope='session')
def arm3():
    return kinematics.ArmModel.from_urdf(urdf_path('picking_arm_3dof'))
