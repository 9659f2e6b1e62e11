"""Apples that exist: a harvest counted by the simulator's own judgement of the measured arm (every apple
grasped, pulled off, carried and in the box, nothing knocked or bruised; a goal's apple that hangs nowhere missed,
as the measured gripper shows, and not claimed), and the camera's detections, through /tf_static, where the apples
truly hang."""

import subprocess
import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseArray
from rosstack import BURST, make_pose, running_stack
from scipy.spatial.transform import Rotation
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import MarkerArray

from picking_common.status import status_values
from picking_common.topics import LATCHED
from picking_common.vision import read_detections
from picking_core.harvest import synthetic_tree
from vision_msgs.msg import Detection3DArray

TREE = ('synthetic', 3, 0)


def test_a_harvest_puts_every_apple_in_the_box_by_the_simulators_count(tmp_path):
    kind, n, seed = TREE
    with running_stack('/fruit1', tmp_path, sim_args=('-p', f'tree:={kind} {n} {seed}')) as (stack, client):
        events, detections, truth, static = [], [], [], []
        client.create_subscription(DiagnosticStatus, 'fruit_events', events.append, BURST)
        client.create_subscription(Detection3DArray, 'detections', detections.append, 10)
        client.create_subscription(MarkerArray, 'fruit_truth', truth.append, 10)
        client.create_subscription(TFMessage, '/tf_static', static.append, LATCHED)
        pub = client.create_publisher(PoseArray, 'harvest_targets', BURST)
        camera = 'fruit1/camera_optical_frame'            # (the stack prefixes an arm's frames with its namespace)
        client.wait_for(lambda: len(detections) > 5 and truth and [t for m in static for t in m.transforms
                                                                   if t.child_frame_id == camera],
                        20.0, 'detections, truth and the camera frame')

        # The camera's detections, placed through its transform on /tf_static, are where the apples hang.
        mount = next(t.transform for m in static for t in m.transforms if t.child_frame_id == camera)
        R = Rotation.from_quat([mount.rotation.x, mount.rotation.y, mount.rotation.z, mount.rotation.w]).as_matrix()
        o = np.array([mount.translation.x, mount.translation.y, mount.translation.z])
        hanging = np.array([[m.pose.position.x, m.pose.position.y, m.pose.position.z] for m in truth[-1].markers])
        positions, covs, _, _, refused = read_detections(detections[-1])
        assert detections[-1].header.frame_id == camera and not refused and len(positions)
        seen = positions @ R.T + o
        assert np.max(np.min(np.linalg.norm(seen[:, None] - hanging[None], axis=2), axis=1)) < 0.02
        assert np.allclose(covs[0], np.eye(3) * 0.003 ** 2)

        # The goal adds an apple where none hangs: the fingers close on air there.
        apples = synthetic_tree(n, seed)
        others = synthetic_tree(6, seed + 5)
        absent = max(others, key=lambda T: min(np.linalg.norm(T[:3, 3] - A[:3, 3]) for A in apples))
        msg = PoseArray(poses=[make_pose(T[:3, 3], Rotation.from_matrix(T[:3, :3]).as_quat())
                               for T in [*apples, absent]])
        msg.header.frame_id, msg.header.stamp = 'base_link', client.get_clock().now().to_msg()
        mark = client.mark()
        pub.publish(msg)
        client.wait_for(lambda: [m for _, m in client.planner_status[mark['planner']:]
                                 if status_values(m).get('kind') == 'harvest'
                                 and status_values(m).get('state') in ('succeeded', 'aborted', 'refused')],
                        120.0, 'the harvest to end')
        client.wait_for(lambda: events and int(status_values(events[-1])['in_the_box']) == n, 5.0,
                        f'{n} apples in the box by the simulator\'s count: {[e.message for e in events]}')
        time.sleep(0.5)
        kinds = [status_values(e)['event'] for e in events]
        for k in ('grasped', 'detached', 'released', 'in the box'):
            assert kinds.count(k) == n, kinds
        last = status_values(events[-1])
        # (A link may brush an apple it does not pick: the planner avoids the scene, not the other apples. Such
        # a knock is reported; none bruises.)
        assert (last['bruised'], last['missed_grasps'], last['dropped']) == ('0', '0', '0'), last
        # The harvest's own claims agree with the world's: the apple that hangs nowhere is missed, not claimed.
        said = [status_values(m) for _, m in client.planner_status[mark['planner']:]]
        picked = [v for v in said if v.get('apple_state') == 'picked']
        assert len(picked) == n and all(v['verified'] == 'True' for v in picked), picked
        missed = [v for v in said if v.get('apple_state') == 'missed']
        assert [v['apple'] for v in missed] == [str(n)], said
        end = next(v for v in reversed(said) if v.get('kind') == 'harvest' and v.get('state') == 'succeeded')
        assert (end['picked'], end['missed'], end['missed_apples']) == (str(n), '1', str(n)), end


