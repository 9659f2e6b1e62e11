"""Branch-aware picking through the running stack, seen from outside: a scene published on the
latched ``scene`` topic puts a branch across the straight approach to an apple; the planner picks
it from another direction and the simulator, as a witness, reports no contact; with collision
checking off (the parameter service), the same pick hits the branch and the witness says so; a
pose goal whose straight move crosses the branch goes around it; a pose goal into the branch is
refused naming it; a canopy cloud is taken from ``canopy_points``, and one that comes while a pick or a
harvest runs stops it where it would now touch, or, when it blocks only a harvest's apples not started,
has them planned again around it."""

import time

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseArray, PoseStamped
from rosstack import FINAL, final_answer, make_pose, reach, running_stack
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import PointCloud2
from visualization_msgs.msg import MarkerArray

from picking_bringup.shipped import shipped_harvest
from picking_common.scene_msgs import cloud_message, scene_markers
from picking_common.status import stamp_key, status_values
from picking_common.topics import BURST, LATCHED
from picking_core.collision import Scene
from picking_core.collision.scene import rod
from picking_core.harvest import synthetic_tree
from picking_description import scene_path

#: An apple of the synthetic tree, approached along +x; a branch 8 cm in front of it and 6 cm below.
APPLE = synthetic_tree(10, seed=1)[1]
A = APPLE[:3, 3]
BRANCH = rod('low branch', 'branch', A + [-0.08, -0.4, -0.06], A + [-0.08, 0.4, -0.06], 0.015)


@pytest.fixture(scope='module')
def arm(tmp_path_factory):
    with running_stack('/col', tmp_path_factory.mktemp('logs')) as (stack, client):
        contacts = []
        client.create_subscription(DiagnosticStatus, 'sim_contacts', lambda m: contacts.append(m), BURST)
        scene = Scene.from_yaml(scene_path('workcell')).merged([BRANCH])
        pub = client.create_publisher(MarkerArray, 'scene', LATCHED)
        pub.publish(scene_markers(scene, 'base_link'))
        client.wait_for(lambda: 'scene replaced' in stack.planner.output()
                        and 'from the scene topic' in stack.sim.output(), 20.0, 'both nodes to take the scene')
        yield stack, client, contacts


def pick_msg():
    msg = PoseStamped()
    msg.header.frame_id = 'base_link'
    msg.pose = make_pose(A.tolist(), Rotation.from_matrix(APPLE[:3, :3]).as_quat().tolist())
    return msg


def started(contacts, since):
    return [status_values(m) for m in list(contacts[since:]) if status_values(m).get('state') == 'started']


def ended(contacts, since):
    return [status_values(m) for m in list(contacts[since:]) if status_values(m).get('state') == 'ended']


def test_the_planner_picks_around_a_branch_and_the_witness_sees_no_contact(arm):
    stack, client, contacts = arm
    seen = len(contacts)
    answer = reach(client, lambda: client.send(client.pub_pick, pick_msg()), timeout=60.0)
    assert 'approached' in answer.message and 'off the requested axis' in answer.message, answer.message
    assert float(status_values(answer)['approach_tilt']) > 0.0
    time.sleep(0.5)                                           # the witness looks 20 times a second
    assert started(contacts, seen) == []


def test_with_checking_off_the_same_pick_hits_the_branch_and_the_witness_says_so(arm):
    stack, client, contacts = arm
    seen = len(contacts)
    client.set_planner_parameter('avoid_collisions', False)
    try:
        reach(client, lambda: client.send(client.pub_pick, pick_msg()), timeout=60.0)
        client.wait_for(lambda: ended(contacts, seen), 5.0, 'a contact on sim_contacts')
        hit = started(contacts, seen)[0]
        assert hit['obstacle'] == 'low branch' and abs(float(hit['start']) - time.time()) < 60.0, hit   # ROS clock
        # A contact starts at the first touch; its end says how deep it went at worst.
        deepest = max(float(c['depth']) for c in ended(contacts, seen) if c['obstacle'] == 'low branch')
        assert deepest > 0.0
        assert hit['link'] in ('wrist_3_link', 'tool0', 'wrist_1_link', 'forearm_link')
    finally:
        client.set_planner_parameter('avoid_collisions', True)


def test_a_pose_goal_into_the_branch_is_refused_naming_it(arm):
    stack, client, contacts = arm
    mark = client.mark()
    client.send(client.pub_pose, pick_pose_at(BRANCH.ends.mean(axis=0)))
    answer = final_answer(client, mark)
    assert status_values(answer)['state'] == 'refused'
    assert 'would hit an obstacle' in answer.message and 'low branch' in answer.message, answer.message


