"""The demo's scenario 6: apples swaying in the simulator's wind, each picked as it moves. Three apples hang in
front of the arm; a steady wind sways them about ±30 mm at 1 Hz across the approach; each pick goal is sent once,
where its apple hangs at rest, and nothing is streamed: the planner follows the apple from its own camera. The
simulator, judging the measured arm, says where each apple ended and how far its centre was from the grasp point
when the fingers took it. Recorded to ``wind.mcap`` and drawn in ``wind.png``."""

from __future__ import annotations

import os
import time

import numpy as np
import yaml

from picking_common.middleware import use_fast_discovery
from picking_common.status import status_values

from .demo_report import _table, log, stop_stack
from .stack import Stack

#: m: the apples, where they hang at rest (20 cm apart, in front of the arm, where the camera sees the whole of
#: their sway), in the order they are picked.
APPLES = ((0.70, 0.05, 0.65), (0.70, 0.25, 0.65), (0.70, 0.45, 0.65))
#: The simulator's wind: a push of 2.4 m/s² at 1 Hz across the approach (along y) sways its apples about ±30 mm.
WIND = {'wind.amplitude': 2.4, 'wind.frequency': 1.0, 'wind.direction': float(np.pi / 2)}
#: s the camera watches the tree before the first pick.
WATCH = 2.5
#: s before and after the fingers' closing that the plot shows.
WINDOW = (1.2, 0.3)
FINAL = ('succeeded', 'aborted', 'refused', 'superseded', 'canceled')


