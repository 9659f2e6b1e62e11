"""Frames: /tf and /tf_static from the arm, goals in any frame /tf knows, and the arm live through Foxglove."""

import asyncio
import json
import struct
import time

import numpy as np
import pytest
from geometry_msgs.msg import PoseStamped, TransformStamped
from rclpy.serialization import deserialize_message
from rosstack import ARM, DOWN, make_pose, reach, settles_at, shared_stack
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import JointState
from tf2_msgs.msg import TFMessage

from picking_common.status import status_values
from picking_common.tf import TF_STATIC_QOS, FrameListener

NS = '/frames'
PORT = 8795
#: The camera on a mast: 0.3 m ahead of the base, 0.8 m up, looking back down at the tree (a turn of 150
#: degrees about z and 20 about x).
CAMERA = ([0.3, -0.2, 0.8], Rotation.from_euler('zx', [150, 20], degrees=True).as_quat())


@pytest.fixture(scope='module')
def arm(tmp_path_factory):
    with shared_stack(NS, tmp_path_factory.mktemp('logs'), foxglove=PORT) as (stack, client):
        yield stack, client


def static_camera(client, parent='frames/base_link', child='camera', where=CAMERA, stamp=None):
    """Publish the camera's mount on /tf_static (a transient-local publisher kept on the client)."""
    pub = client.create_publisher(TFMessage, '/tf_static', TF_STATIC_QOS)
    tf = TransformStamped()
    tf.header.frame_id, tf.child_frame_id = parent, child
    if stamp is not None:
        tf.header.stamp = stamp
    t, q = tf.transform.translation, tf.transform.rotation
    t.x, t.y, t.z = map(float, where[0])
    q.x, q.y, q.z, q.w = map(float, where[1])
    pub.publish(TFMessage(transforms=[tf]))
    client.keep = getattr(client, 'keep', []) + [pub]
    return pub


def tool_from_tf(frames, base='frames/base_link'):
    return frames.transform(base, 'frames/tool0', 0.0, 2.0)


def test_the_arms_links_are_on_tf_and_the_tool_frame_is_its_fk(arm):
    _, client = arm
    frames = FrameListener(client, prefer='picking_core')
    try:
        client.wait_for(lambda: 'frames/tool0' in frames.frames(), 10.0, 'tool0 on /tf_static')
        T = tool_from_tf(frames)
        q = client.last_positions()[:6]
        assert np.abs(T[:3, 3] - ARM.fk(q)[:3, 3]).max() < 1e-4
    finally:
        client.retire(frames)


def test_a_pose_goal_in_a_camera_frame_lands_where_the_same_goal_in_base_link_does(arm):
    """The camera frame is offset and turned from base_link: the goal is given in it, and the tool ends where the
    same goal given in base_link puts it (within 0.1 mm, read from /tf)."""
    _, client = arm
    static_camera(client)
    frames = FrameListener(client, prefer='picking_core')
    try:
        client.wait_for(lambda: 'camera' in frames.frames(), 10.0, 'the camera on /tf_static')
        target = np.eye(4)
        target[:3, :3] = Rotation.from_quat(DOWN).as_matrix()
        target[:3, 3] = [0.58, 0.12, 0.42]
        in_camera = frames.transform('camera', 'frames/base_link') @ target
        msg = PoseStamped(pose=make_pose(in_camera[:3, 3].tolist(),
                                         Rotation.from_matrix(in_camera[:3, :3]).as_quat().tolist()))
        msg.header.frame_id = 'camera'
        msg.header.stamp = client.get_clock().now().to_msg()
        reach(client, lambda: client.send(client.pub_pose, msg))
        settles_at(client, target[:3, 3].tolist(), tolerance=1e-3, timeout=10.0)
        from_camera = tool_from_tf(frames)
        client.send_pose(target[:3, 3].tolist())
        reach(client, lambda: client.send_pose(target[:3, 3].tolist()))
        from_base = tool_from_tf(frames)
        assert np.abs(from_camera[:3, 3] - from_base[:3, 3]).max() < 1e-4
        assert np.abs(from_camera[:3, :3] - from_base[:3, :3]).max() < 1e-3
    finally:
        client.retire(frames)


@pytest.mark.parametrize('frame, why', [('nowhere', "frame 'nowhere' does not exist"),
                                        ('island', 'are not in one tree')])
def test_a_goal_in_a_frame_tf_cannot_reach_is_refused_naming_the_frames(arm, frame, why):
    _, client = arm
    static_camera(client, 'reef', 'island', ([0, 0, 1], [0, 0, 0, 1]))
    mark = client.mark()
    msg = PoseStamped(pose=make_pose([0.58, 0.1, 0.45], DOWN))
    msg.header.frame_id = frame
    msg.header.stamp = client.get_clock().now().to_msg()
    client.send(client.pub_pose, msg)
    answer = client.planner_answer(mark)
    values = status_values(answer)
    assert values['state'] == 'refused' and f"goal in frame '{frame}'" in answer.message and why in answer.message
    assert 'base_link' in answer.message


