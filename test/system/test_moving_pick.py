"""A swaying apple picked from a stream of its stamped places on ``pick_target`` (a camera's, at 30 Hz): the stream
moves one pick on, the planner fits the sway from the stamps and closes the fingers where the apple is then, as the
arm's own joint_states show."""

import time

import numpy as np
from geometry_msgs.msg import PoseStamped
from rosstack import ARM, ARM_JOINTS, FINAL, make_pose, running_stack
from scipy.spatial.transform import Rotation

from picking_common.status import stamp_key, status_values
from picking_core.harvest import SIDEWAYS
from picking_core.moving_pick import APPLE_WIDTH

RATE, SECONDS = 30.0, 3.0
GRASP = Rotation.from_euler('xyz', SIDEWAYS).as_quat()


def swaying(t):
    """The apple at ``t`` s (ROS time): ±30 mm at 1 Hz across the approach."""
    return np.array([0.70, 0.15 + 0.03 * np.sin(2 * np.pi * t), 0.65])


def test_a_pick_streamed_at_camera_rate_closes_where_the_swaying_apple_is(tmp_path):
    with running_stack('/moving', tmp_path) as (_, client):
        mark = client.mark()
        keys, start = [], time.monotonic()
        while time.monotonic() - start < SECONDS:
            now = client.get_clock().now()
            msg = PoseStamped(pose=make_pose(swaying(now.nanoseconds * 1e-9).tolist(), GRASP))
            msg.header.frame_id, msg.header.stamp = 'base_link', now.to_msg()
            client.pub_pick.publish(msg)
            keys.append(stamp_key(msg.header.stamp))
            time.sleep(max(0.0, start + len(keys) / RATE - time.monotonic()))

        def said(key):
            return [{**status_values(m), 'text': m.message} for _, m in client.planner_status[mark['planner']:]
                    if status_values(m).get('goal') == key]
        # (Places that queued up while the planner was busy are coalesced: the newest is taken, the older superseded.)
        first = client.wait_for(lambda: next((k for k in keys if any(v.get('state') == 'accepted' for v in said(k))),
                                             None), 20.0, 'a pick to be accepted')
        end = client.wait_for(lambda: [v for v in said(first) if v.get('state') in FINAL], 40.0, 'the pick to end')[0]
        assert end['state'] == 'succeeded', end
        # Every later place was answered as the same apple, taken as the pick's new target (or not, once its
        # straight approach had begun); none started a pick of its own.
        later = [said(k) for k in keys[keys.index(first) + 1:]]
        assert all(v and v[-1]['state'] == 'superseded' for v in later), later[:3]
        assert sum(f'pick goal {first}: taken as its new target' in v[-1]['text'] for v in later) > 10
        assert any(v.get('state') == 'accepted' and 'closes_in' in v for v in said(first)), 'no plan aimed at the sway'
        # The fingers' closing, as the arm's own joint_states show it: the first sample at the width they are timed to
        # meet; the tool there against where the apple was at that sample's stamp.
        with client.lock:
            states = [m for _, m in client.states]
        opening = np.array([m.position[list(m.name).index('gripper_joint')] for m in states])
        k = int(np.argmax(opening <= APPLE_WIDTH))
        assert opening[k] <= APPLE_WIDTH < opening[k - 1], 'the fingers never closed'
        q = np.array([states[k].position[list(states[k].name).index(j)] for j in ARM_JOINTS])
        t = states[k].header.stamp.sec + states[k].header.stamp.nanosec * 1e-9
        miss = np.linalg.norm(ARM.fk(q)[:3, 3] - swaying(t))
        # (Margin for a loaded machine: the servo's lag, and the 10 ms between joint_states in which the fingers
        # pass the width and the apple moves up to 2 mm.)
        assert miss < 0.008, miss
