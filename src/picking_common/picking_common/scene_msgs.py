"""The scene and the canopy as ROS messages: visualization_msgs/MarkerArray and sensor_msgs/PointCloud2.

A scene on the ``scene`` topic is a MarkerArray that RViz and Foxglove draw as it is: each
CYLINDER in namespace ``branches`` is a branch (a capsule as wide as the cylinder), in ``wires``
a wire (a cylinder), each CUBE in ``boxes`` a box, and a CUBE in ``ground`` the ground (everything
below its top face). A marker's ``text`` names it (else ``<ns> <id>``). The canopy is a
PointCloud2 with float32 fields x, y, z.
"""

from __future__ import annotations

import numpy as np
from geometry_msgs.msg import Point, Pose, Quaternion, Vector3
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray

from picking_core.collision import Scene
from picking_core.collision.scene import box, ground, rod

#: Marker namespaces of a scene and what each holds.
NAMESPACES = {'branches': 'branch', 'wires': 'wire', 'boxes': 'box', 'ground': 'ground'}
COLOURS = {'branch': (0.45, 0.3, 0.15, 1.0), 'wire': (0.6, 0.6, 0.6, 1.0), 'box': (0.3, 0.5, 0.8, 0.6),
           'ground': (0.3, 0.55, 0.3, 0.4)}
#: m: the ground drawn as a slab this wide and thick.
GROUND_SIZE = (4.0, 4.0, 0.02)


def _pose_matrix(pose):
    T = np.eye(4)
    q = pose.orientation
    norm = np.linalg.norm([q.x, q.y, q.z, q.w])
    T[:3, :3] = Rotation.from_quat([q.x, q.y, q.z, q.w] if norm > 0 else [0, 0, 0, 1]).as_matrix()
    T[:3, 3] = [pose.position.x, pose.position.y, pose.position.z]
    return T


def in_frame(frame):
    """An ``in_base`` for :func:`scene_from_markers` and :func:`cloud_points` that knows no other frame than
    ``frame`` (or none given): the identity, or ValueError naming the frame."""
    def in_base(header):
        if header.frame_id.lstrip('/') not in ('', frame):
            raise ValueError(f'frame {header.frame_id!r} is not {frame!r} (no transform to it is known here)')
        return np.eye(4)
    return in_base


def scene_from_markers(msg, in_base):
    """The :class:`Scene` of a MarkerArray in the arm's base frame: ``in_base(header)`` is the 4x4 transform of a
    marker's frame into it (ValueError naming the frames when there is none); ValueError naming the marker that
    cannot be read."""
    obstacles = []
    for m in msg.markers:
        if m.action == Marker.DELETEALL:
            obstacles = []
            continue
        if m.action != Marker.ADD:
            continue
        where = f'marker {m.ns!r} {m.id}'
        kind = NAMESPACES.get(m.ns)
        if kind is None:
            raise ValueError(f'{where}: namespace must be one of {", ".join(NAMESPACES)}')
        try:
            T = in_base(m.header) @ _pose_matrix(m.pose)
        except ValueError as exc:
            raise ValueError(f'{where}: {exc}') from None
        name = m.text or f'{m.ns} {m.id}'
        s = np.array([m.scale.x, m.scale.y, m.scale.z])
        if kind in ('branch', 'wire'):
            if m.type != Marker.CYLINDER:
                raise ValueError(f'{where}: a {kind} is a CYLINDER marker')
            half = T[:3, 2] * s[2] / 2
            obstacles.append(rod(name, kind, T[:3, 3] - half, T[:3, 3] + half, max(s[0], s[1]) / 2))
        elif m.type != Marker.CUBE:
            raise ValueError(f'{where}: a {kind} is a CUBE marker')
        elif kind == 'box':
            obstacles.append(box(name, T[:3, 3], s, Rotation.from_matrix(T[:3, :3]).as_euler('xyz')))
        else:
            obstacles.append(ground(T[2, 3] + s[2] / 2))
    return Scene().merged(obstacles, 'the scene topic')


