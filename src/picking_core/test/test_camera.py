"""The simulated depth camera: what it sees (view, range, occlusion by branches, links and apples), its noise
and its false positives."""

import numpy as np
import pytest

from picking_core.camera import CameraSettings, DepthCamera, look_at

EYE, TARGET = [0.0, 0.0, 1.2], [0.8, 0.0, 0.6]


def camera(**kw):
    return DepthCamera(look_at(EYE, TARGET), CameraSettings(**kw))


def test_look_at_points_the_optical_axis_at_the_target_with_y_down():
    T = look_at(EYE, TARGET)
    z = np.subtract(TARGET, EYE) / np.linalg.norm(np.subtract(TARGET, EYE))
    assert T[:3, 2] == pytest.approx(z) and T[2, 1] < 0 and np.allclose(T[:3, :3].T @ T[:3, :3], np.eye(3))


def test_it_sees_apples_in_view_and_range_and_not_behind_a_branch_or_another_apple():
    centres = np.array([[0.8, 0.0, 0.6], [0.8, 2.5, 0.6], [-0.5, 0.0, 0.6], [0.8, 0.3, 0.6], [1.2, 0.0, 0.4]])
    radii = np.full(5, 0.04)
    cam = camera()
    # 1 out of view, 2 behind the camera; 4 behind apple 0 along the line of sight (placed there below).
    centres[4] = np.array(EYE) + 1.6 * (centres[0] - EYE)
    assert cam.visible(centres, radii, np.ones(5, bool)).tolist() == [True, False, False, True, False]
    branch = np.array([[[0.6, 0.25, 0.5], [0.6, 0.25, 0.9]]])          # across the line of sight to apple 3
    seen = cam.visible(centres, radii, np.ones(5, bool), branch, np.array([0.03]))
    assert seen.tolist() == [True, False, False, False, False]
    assert camera(occlusion=False).visible(centres, radii, np.ones(5, bool), branch, np.array([0.03]))[[0, 3, 4]].all()
    assert not cam.visible(centres, radii, np.array([False, True, True, True, True]))[0]   # gone: not seen


def test_detections_are_noisy_centres_in_the_camera_frame_with_their_spread():
    cam = camera(noise=0.003, seed=1)
    centre = np.array([[0.8, 0.0, 0.6]])
    local = (centre[0] - cam.origin) @ cam.mount[:3, :3]
    errors = np.array([cam.capture(centre, np.array([0.04]), [True])[0].position - local for _ in range(2000)])
    assert np.abs(errors.mean(axis=0)).max() < 3e-4 and errors.std(axis=0) == pytest.approx([0.003] * 3, rel=0.1)


def test_false_positives_come_at_the_rate_asked_and_are_marked_for_tests():
    cam = camera(false_positives=2.0, seed=2)
    frames = [cam.capture(np.empty((0, 3)), np.empty(0), np.empty(0, bool)) for _ in range(500)]
    counts = [len(f) for f in frames]
    assert np.mean(counts) == pytest.approx(2.0, rel=0.15)
    assert all(d.truth == -1 and cam.in_view([cam.mount[:3, :3] @ d.position + cam.origin])[0] for f in frames for d in f)


def test_bad_settings_are_refused_naming_the_field():
    with pytest.raises(ValueError, match='noise'):
        CameraSettings(noise=-1.0)
    with pytest.raises(ValueError, match='near'):
        CameraSettings(near=4.0)
