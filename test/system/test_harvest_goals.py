"""A tree harvested end to end on one arm, as picking-stack starts it (the shipped files)."""

import os
import signal
import time

import numpy as np
import pytest
import yaml
from geometry_msgs.msg import PoseArray
from rosstack import ARM, BURST, RELIABLE, Client, ensure_rclpy, make_pose
from trajectory_msgs.msg import JointTrajectory

from picking_bringup.shipped import config_dir
from picking_common.status import stamp_key, status_values
from picking_core.harvest import synthetic_tree
from picking_core.pick_cycle import PickSettings

NS = '/harvest'
FINAL = ('succeeded', 'refused', 'aborted', 'superseded', 'canceled')
BOX = np.array(yaml.safe_load((config_dir() / 'pick_cycle.yaml').read_text())
               ['/**/picking_planner']['ros__parameters']['box_position'])


@pytest.fixture(scope='module')
def arm(tmp_path_factory):
    from picking_bringup.stack import Stack as Launcher
    ensure_rclpy()
    stack = Launcher(NS, tmp_path_factory.mktemp('logs'))
    client = Client(NS)
    trajectories = []
    client.create_subscription(JointTrajectory, 'planned_trajectory', trajectories.append, RELIABLE)
    client.pub_harvest = client.create_publisher(PoseArray, 'harvest_targets', BURST)
    try:
        stack.wait_ready()
        client.wait_ready()
        yield stack, client, trajectories
    finally:
        codes = stack.stop()
        client.close()
    assert set(codes.values()) == {0}, codes


def tree_msg(client, poses):
    from scipy.spatial.transform import Rotation
    msg = PoseArray(poses=[make_pose(T[:3, 3], Rotation.from_matrix(T[:3, :3]).as_quat()) for T in poses])
    msg.header.frame_id, msg.header.stamp = 'base_link', client.get_clock().now().to_msg()
    return msg


def statuses(client, key):
    """The statuses of goal ``key`` (call with the client's lock held: wait_for holds it for its predicate)."""
    return [status_values(m) | {'message': m.message} for _, m in client.planner_status
            if status_values(m).get('goal') == key]


def final(client, key, timeout):
    return client.wait_for(lambda: next((s for s in statuses(client, key) if s.get('state') in FINAL), None),
                           timeout, f'the end of harvest {key}')


def first_apple_in_the_box(client, apples):
    """Send a harvest of ``apples``; return its id once its first apple is in the box."""
    tree = tree_msg(client, apples)
    key = stamp_key(tree.header.stamp)
    since = client.mark()
    client.send(client.pub_harvest, tree)
    client.planner_answer(since, timeout=30.0)
    client.wait_for(lambda: any(s.get('apple_state') == 'picked' for s in statuses(client, key)), 30.0,
                    'the first apple in the box')
    return key


def arm_at(client, q):
    """True when the newest joint_states put the arm within 1 mrad of ``q`` (lock held)."""
    msg = client.states[-1][1]
    names = list(msg.name)
    return np.abs(np.array([msg.position[names.index(n)] for n in ARM.joint_names]) - q).max() < 1e-3


def tool_at(q):
    return ARM.fk(np.asarray(q)[:6])[:3, 3]


