"""The description is found where a user's tools look for it, and says what is missing when it is not."""

import pytest

import picking_description as d


def test_the_shipped_arm_scenes_and_platforms_are_found():
    assert d.default_urdf().name == 'picking_arm.urdf' and d.default_urdf().exists()
    assert d.urdf_path('picking_arm_3dof').exists()
    assert (d.default_urdf().parent / 'picking_arm_joint_limits.yaml').exists()
    assert {d.scene_path(n).name for n in ('workcell', 'orchard', 'platform_arm')} == {
        'workcell_scene.yaml', 'orchard_scene.yaml', 'platform_arm_scene.yaml'}
    assert d.platform_path().name == 'platform.yaml'


def test_a_missing_file_is_named_with_what_is_there():
    with pytest.raises(FileNotFoundError, match=r"no URDF 'ur99\.urdf' in .*urdf \(there: .*picking_arm\.urdf"):
        d.urdf_path('ur99')


def test_the_environment_variable_points_elsewhere(tmp_path, monkeypatch):
    monkeypatch.setenv('PICKING_DESCRIPTION', str(tmp_path))
    assert d.share_dir() == tmp_path
    with pytest.raises(FileNotFoundError, match='no scene'):
        d.scene_path('workcell')