def test_a_pose_goal_whose_move_crosses_the_branch_goes_around_it(arm):
    stack, client, contacts = arm
    cycle = shipped_harvest().cycle
    home = cycle.arm.fk(np.asarray(cycle.s.home_positions))
    reach(client, lambda: client.send(client.pub_pose, pose_goal(home)))
    seen = len(contacts)
    # From home, tool down, to the other side of the branch: the straight joint move sweeps the wrist across it.
    goal = np.eye(4)
    goal[:3, :3] = Rotation.from_euler('x', 180.0, degrees=True).as_matrix()
    goal[:3, 3] = [0.6, 0.4, 0.45]
    answer = reach(client, lambda: client.send(client.pub_pose, pose_goal(goal)))
    assert 'around obstacles through' in status_values(answer).get('detours', ''), answer.message
    time.sleep(0.5)
    assert started(contacts, seen) == []


def pose_goal(T):
    msg = PoseStamped()
    msg.header.frame_id = 'base_link'
    msg.pose = make_pose(T[:3, 3].tolist(), Rotation.from_matrix(T[:3, :3]).as_quat().tolist())
    return msg


def shell_around(centre, seed, radius=0.12, n=3000):
    """A cloud of ``n`` points on a sphere of ``radius`` m about ``centre``: an apple enclosed by the canopy."""
    shell = np.random.default_rng(seed).normal(size=(n, 3))
    return centre + radius * shell / np.linalg.norm(shell, axis=1)[:, None]


def pick_pose_at(xyz):
    msg = pick_msg()
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = (float(v) for v in xyz)
    return msg


def test_a_canopy_cloud_is_taken_and_an_apple_inside_it_is_refused_with_what_blocks_it(arm):
    stack, client, contacts = arm
    shell = shell_around(A, seed=4)
    pub = client.create_publisher(PointCloud2, 'canopy_points', 10)
    client.wait_for(lambda: pub.get_subscription_count() > 0, 10.0, 'the planner on canopy_points')
    publish_until(client, pub, cloud_message(shell, 'base_link'),
                  lambda: 'canopy from canopy_points' in stack.planner.output(), 20.0, 'the canopy taken')
    try:
        mark = client.mark()
        client.send(client.pub_pick, pick_msg())
        answer = final_answer(client, mark, 60.0)
        assert status_values(answer)['state'] == 'refused', answer.message
        # The same pick was made around the low branch before the cloud came (the first test); the message names
        # the obstacle that blocked most of the approaches it names (the branch or the cloud).
        assert 'blocks every approach within 45°' in answer.message, answer.message
    finally:
        clear_canopy(stack, client, pub)


def test_a_cloud_that_comes_while_the_arm_moves_stops_a_plan_it_puts_something_in_the_way_of(arm):
    """The canopy replaced mid-motion: the rest of the running pick is checked against it; the shell
    around the apple now lies on its way, so the planner stops it (the controller brakes to rest)
    and the goal ends aborted saying why."""
    stack, client, contacts = arm
    shell = shell_around(A, seed=5)
    pub = client.create_publisher(PointCloud2, 'canopy_points', 10)
    client.wait_for(lambda: pub.get_subscription_count() > 0, 10.0, 'the planner on canopy_points')
    mark = client.mark()
    client.send(client.pub_pick, pick_msg())
    client.wait_for(lambda: [m for m in client.answers(mark) if status_values(m).get('state') == 'executing'],
                    30.0, 'the pick to run')
    try:
        answer = publish_until(client, pub, cloud_message(shell, 'base_link'),
                               lambda: [m for m in client.answers(mark) if status_values(m).get('state') in FINAL],
                               60.0, 'the pick to end')[0]
        assert status_values(answer)['state'] == 'aborted', answer.message
        assert 'stopped: the world changed while it ran' in answer.message and 'the canopy' in answer.message
        client.wait_for(lambda: arm_at_rest(client), 10.0, 'the arm at rest')
    finally:
        clear_canopy(stack, client, pub)


def test_a_cloud_that_comes_mid_harvest_stops_it_and_the_apples_in_the_box_are_reported(arm):
    """A harvest is stopped as a pick is, when a new cloud lies on the rest of its plan: the apples
    picked by then are reported, the one in hand as failed, nothing touched."""
    stack, client, contacts = arm
    apples = [T for T in synthetic_tree(12, seed=7) if np.linalg.norm(T[:3, 3] - A) > 0.25][:3]
    seen = len(contacts)
    pub, of_harvest = send_harvest(client, apples)
    first = client.wait_for(lambda: of_harvest(apple_state='picked'), 60.0, 'the first apple in the box')[0]
    # The canopy closes round the two apples left (whichever the harvest's order takes next).
    left = [T[:3, 3] for i, T in enumerate(apples) if i != int(first['apple'])]
    cloud = cloud_message(np.vstack([shell_around(p, seed=6 + k) for k, p in enumerate(left)]), 'base_link')
    try:
        end = publish_until(client, pub, cloud, lambda: of_harvest('aborted'), 60.0, 'the harvest stopped')[0]
        assert 'stopped: the world changed while it ran' in end['message'] and 'the canopy' in end['message'], end
        assert 1 <= int(end['picked']) < 3 and first['apple'] in end['picked_apples'].split(), end
        client.wait_for(lambda: arm_at_rest(client), 10.0, 'the arm at rest')
        assert started(contacts, seen) == []
    finally:
        clear_canopy(stack, client, pub)