def test_harvest_seen_picks_the_apples_the_camera_reports_into_the_box(tmp_path):
    """`picking-goal harvest --seen`: the planner harvests what its fruit map confirmed from the camera's noisy
    detections (it never reads the truth), and the simulator counts every apple in the box."""
    kind, n, seed = TREE
    with running_stack('/fruit2', tmp_path, sim_args=('-p', f'tree:={kind} {n} {seed}')) as (stack, client):
        # (2 s: the camera's frames confirm the apples.)
        printed, _, _, events = _harvest_seen(client, '/fruit2', look=2.0, timeout=120)
        assert 'a harvest of the apples seen' in printed and 'succeeded' in printed, printed
        client.wait_for(lambda: events and int(status_values(events[-1])['in_the_box']) == n, 5.0,
                        f'{n} apples in the box by the simulator\'s count: {[e.message for e in events]}')
        last = status_values(events[-1])
        assert (last['bruised'], last['missed_grasps'], last['dropped']) == ('0', '0', '0'), last
        assert 'apples seen' in stack.planner.output()


def test_harvest_seen_takes_in_an_apple_the_arm_hid_from_the_camera_at_home(tmp_path):
    """Apple 2 of this tree is behind the arm at home: the harvest of the apples seen starts with two, the camera sees
    the third once the arm is away, and the same goal takes it in (once); all three end in the box by the simulator's
    count, each claimed once. (An apple the arm knocked rings on its stem: the harvest may aim it at its sway too.)"""
    with running_stack('/fruit4', tmp_path, sim_args=('-p', 'tree:=synthetic 3 5')) as (stack, client):
        # (2 s: the camera's frames confirm the apples it sees.)
        _, statuses, said, events = _harvest_seen(client, '/fruit4', look=2.0, timeout=120)
        assert 'harvest of the 2 apples seen' in stack.planner.output(), stack.planner.output()
        taken = [m.message for _, m in statuses if status_values(m).get('state') == 'replanned'
                 and 'more apple' in m.message]
        assert len(taken) == 1 and '1 more apple seen (2)' in taken[0], [m.message for _, m in statuses]
        client.wait_for(lambda: events and int(status_values(events[-1])['in_the_box']) == 3, 5.0,
                        f'3 apples in the box by the simulator\'s count: {[e.message for e in events]}')
        picked = [v['apple'] for v in said if v.get('apple_state') == 'picked']
        assert sorted(picked) == ['0', '1', '2'], said
        end = next(v for v in reversed(said) if v.get('kind') == 'harvest' and v.get('state') == 'succeeded')
        assert end['picked'] == '3', end