def test_a_transform_that_is_not_one_is_not_taken_and_a_goal_in_its_frame_is_refused(arm):
    stack, client = arm
    static_camera(client, 'frames/base_link', 'broken', ([float('nan'), 0, 0], [0, 0, 0, 1]))
    mark = client.mark()
    msg = PoseStamped(pose=make_pose([0.58, 0.1, 0.45], DOWN))
    msg.header.frame_id = 'broken'
    client.send(client.pub_pose, msg)
    answer = client.planner_answer(mark)
    assert status_values(answer)['state'] == 'refused' and "'broken'" in answer.message
    assert stack.planner.alive()


def test_foxglove_shows_the_arm_the_tool_from_tf_is_the_fk_of_the_joint_states(arm):
    """A Foxglove client (the WebSocket protocol: advertise, subscribe, binary message data) subscribes to /tf,
    /tf_static and joint_states: the tool frame it computes from /tf is the FK of the joint states of the same
    stamp within 0.1 mm. A client that leaves mid-stream changes nothing for the arm."""
    stack, client = arm
    got = asyncio.run(_foxglove_client(['/tf', '/tf_static', f'{NS}/joint_states'], seconds=3.0))
    assert got['/tf'] and got['/tf_static'] and got[f'{NS}/joint_states'], {k: len(v) for k, v in got.items()}
    links = {}
    for data in got['/tf_static']:
        for tf in deserialize_message(data, TFMessage).transforms:
            links[tf.child_frame_id] = (tf.header.frame_id, _matrix(tf.transform), None)
    by_stamp = {}
    for data in got['/tf']:
        for tf in deserialize_message(data, TFMessage).transforms:
            key = (tf.header.stamp.sec, tf.header.stamp.nanosec)
            by_stamp.setdefault(key, {})[tf.child_frame_id] = (tf.header.frame_id, _matrix(tf.transform))
    states = {(m.header.stamp.sec, m.header.stamp.nanosec): m
              for m in (deserialize_message(d, JointState) for d in got[f'{NS}/joint_states'])}
    compared = 0
    for stamp, moving in by_stamp.items():
        if stamp not in states or len(moving) < 6:
            continue
        tree = {child: (parent, T) for child, (parent, T, _) in links.items()} | moving
        frame, T = 'frames/tool0', np.eye(4)
        while frame != 'frames/base_link':
            parent, T_link = tree[frame]
            T, frame = T_link @ T, parent
        q = dict(zip(states[stamp].name, states[stamp].position))
        fk = ARM.fk(np.array([q[n] for n in ARM.joint_names]))
        assert np.abs(T[:3, 3] - fk[:3, 3]).max() < 1e-4
        compared += 1
    assert compared >= 10
    assert stack.controller.alive() and stack.planner.alive()


def _matrix(transform):
    T = np.eye(4)
    r, t = transform.rotation, transform.translation
    T[:3, :3] = Rotation.from_quat([r.x, r.y, r.z, r.w]).as_matrix()
    T[:3, 3] = [t.x, t.y, t.z]
    return T


async def _foxglove_client(topics, seconds):
    """Connect as Foxglove does, subscribe to ``topics`` and return ``{topic: [CDR bytes]}`` heard in ``seconds``."""
    import websockets
    got = {t: [] for t in topics}
    async with websockets.connect(f'ws://127.0.0.1:{PORT}', subprotocols=['foxglove.sdk.v1', 'foxglove.websocket.v1'],
                                  max_size=None) as ws:
        channels, subscribed, end = {}, {}, time.monotonic() + seconds + 10.0
        while time.monotonic() < end:
            try:
                frame = await asyncio.wait_for(ws.recv(), 1.0)
            except asyncio.TimeoutError:
                continue
            if isinstance(frame, str):
                msg = json.loads(frame)
                if msg.get('op') == 'advertise':
                    for ch in msg['channels']:
                        channels[ch['topic']] = ch
                    new = [t for t in topics if t in channels and t not in subscribed]
                    for t in new:
                        subscribed[t] = len(subscribed) + 1
                    if new:
                        await ws.send(json.dumps({'op': 'subscribe', 'subscriptions': [
                            {'id': subscribed[t], 'channelId': channels[t]['id']} for t in new]}))
                        if len(subscribed) == len(topics):
                            end = time.monotonic() + seconds
                continue
            if frame[0] == 0x01:                  # message data: sub id u32, log time u64, payload
                sub_id, = struct.unpack_from('<I', frame, 1)
                topic = next(t for t, i in subscribed.items() if i == sub_id)
                got[topic].append(bytes(frame[13:]))
    return got