def test_the_cli_harvests_a_small_tree_box_to_next_apple_and_skips_what_it_cannot_reach(arm, run_tool, tmp_path):
    stack, client, trajectories = arm
    apples = [T[:3, 3].tolist() for T in synthetic_tree(3, seed=5)]
    tree = tmp_path / 'tree.yaml'
    tree.write_text(yaml.safe_dump([*apples[:1], [2.5, 0.0, 0.6], *apples[1:]]))
    seen = len(trajectories)
    done = run_tool('picking-goal', 'harvest', '--file', tree, '--ros-args', '-r', f'__ns:={NS}', timeout=180)
    assert done.returncode == 0, done.stdout + done.stderr
    out = done.stdout
    assert 'apple 1 skipped: unreachable' in out
    assert out.count(' picked: in the box ') == 3
    assert '3 of 3 apples picked, 1 skipped' in out and 'apples/h' in out
    key = out.split('goal ')[1].split()[0]
    end = final(client, key, 5.0)
    assert end['state'] == 'succeeded' and end['picked'] == '3' and end['skipped_apples'] == '1'
    assert sorted(end['picked_apples'].split()) == ['0', '2', '3']
    # One plan: home only at its ends; in between, after each release, the arm left the box for the next apple.
    plan = trajectories[seen]
    q = np.array([p.positions for p in plan.points])
    home = np.array(PickSettings().home_positions)
    at_home = np.abs(q[:, :6] - home).max(axis=1) < 1e-3
    assert at_home[-1] and not at_home[len(q) // 5:-len(q) // 5].any()
    in_box = np.linalg.norm([tool_at(x) - BOX for x in q], axis=1) < 2e-3
    visits = np.flatnonzero(np.diff(in_box.astype(int)) == 1)
    assert len(visits) == 3
    # The arm came back home, at rest, with nothing limited on the way.
    client.wait_for(lambda: arm_at(client, home), 10.0, 'the arm home')
    with client.lock:
        assert not [m.message for _, m in client.controller_status if 'command limited' in m.message]


def replace_tree(stack, client, trajectories, key):
    """Send a new tree of two apples while harvest ``key`` (four apples) runs: the running one ends
    superseded with the apples in the box by then, the new one is planned once, begins at rest in
    the box after the apple in hand (dropped: the gripper open) and picks both."""
    seen = len(trajectories)
    second = tree_msg(client, synthetic_tree(2, seed=8))
    plans = stack.planner.output().count('harvest goal: harvest,')
    client.send(client.pub_harvest, second)
    for _ in range(3):                   # sent again while the planner plans it: the same goal, planned once
        time.sleep(0.2)
        client.pub_harvest.publish(second)
    replaced = final(client, key, 30.0)
    assert replaced['state'] == 'superseded' and 1 <= int(replaced['picked']) < 4, replaced
    done = final(client, stamp_key(second.header.stamp), 60.0)
    assert done['state'] == 'succeeded' and done['picked'] == '2', done
    # Planned once however often it came; again only when its plan came too late (one
    # planned before the feedback of a stall that came meanwhile: a loaded machine's controller stalls).
    log = stack.planner.output()
    late = log.count(f'harvest goal {stamp_key(second.header.stamp)}: its plan came too late')
    assert log.count('harvest goal: harvest,') == plans + 1 + late
    plan = trajectories[seen]
    start = np.array(plan.points[0].positions)
    assert np.linalg.norm(tool_at(start) - BOX) < 2e-3 and not np.any(plan.points[0].velocities)
    assert start[plan.joint_names.index('gripper_joint')] == pytest.approx(PickSettings().gripper_open)
    with client.lock:
        assert not [m.message for _, m in client.controller_status if 'command limited' in m.message]


def test_a_new_tree_while_harvesting_replaces_the_apples_not_started_after_the_apple_in_hand(arm):
    stack, client, trajectories = arm
    replace_tree(stack, client, trajectories, first_apple_in_the_box(client, synthetic_tree(4, seed=6)))


def test_a_new_tree_after_the_controller_stalled_still_starts_in_the_box_after_the_apple_in_hand(arm):
    """A stalled controller runs the harvest later than planned (it delays its trajectory rather
    than jump): its feedback tells the planner, which plans the new tree from the box where the
    delayed harvest will be, seconds ahead, not from the reference extrapolated (a tree that
    comes before that feedback waits for it)."""
    stack, client, trajectories = arm
    key = first_apple_in_the_box(client, synthetic_tree(4, seed=6))
    mark = client.mark()
    os.kill(stack.controller.pid, signal.SIGSTOP)
    time.sleep(0.4)
    os.kill(stack.controller.pid, signal.SIGCONT)
    client.wait_for(lambda: any('control loop stalled' in m.message for _, m in client.controller_status[
        mark['controller']:]), 10.0, 'the controller to report its stall')
    replace_tree(stack, client, trajectories, key)     # (perhaps before its feedback: the goal waits for it)


def test_a_harvest_stopped_mid_way_says_which_apples_are_in_the_box_and_which_one_failed(arm, run_tool):
    stack, client, _ = arm
    key = first_apple_in_the_box(client, synthetic_tree(4, seed=12))
    time.sleep(1.0)                                       # into the second apple's cycle
    stopped = run_tool('picking-goal', 'stop', '--ros-args', '-r', f'__ns:={NS}')
    assert stopped.returncode == 0, stopped.stdout + stopped.stderr
    end = final(client, key, 20.0)
    # (picking-goal takes a couple of seconds to start and discover the controller: an apple or two more may be in.)
    assert end['state'] == 'canceled' and 1 <= int(end['picked']) < 4, end
    with client.lock:
        failed = [s for s in statuses(client, key) if s.get('apple_state') == 'failed']
    assert len(failed) == 1 and 'canceled during its cycle' in failed[0]['message'], failed
    assert failed[0]['apple'] not in end['picked_apples'].split()
