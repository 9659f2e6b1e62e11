import pytest

from picking_core.kinematics import ArmModel
from picking_core.testing import pytest_configure  # noqa: F401  (hypothesis profiles, the fuzz marker)
from picking_description import default_urdf


@pytest.fixture(scope='session')
def arm():
    return ArmModel.from_urdf(default_urdf())
