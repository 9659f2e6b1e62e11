"""Apple detections as vision_msgs/Detection3DArray, and back (class "apple", the centre with its covariance,
the diameter as the box's size).

A camera publishes a frame of detections many times a second: :func:`detections_cdr` writes its CDR bytes straight
(as :mod:`picking_common.cdr` does for the joint states), where :func:`cdr_agrees` finds the middleware reads them as
the message :func:`detections_msg` builds; elsewhere the message itself is published."""

from __future__ import annotations

import functools
import struct

import numpy as np

from .cdr import _STAMP, _Writer

CLASS = 'apple'
#: m^2: the orientation's variance (it is not measured).
UNMEASURED = 1e3
_F8 = struct.Struct('<d')


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
        cov[3:, 3:] = np.eye(3) * UNMEASURED
        hyp.pose.covariance = cov.ravel().tolist()
        det.results.append(hyp)
        det.bbox.center = hyp.pose.pose
        det.bbox.size.x = det.bbox.size.y = det.bbox.size.z = float(d.diameter)
        msg.detections.append(det)
    return msg


def detections_cdr(detections, frame, stamp_ns):
    """The CDR bytes of :func:`detections_msg`'s message, written directly."""
    stamp = _STAMP.pack(*divmod(int(stamp_ns), 1_000_000_000))
    w = _Writer()
    w.buf += stamp
    w.string(frame)
    w.u32(len(detections))
    cov = np.zeros(36, '<f8')
    cov[21] = cov[28] = cov[35] = UNMEASURED
    for d in detections:
        w.align(4)
        w.buf += stamp
        w.string(frame)
        w.u32(1)                                       # one hypothesis: an apple
        w.string(CLASS)
        w.align(8)
        w.buf += _F8.pack(float(d.score))
        pose = np.array([*d.position, 0.0, 0.0, 0.0, 1.0], '<f8').tobytes()
        cov[0] = cov[7] = cov[14] = d.sigma ** 2
        w.buf += pose + cov.tobytes() + pose + np.full(3, float(d.diameter), '<f8').tobytes()
        w.string('')                                   # id: none
    return bytes(w.buf)


@functools.cache
def cdr_agrees():
    """True when the middleware reads :func:`detections_cdr`'s bytes as the message :func:`detections_msg`
    builds (then a publisher may send the bytes)."""
    from rclpy.serialization import deserialize_message

    from picking_core.camera import Detection
    from vision_msgs.msg import Detection3DArray

    sample = [Detection(np.array([0.1, -0.2, 0.9]), 0.075, 0.9, 0.003, 0),
              Detection(np.array([1.5, 0.25, 2.0]), 0.06, 0.42, 0.01, -1)]
    try:
        ours = deserialize_message(detections_cdr(sample, 'a/camera', 1_700_000_000_123_456_789), Detection3DArray)
    except Exception:  # noqa: BLE001 - bytes it cannot read: do not send them
        return False
    # (Compared as messages: the middleware's serialiser leaves its padding bytes as they were.)
    return ours == detections_msg(sample, 'a/camera', 1_700_000_000_123_456_789)


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