def test_bad_detections_are_counted_with_their_reason_and_harvest_seen_without_apples_is_refused(tmp_path):
    from diagnostic_msgs.msg import DiagnosticArray
    from std_msgs.msg import Header

    from picking_common.vision import detections_msg
    from picking_core.camera import Detection
    with running_stack('/fruit3', tmp_path) as (stack, client):
        arrays = []
        client.create_subscription(DiagnosticArray, '/diagnostics', arrays.append, 10)
        pub = client.create_publisher(Detection3DArray, 'detections', 10)
        client.wait_for(lambda: pub.get_subscription_count() > 0, 20.0, 'the planner to subscribe to detections')
        one = [Detection(np.array([0.7, 0.0, 0.6]), 0.07, 0.9, 0.003, 0)]
        stamp = client.get_clock().now().nanoseconds
        nan = detections_msg(one, 'fruit3/base_link', stamp)
        nan.detections[0].results[0].pose.pose.position.x = float('nan')
        flood = detections_msg(one * 100, 'fruit3/base_link', stamp)
        lost = detections_msg(one, 'nowhere', stamp)
        for msg in (nan, flood, lost):
            pub.publish(msg)

        def fruit_map():
            for array in reversed(arrays):
                for s in array.status:
                    if s.name == 'fruit3/picking_planner: fruit map' and 'not finite' in s.message and \
                            'flood' in s.message and "'nowhere'" in s.message:
                        return s
            return None
        report = client.wait_for(fruit_map, 10.0, 'the fruit map to count the refusals')
        assert status_values(report)['refused'] == '102' and status_values(report)['confirmed'] == '0', report.message

        seen = client.create_publisher(Header, 'harvest_seen', BURST)
        client.wait_for(lambda: seen.get_subscription_count() > 0, 20.0, 'the planner to subscribe to harvest_seen')
        mark = client.mark()
        header = Header(stamp=client.get_clock().now().to_msg())
        seen.publish(header)
        refused = client.wait_for(lambda: [m for _, m in client.planner_status[mark['planner']:]
                                           if status_values(m).get('state') == 'refused'], 10.0, 'the refusal')[0]
        assert 'no apples seen' in refused.message
        # The same goal sent again (its sender heard nothing yet) is answered again, not made again.
        seen.publish(header)
        client.wait_for(lambda: len([m for _, m in client.planner_status[mark['planner']:]
                                     if status_values(m).get('state') == 'refused']) == 2, 10.0, 'the answer again')
        client.wait_for(lambda: 'came again' in stack.planner.output(), 5.0, 'the planner to say it came again')


def test_harvest_seen_in_the_wind_aims_each_swaying_apple_and_the_world_agrees(tmp_path):
    """`picking-goal harvest --seen` on a tree of four swaying about ±30 mm at 1 Hz across the approach: before each
    apple in hand is dropped the harvest is aimed again at the next one's sway (said as `replanned`), and the
    planner's claims agree with the simulator's count: every apple it calls picked is in the box, a grasp beside an
    apple is reported missed, none bruised. At least two of the four in the box (aimed on the wrong clock, one):
    on a loaded machine a re-aim that comes too late leaves its apple planned where it hangs, and the stalls of
    the controller and the simulator close the fingers late, beside an apple that sways 0.19 m/s at its middle
    (seen in CI: two of four closed 2.1 and 3.4 cm across, beyond the capture region's 2 cm). How near each
    closing is to its apple, and how many go in the box, are benchmark row 11's."""
    wind = ('-p', 'wind.amplitude:=2.4', '-p', 'wind.frequency:=1.0', '-p', f'wind.direction:={np.pi / 2}')
    with running_stack('/fruit5', tmp_path, sim_args=('-p', 'tree:=synthetic 4 2', *wind)) as (stack, client):
        # (5 s: the wind's sway grows steady; the camera fits it.)
        _, statuses, said, events = _harvest_seen(client, '/fruit5', look=5.0, timeout=150)
        aimed = [m.message for _, m in statuses if status_values(m).get('state') == 'replanned'
                 and 'sways: aimed where it will be' in m.message]
        assert len(aimed) >= 2, [m.message for _, m in statuses]
        time.sleep(1.0)
        last = status_values(events[-1])
        picked = [v['apple'] for v in said if v.get('apple_state') == 'picked']
        missed = [v['apple'] for v in said if v.get('apple_state') == 'missed']
        assert int(last['in_the_box']) == len(picked) >= 2, (last, [m.message for _, m in statuses])
        assert int(last['missed_grasps']) <= len(missed) and (last['bruised'], last['dropped']) == ('0', '0'), last


def _harvest_seen(client, namespace, look, timeout):
    """`picking-goal harvest --seen` in ``namespace``, sent after the camera has watched for ``look`` s, waited for
    (it must exit 0): what it printed, the planner's statuses since it was sent, their values, and the simulator's
    fruit events (subscribed before the look)."""
    events = []
    client.create_subscription(DiagnosticStatus, 'fruit_events', events.append, BURST)
    time.sleep(look)
    mark = client.mark()
    done = subprocess.run(['picking-goal', 'harvest', '--seen', '--timeout', str(timeout), '--ros-args', '-r',
                           f'__ns:={namespace}'], capture_output=True, text=True, timeout=timeout + 50)
    assert done.returncode == 0, '\n'.join((done.stdout, done.stderr))
    statuses = client.planner_status[mark['planner']:]
    return done.stdout, statuses, [status_values(m) for _, m in statuses], events
