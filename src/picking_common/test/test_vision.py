"""Apple detections to vision_msgs/Detection3DArray and back, and the detections a reader refuses."""

import numpy as np
import pytest

from picking_common.vision import detections_msg, read_detections
from picking_core.camera import Detection


def test_detections_go_out_and_come_back_with_their_spread():
    dets = [Detection(np.array([0.1, -0.2, 0.9]), 0.075, 0.9, 0.003, 0),
            Detection(np.array([0.0, 0.1, 1.2]), 0.07, 0.5, 0.003, -1)]
    msg = detections_msg(dets, 'arm1/camera_optical_frame', 1_700_000_000_250_000_000)
    assert msg.header.frame_id == 'arm1/camera_optical_frame' and msg.header.stamp.nanosec == 250_000_000
    positions, covs, diameters, scores, refused = read_detections(msg)
    assert positions == pytest.approx(np.array([d.position for d in dets])) and refused == []
    assert covs[0] == pytest.approx(np.eye(3) * 0.003 ** 2) and diameters == pytest.approx([0.075, 0.07])
    assert scores == pytest.approx([0.9, 0.5])


def test_a_detection_with_nan_a_bad_covariance_or_another_class_is_refused_with_the_reason():
    dets = [Detection(np.array([0.1, 0.2, 0.9]), 0.07, 0.9, 0.003, 0) for _ in range(4)]
    msg = detections_msg(dets, 'cam', 0)
    msg.detections[0].results[0].pose.pose.position.x = float('nan')
    cov = np.array(msg.detections[1].results[0].pose.covariance).reshape(6, 6)
    cov[0, 0] = -1.0
    msg.detections[1].results[0].pose.covariance = cov.ravel().tolist()
    msg.detections[2].results[0].hypothesis.class_id = 'leaf'
    positions, _, _, _, refused = read_detections(msg)
    assert len(positions) == 1 and len(refused) == 3
    assert 'not finite' in refused[0] and 'positive semi-definite' in refused[1] and '"apple"' in refused[2]


@pytest.mark.parametrize('n', [0, 1, 7])
def test_the_bytes_written_directly_are_the_message_the_middleware_writes(n):
    from rclpy.serialization import deserialize_message

    from picking_common.vision import cdr_agrees, detections_cdr
    from vision_msgs.msg import Detection3DArray
    rng = np.random.default_rng(n)
    dets = [Detection(rng.normal(size=3), float(rng.uniform(0.05, 0.1)), float(rng.uniform()), 0.003 * (i + 1), i)
            for i in range(n)]
    frame, stamp = 'arm2/camera_optical_frame' [:n + 10], 1_700_000_123_000_000_007
    ours = deserialize_message(detections_cdr(dets, frame, stamp), Detection3DArray)
    assert ours == detections_msg(dets, frame, stamp)
    assert cdr_agrees()
