"""Apple detections as vision_msgs/Detection3DArray, and back (class "apple", the centre with its covariance,
the diameter as the box's size)."""

from __future__ import annotations

import numpy as np

CLASS = 'apple'


def detections_msg(detections, frame, stamp_ns):
    """A Detection3DArray of ``detections`` (picking_core.camera.Detection, in ``frame``) stamped ``stamp_ns``
    (the capture time)."""
    from vision_msgs.msg import Detection3D, Detection3DArray, ObjectHypothesisWithPose

    msg = Detection3DArray()
    msg.header.frame_id = frame
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(stamp_ns), 1_000_000_000)
    for d in detections:
        det = Detection3D()
        det.header = msg.header
        hyp = ObjectHypothesisWithPose()
        hyp.hypothesis.class_id, hyp.hypothesis.score = CLASS, float(d.score)
        x, y, z = (float(v) for v in d.position)
        hyp.pose.pose.position.x, hyp.pose.pose.position.y, hyp.pose.pose.position.z = x, y, z
        cov = np.zeros((6, 6))
        cov[:3, :3] = np.eye(3) * d.sigma ** 2
        cov[3:, 3:] = np.eye(3) * 1e3                  # the orientation is not measured
        hyp.pose.covariance = cov.ravel().tolist()
        det.results.append(hyp)
        det.bbox.center = hyp.pose.pose
        det.bbox.size.x = det.bbox.size.y = det.bbox.size.z = float(d.diameter)
        msg.detections.append(det)
    return msg


def read_detections(msg):
    """``(positions (N, 3), covariances (N, 3, 3), diameters (N,), scores (N,), refused)`` of the apples in
    ``msg`` (in its header's frame); ``refused`` lists why each detection left out was (not an apple, a
    position that is not finite, a covariance that is not symmetric positive semi-definite)."""
    positions, covariances, diameters, scores, refused = [], [], [], [], []
    for k, det in enumerate(msg.detections):
        hyp = next((r for r in det.results if r.hypothesis.class_id == CLASS), None)
        if hyp is None:
            refused.append(f'detection {k}: no "{CLASS}" hypothesis')
            continue
        p = hyp.pose.pose.position
        position = np.array([p.x, p.y, p.z], float)
        cov = np.array(hyp.pose.covariance, float).reshape(6, 6)[:3, :3]
        if not np.all(np.isfinite(position)):
            refused.append(f'detection {k}: its position is not finite')
            continue
        if not np.all(np.isfinite(cov)) or not np.allclose(cov, cov.T, atol=1e-12) or \
                np.linalg.eigvalsh(cov).min() < -1e-12:
            refused.append(f'detection {k}: its position covariance is not symmetric positive semi-definite')
            continue
        positions.append(position)
        covariances.append(cov)
        diameters.append(max(det.bbox.size.x, det.bbox.size.y, det.bbox.size.z))
        scores.append(hyp.hypothesis.score)
    return (np.array(positions, float).reshape(-1, 3), np.array(covariances, float).reshape(-1, 3, 3),
            np.array(diameters, float), np.array(scores, float), refused)