def take_scene(msg, in_base, logger):
    """The :class:`Scene` of a ``scene`` message (``in_base`` as for :func:`scene_from_markers`), or None after
    logging why it was refused (the node keeps its old scene)."""
    try:
        return scene_from_markers(msg, in_base)
    except ValueError as exc:
        logger.error(f'scene refused, the old one kept: {exc}')
        return None


def scene_markers(scene, frame, stamp=None):
    """A MarkerArray drawing ``scene`` (read back by :func:`scene_from_markers`)."""
    out = MarkerArray()
    out.markers.append(Marker(action=Marker.DELETEALL, header=Header(frame_id=frame)))
    for i, o in enumerate(scene.obstacles):
        m = Marker(header=Header(frame_id=frame), id=i, action=Marker.ADD, text=o.name,
                   color=ColorRGBA(**dict(zip('rgba', map(float, COLOURS[o.kind])))))
        if stamp is not None:
            m.header.stamp = stamp
        m.ns = next(ns for ns, kind in NAMESPACES.items() if kind == o.kind)
        T, size = o.pose, None
        if o.kind in ('branch', 'wire'):
            m.type, size = Marker.CYLINDER, (2 * o.radius, 2 * o.radius, float(np.linalg.norm(o.ends[1] - o.ends[0])))
        elif o.kind == 'box':
            m.type, size = Marker.CUBE, tuple(o.size)
        else:
            m.type, size = Marker.CUBE, GROUND_SIZE
            T = np.eye(4)
            T[2, 3] = o.hi[2] - GROUND_SIZE[2] / 2
        x, y, z, w = Rotation.from_matrix(T[:3, :3]).as_quat()
        m.pose = Pose(position=Point(x=float(T[0, 3]), y=float(T[1, 3]), z=float(T[2, 3])),
                      orientation=Quaternion(x=float(x), y=float(y), z=float(z), w=float(w)))
        m.scale = Vector3(x=float(size[0]), y=float(size[1]), z=float(size[2]))
        out.markers.append(m)
    return out


def cloud_points(msg, in_base):
    """The (N, 3) points of a PointCloud2 with float32 x, y, z, in the arm's base frame (``in_base(header)``: the
    4x4 transform of the cloud's frame into it); ValueError otherwise (finite points only are kept)."""
    T = in_base(msg.header)
    fields = {f.name: f for f in msg.fields}
    if not all(k in fields and fields[k].datatype == PointField.FLOAT32 for k in 'xyz'):
        raise ValueError('canopy_points needs float32 fields x, y and z')
    n = msg.width * msg.height
    dtype = np.dtype({'names': list('xyz'), 'formats': ['<f4' if not msg.is_bigendian else '>f4'] * 3,
                      'offsets': [fields[k].offset for k in 'xyz'], 'itemsize': msg.point_step})
    if msg.height > 1 and msg.row_step != msg.width * msg.point_step:
        rows = np.frombuffer(bytes(msg.data), np.uint8).reshape(msg.height, msg.row_step)[:, :msg.width * msg.point_step]
        data = np.ascontiguousarray(rows).tobytes()
    else:
        data = bytes(msg.data)[:n * msg.point_step]
    points = np.frombuffer(data, dtype, count=n)
    xyz = np.stack([points['x'], points['y'], points['z']], axis=1).astype(float)
    xyz = xyz[np.all(np.isfinite(xyz), axis=1)]
    return xyz @ T[:3, :3].T + T[:3, 3]


def cloud_message(points, frame, stamp=None):
    """A PointCloud2 of the (N, 3) ``points`` (float32 x, y, z; unordered, dense)."""
    points = np.asarray(points, np.float32).reshape(-1, 3)
    msg = PointCloud2(header=Header(frame_id=frame), height=1, width=len(points), is_bigendian=False,
                      point_step=12, row_step=12 * len(points), is_dense=True)
    if stamp is not None:
        msg.header.stamp = stamp
    msg.fields = [PointField(name=k, offset=4 * i, datatype=PointField.FLOAT32, count=1) for i, k in enumerate('xyz')]
    msg.data = points.tobytes()
    return msg
