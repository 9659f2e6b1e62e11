"""Re-targets: a running goal's target moved at camera rate, each update planned from the running plan and spliced on
at the controller, or replaced by a newer one; the arm ends at the last target within every limit."""

import time

import numpy as np
import pytest
from geometry_msgs.msg import PoseStamped
from rosstack import ARM, BURST, DOWN, make_pose, settles_at, shared_stack

from picking_common.status import status_values
from picking_core.goals.intake import ZERO_KEY
from picking_core.goals.runner import STREAM_PAUSE

NS = '/retarget'
RATE = 30.0
SECONDS = 10.0
CENTRE = np.array([0.6, 0.05, 0.45])


@pytest.fixture(scope='module')
def arm(tmp_path_factory):
    with shared_stack(NS, tmp_path_factory.mktemp('logs')) as (stack, client):
        yield stack, client


def circle(k):
    """The k-th target: a point going round a 5 cm circle once every 2 s."""
    a = 2 * np.pi * k / (2 * RATE)
    return CENTRE + 0.05 * np.array([0.0, np.cos(a), np.sin(a)])


@pytest.mark.load
def test_a_30_hz_stream_of_retargets_is_spliced_or_replaced_and_the_arm_ends_at_the_last(arm):
    stack, client = arm
    client.watch_commands()
    retarget = client.create_publisher(PoseStamped, 'retarget', BURST)
    client.wait_for(lambda: retarget.get_subscription_count() > 0, 10.0, 'the planner on retarget')
    mark = client.mark()
    goal = client.send_pose(circle(0).tolist())
    key = f'{goal.header.stamp.sec}.{goal.header.stamp.nanosec:09d}'
    client.planner_answer(mark)
    sent, start, times = 0, time.monotonic(), []
    while time.monotonic() - start < SECONDS:
        sent += 1
        msg = PoseStamped(pose=make_pose(circle(sent).tolist(), DOWN))
        msg.header.frame_id = 'base_link'
        retarget.publish(msg)
        times.append(time.monotonic())
        time.sleep(max(0.0, start + sent / RATE - time.monotonic()))
    end = client.wait_for(lambda: [status_values(m) for _, m in client.planner_status[mark['planner']:]
                                   if status_values(m).get('goal') == key
                                   and status_values(m).get('state') in ('succeeded', 'aborted', 'refused')],
                          40.0, 'the goal to end')[0]
    assert end['state'] == 'succeeded', end
    # Every update was taken: spliced on, or replaced by a newer one before it was planned; none refused. How
    # many are spliced depends on how fast the machine plans (a loaded one replaces more): a good share is.
    counts = {k: int(end[f'retargets_{k}']) for k in ('received', 'spliced', 'replaced', 'refused')}
    # A host that stalls this test's own publisher longer than the planner's stream pause has paused the stream:
    # the goal then ends at rest, every update sent before the pause taken (but the last: it may leave the stalled
    # sender's DDS threads only after the pause), the later ones answered "not taken".
    gaps = np.diff(times)
    paused = int(np.argmax(gaps)) if gaps.max() > STREAM_PAUSE else sent
    assert paused <= counts['received'] <= sent and counts['refused'] == 0, (counts, f'paused after {paused + 1}')
    last = counts['received']
    assert counts['spliced'] + counts['replaced'] == last and counts['spliced'] >= last // 10, counts
    settles_at(client, circle(last).tolist(), tolerance=1e-3, timeout=10.0)
    # The reference stayed within the limits throughout, and the controller never had to limit it.
    with client.lock:
        commands = [m for _, m in client.commands[mark['commands']:]]
        limited = [m.message for _, m in client.controller_status[mark['controller']:] if 'limited' in m.message]
        taken = [m.message for _, m in client.controller_status[mark['controller']:] if 'accepted' in m.message]
    velocity = np.abs(np.array([m.velocity[:6] for m in commands]))
    acceleration = np.abs(np.array([m.effort[:6] for m in commands]))
    assert (velocity <= ARM.max_velocity * (1 + 1e-6)).all() and (acceleration <= ARM.max_acceleration * (1 + 1e-6)).all()
    assert not limited, limited[:3]
    # Each plan carries on from the running one exactly, or, where the planner's start was not the controller's
    # (a plan it had to put at its reference, now), is bridged to within the limits; nothing else.
    assert taken and all('carries on from the reference' in m or 'bridged from the reference' in m for m in taken), \
        [m for m in taken if 'carries' not in m and 'bridged' not in m][:3]
    assert key != ZERO_KEY