def run_wind_scenario(config, out, demo):
    """Start one arm with the swaying apples, pick each, stop it; returns ``(report lines, files, checks)``."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticStatus
    from geometry_msgs.msg import PoseStamped
    from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
    from sensor_msgs.msg import JointState
    from visualization_msgs.msg import MarkerArray

    from picking_common.poses import pose_msg
    from picking_common.run import BackgroundSpin
    from picking_common.topics import BURST
    from picking_core.harvest import SIDEWAYS
    from picking_core.kinematics import pose_matrix

    from .recording import Recorder

    log(f'scenario 6, apples in the wind: {len(APPLES)} apples swaying about ±30 mm at 1 Hz across the approach; '
        'each pick sent once where its apple hangs at rest, followed from the camera')
    tree = out / 'wind_tree.yaml'
    tree.write_text(yaml.safe_dump({'apples': [list(p) for p in APPLES]}, default_flow_style=None))
    ns = '/wind'
    sim = ['-p', f'tree:={tree}', *[a for k, v in WIND.items() for a in ('-p', f'{k}:={v}')]]
    stack = Stack(ns, out / 'logs', config=config, arm=demo.get('arm'), args={'picking-sim': sim})
    use_fast_discovery()
    rclpy.init()
    node = rclpy.create_node(f'picking_demo_wind_{os.getpid()}', namespace=ns)
    reliable = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    rec = Recorder(node, {f'{ns}/planner_status': DiagnosticStatus, f'{ns}/fruit_events': DiagnosticStatus,
                          f'{ns}/fruit_truth': MarkerArray}, reliable)
    rec.add(node, {f'{ns}/joint_states': JointState}, qos_profile_sensor_data)
    rec.add_frames(node, [ns])
    pub = node.create_publisher(PoseStamped, 'pick_target', BURST)
    spinner = BackgroundSpin(node)
    picks, codes = [], {}
    try:
        stack.wait_ready()
        _wait(stack, lambda: pub.get_subscription_count() > 0, 20.0, 'the planner on pick_target')
        time.sleep(WATCH)
        for i, p in enumerate(APPLES):
            msg = PoseStamped(pose=pose_msg(pose_matrix(p, _quaternion(SIDEWAYS))))
            msg.header.frame_id = 'base_link'
            msg.header.stamp = node.get_clock().now().to_msg()
            key = f'{msg.header.stamp.sec}.{msg.header.stamp.nanosec:09d}'
            t0 = time.monotonic()
            pub.publish(msg)
            _wait(stack, lambda: _final(rec, ns, key) is not None, 60.0, f'the pick of apple {i} to end')
            time.sleep(0.5)                                   # the apple lands
            end = _final(rec, ns, key)
            grasp = _event(rec, ns, i, 'grasped') or _event(rec, ns, i, 'missed grasp')
            landed = _event(rec, ns, i, 'in the box')
            picks.append((i, key, end, grasp, landed))
            off = f'{float(grasp["offset"]) * 1e3:.1f} mm from the grasp point' if grasp and 'offset' in grasp \
                else 'not taken'
            log(f'  apple {i}: pick {end.get("state")} in {time.monotonic() - t0:.1f} s, re-targeted '
                f'{end.get("retargets_received", "0")} times from the camera; the simulator: '
                f'{"in the box" if landed else "NOT in the box"}, its centre {off}')
    except RuntimeError as exc:
        log(f'FAILED: {exc}')
    finally:
        codes = stop_stack(stack)
    spinner.stop(2.0)
    node.destroy_node()
    rclpy.try_shutdown()
    return wind_report(rec, ns, picks, codes, out, demo)


def _quaternion(rpy):
    from scipy.spatial.transform import Rotation
    return Rotation.from_euler('xyz', rpy).as_quat()


def _wait(stack, pred, timeout, what):
    end = time.monotonic() + timeout
    while not pred():
        if time.monotonic() > end:
            raise RuntimeError(f'timed out waiting for {what}')
        if not all(stack.alive().values()):
            raise RuntimeError(f'a node exited while waiting for {what}')
        time.sleep(0.05)


def _final(rec, ns, key):
    return next((v for v in (status_values(m) for _, m in rec.messages(f'{ns}/planner_status'))
                 if v.get('goal') == key and v.get('state') in FINAL), None)


def _event(rec, ns, apple, kind):
    return next((v for v in (status_values(m) for _, m in rec.messages(f'{ns}/fruit_events'))
                 if v.get('apple') == str(apple) and v.get('event') == kind), None)


def wind_report(rec, ns, picks, codes, out, demo):
    """The scenario's section: its checks, a table of the picks, ``wind.png`` and ``wind.mcap``;
    ``(lines, files, checks)``."""
    from picking_core.kinematics import ArmModel
    from picking_description import DEFAULT_ARM, urdf_path

    from .plots import plot_sway_picks
    title = '## Scenario 6: apples swaying in the wind'
    checks = {'every node of the wind arm exited with 0': set(codes.values()) == {0},
              'every pick ended': len(picks) == len(APPLES)}
    if len(picks) < len(APPLES):
        return ['', title, '', 'A pick did not end: see the logs.'], [], checks
    arm = ArmModel.from_urdf(urdf_path(demo.get('arm') or DEFAULT_ARM))
    states = [m for _, m in rec.messages(f'{ns}/joint_states') if set(arm.joint_names) <= set(m.name)]
    q = np.array([[m.position[list(m.name).index(j)] for j in arm.joint_names] for m in states])
    t_tool = np.array([m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in states])
    y_tool = arm.fk(q)[:, 1, 3]
    truth = [(m.markers[0].header.stamp, m.markers) for _, m in rec.messages(f'{ns}/fruit_truth') if m.markers]
    t_truth = np.array([s.sec + s.nanosec * 1e-9 for s, _ in truth])
    rows, panels = [], []
    for i, key, end, grasp, landed in picks:
        offset = float(grasp['offset']) if grasp and 'offset' in grasp else None
        rows.append((str(i), end.get('state', '?'), end.get('retargets_received', '0'),
                     'in the box' if landed else 'not in the box',
                     f'{offset * 1e3:.1f}' if offset is not None else 'not taken'))
        if grasp:                            # (the fingers' closing: on the apple, or beside it)
            t = float(grasp['t'])
            near = (t_truth >= t - WINDOW[0]) & (t_truth <= t + WINDOW[1])
            y_apple = np.array([m.pose.position.y for k, (_, markers) in enumerate(truth) if near[k]
                                for m in markers if m.id == i])
            tool = (t_tool >= t - WINDOW[0]) & (t_tool <= t + WINDOW[1])
            label = f'{offset * 1e3:.1f} mm off centre' if offset is not None else 'closed beside it'
            panels.append((f'apple {i}: {label}', t_truth[near] - t, 1e3 * (y_apple - APPLES[i][1]),
                           t_tool[tool] - t, 1e3 * (y_tool[tool] - APPLES[i][1]), 0.0))
    files = [plot_sway_picks(out / 'wind.png', panels, 'Scenario 6: swaying apples, each picked as it moves')] \
        if panels else []
    path, count = rec.write_mcap(out / 'wind.mcap')
    files.append(path)
    checks['each pick\'s result agrees with the simulator (succeeded: its apple is in the box)'] = all(
        (end.get('state') == 'succeeded') == bool(landed) for _, _, end, _, landed in picks)
    checks['every pick followed its apple from the camera'] = all(
        int(end.get('retargets_received', 0)) > 0 for _, _, end, _, _ in picks)
    lines = ['', title, '',
             f'{len(APPLES)} apples hang 20 cm apart in front of the arm, where the camera sees the whole of their '
             'sway; the simulator\'s wind (a push of '
             f'{WIND["wind.amplitude"]} m/s² at {WIND["wind.frequency"]:g} Hz across the approach) sways them about '
             '±30 mm. Each pick goal is sent once on `pick_target`, where its apple hangs at rest, and nothing is '
             'streamed: the planner fits each apple\'s sway from its camera\'s detections (the 2 s before the goal, '
             'then each frame), aims the fingers where the apple will be when they close, and re-plans as the '
             'frames come. The simulator judges the measured arm.', '',
             _table(['apple', 'pick', 're-targets from the camera', 'the simulator', 'centre off the grasp point '
                     '[mm]'], rows), '',
             # (A measurement, not a check: a miss is reported, and the pick says so, as the simulator does.)
             f'{sum(bool(landed) for *_, landed in picks)} of {len(picks)} apples in the box by the simulator\'s '
             'count.', '',
             '`wind.png`: for each pick, across the approach (y, from where the apple hangs at rest), the apple\'s '
             'true place (the simulator\'s `fruit_truth`, 10 Hz) and the grasp point\'s (from `joint_states`) in '
             'the last second before the fingers closed. '
             f'`wind.mcap` ({count} messages): joint states, statuses, the fruit\'s events and truth.']
    lines += ['', *[f'- {k}: {"yes" if ok else "NO"}' for k, ok in checks.items()]]
    return lines, files, checks
