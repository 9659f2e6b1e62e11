import pathlib

import pytest

from picking_planner import kinematics
from picking_common.testing import pytest_configure  # noqa: F401  (hypothesis profiles, the fuzz marker)

CONFIG = pathlib.Path(__file__).resolve().parents[3] / 'config'


@pytest.fixture(scope='session')
def arm():
    return kinematics.ArmModel.from_urdf(CONFIG / 'picking_arm.urdf')


@pytest.fixture(scope='session')
def arm3():
    return kinematics.ArmModel.from_urdf(CONFIG / 'picking_arm_3dof.urdf')