def test_a_cloud_that_blocks_only_apples_not_started_has_the_rest_of_the_harvest_planned_around_it(arm):
    """A new cloud that encloses an apple of the harvest not started while an earlier one is in hand: the harvest is
    not stopped; the apples not started are planned again around the new canopy (the same goal goes on),
    the enclosed apple is skipped naming the canopy, the others are picked, and the goal succeeds."""
    stack, client, contacts = arm
    apples = []
    for T in synthetic_tree(40, seed=29):         # five apples a shell round one of them leaves clear
        if np.linalg.norm(T[:3, 3] - A) > 0.25 and all(np.linalg.norm(T[:3, 3] - U[:3, 3]) > 0.25 for U in apples):
            apples.append(T)
    apples = apples[:5]
    assert len(apples) == 5
    seen = len(contacts)
    pub, of_harvest = send_harvest(client, apples)
    accepted = client.wait_for(lambda: of_harvest('accepted'), 60.0, 'the harvest accepted')[0]
    order = list(dict.fromkeys(int(part.split(':')[0].split()[1]) for part in accepted['segments'].split('; ')
                               if part.startswith('apple ')))
    assert len(order) >= 4, accepted                     # (one may be out of reach from the start)
    # The apple to enclose: not the first nor the one in hand when the cloud comes, and the farthest from the
    # box (at -y) of those left, so that no other apple's way to and from the box passes by it.
    last = max(order[2:], key=lambda i: apples[i][1, 3])
    client.wait_for(lambda: of_harvest(apple_state='picked'), 60.0, 'the first apple in the box')
    cloud = cloud_message(shell_around(apples[last][:3, 3], seed=11), 'base_link')
    try:
        publish_until(client, pub, cloud, lambda: of_harvest('replanned'), 30.0, 'the harvest planned again')
        end = client.wait_for(lambda: [m for m in of_harvest() if m.get('state') in FINAL], 90.0,
                              'the harvest to end')[0]
        assert end['state'] == 'succeeded', end
        assert str(last) in end['skipped_apples'].split() and int(end['picked']) == len(order) - 1, end
        skipped = [m for m in of_harvest(apple_state='skipped') if m['apple'] == str(last)]
        assert len(skipped) == 1 and 'canopy' in skipped[0]['message'], skipped
        assert sorted(int(m['apple']) for m in of_harvest(apple_state='picked')) == sorted(set(order) - {last})
        assert started(contacts, seen) == []
    finally:
        clear_canopy(stack, client, pub)


def send_harvest(client, apples):
    """Send a harvest of ``apples`` (4x4 grasp poses); ``(canopy publisher, of_harvest)``, where
    ``of_harvest(state, apple_state)`` lists the harvest's statuses so far (values and message)."""
    pub = client.create_publisher(PointCloud2, 'canopy_points', 10)
    harvest = client.create_publisher(PoseArray, 'harvest_targets', BURST)
    client.wait_for(lambda: pub.get_subscription_count() > 0 and harvest.get_subscription_count() > 0, 10.0,
                    'the planner on canopy_points and harvest_targets')
    tree = PoseArray(poses=[make_pose(T[:3, 3].tolist(), Rotation.from_matrix(T[:3, :3]).as_quat().tolist())
                            for T in apples])
    tree.header.frame_id, tree.header.stamp = 'base_link', client.get_clock().now().to_msg()
    key = stamp_key(tree.header.stamp)
    mark = client.mark()
    client.send(harvest, tree)
    client.planner_answer(mark, timeout=30.0)    # (sent again while unanswered: see planner_answer)

    def of_harvest(state=None, apple_state=None):
        return [status_values(m) | {'message': m.message} for m in client.answers(mark)
                if status_values(m).get('goal') == key and (state is None or status_values(m).get('state') == state)
                and (apple_state is None or status_values(m).get('apple_state') == apple_state)]
    return pub, of_harvest


def publish_until(client, pub, msg, predicate, timeout, what):
    """Publish ``msg`` every 0.2 s, as a camera does, until ``predicate()`` holds: the planner takes
    clouds best effort (the newest), so any one of them may be dropped."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        pub.publish(msg)
        try:
            return client.wait_for(predicate, 0.2, what)
        except AssertionError:
            continue
    raise AssertionError(f'timed out after {timeout} s waiting for {what}')


def clear_canopy(stack, client, pub):
    """An empty cloud: no canopy (published until the planner says so)."""
    cleared = stack.planner.output().count('canopy cleared')
    publish_until(client, pub, cloud_message(np.zeros((0, 3)), 'base_link'),
                  lambda: stack.planner.output().count('canopy cleared') > cleared, 20.0, 'the canopy cleared')


def arm_at_rest(client):
    """The last five joint states at rest (called inside client.wait_for, which holds the client's lock)."""
    recent = [np.asarray(m.velocity) for _, m in client.states[-5:] if len(m.velocity)]
    return len(recent) == 5 and max(np.abs(v).max() for v in recent) < 1e-3
