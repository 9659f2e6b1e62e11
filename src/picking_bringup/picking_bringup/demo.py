"""``picking-demo`` (``make demo``): the Table 1 apple pick-and-place cycle, end to end on the simulator.

Starts the simulator, the controller and the planner as separate processes
(loopback-only DDS, a domain of the run's own), sends the pick cycle through
``pick_target`` as a user would, records everything to an MCAP file, stops
every process by its pid, and writes a report and plots to ``--out``. Then the
paper's Sec. 3.1 arc as a second scenario, the same cycle planned with
cubic, quintic and LSPB segments side by side, a tree harvested by the arm
(scenario 3), a wider tree harvested by two arms (scenario 4,
``picking-stack --platform``), and a tree among branches harvested around them and
once without collision checking (scenario 5), and apples swaying in the simulator's wind, each picked as it moves
(scenario 6). Exit code 0 only if every step worked.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

from picking_common.middleware import use_fast_discovery

from .demo_report import analyse_and_report, load_demo_settings, log, log_checks, run_tool
from .stack import BIN as HERE
from .stack import Stack


def run_ros_part(args, config, out, demo, stack_initial):
    """Start, drive, record, stop. Returns (recorder, events dict, exit codes)."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticStatus
    from nav_msgs.msg import Path as PathMsg
    from picking_interfaces.action import Pick
    from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
    from sensor_msgs.msg import JointState
    from trajectory_msgs.msg import JointTrajectory

    from picking_common.actions import ActionClient
    from picking_common.run import BackgroundSpin

    from .recording import Recorder

    reliable = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    # The arm as picking-stack brings it up, at the pick cycle's home, its logs beside the report; the simulator
    # hangs the apples the scenarios pick (scenario 3's tree, then scenario 1's apple) and counts what they become.
    tree = write_tree(out / 'tree.yaml', demo)
    stack = Stack('/', out / 'logs', config=config, arm=args.arm, args={
        'picking-sim': ['-p', 'initial_positions:=[' + ','.join(map(str, stack_initial)) + ']', '-p', f'tree:={tree}']})
    for name, p in stack.nodes.items():
        log(f'started {name} (pid {p.pid})')
    events = {'ok': False}
    use_fast_discovery()
    rclpy.init()
    node = rclpy.create_node(f'picking_demo_{os.getpid()}')
    rec = Recorder(node, {'planned_trajectory': JointTrajectory, 'planned_path': PathMsg,
                          'planner_status': DiagnosticStatus, 'controller_status': DiagnosticStatus,
                          'fruit_events': DiagnosticStatus}, reliable)
    # The 100 Hz and 1 kHz streams as sensor data: a recorder must never slow the arm down.
    rec.add(node, {'joint_states': JointState, 'joint_commands': JointState}, qos_profile_sensor_data)
    rec.add_frames(node)
    pick = ActionClient(node, Pick, 'pick')
    spinner = BackgroundSpin(node)

    def spin_until(pred, timeout, what):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            time.sleep(0.02)
            if pred():
                return True
            if not all(stack.alive().values()):
                raise RuntimeError(f'a node died while waiting for {what}: {stack.alive()}')
        raise RuntimeError(f'timed out after {timeout} s waiting for {what}')

    try:
        spin_until(lambda: rec.count('joint_states') > 10 and pick.server_is_ready(), 30.0, 'the nodes to come up')
        spin_until(lambda: rec.count('joint_commands') > 10, 30.0, 'the controller to hold the arm')
        log('nodes up: joint_states flowing, controller holding, planner listening')
        seen = look_at_the_tree(node, spin_until)
        log(f"the planner's fruit map sees {seen} apples of the tree: a pick passes them slowly")
        run_pick_scenario(node, pick, rec, demo, spin_until, events)
        time.sleep(0.5)                          # a last half second of joint_states
        if not args.quick:
            events['arc'] = run_arc_scenario(demo, spin_until, rec)
            events['harvest'] = run_harvest_scenario(demo, spin_until, rec, node)
        events['ok'] = True
    except RuntimeError as exc:
        events['error'] = str(exc)
        log(f'FAILED: {exc}')
    finally:
        spinner.stop()
        node.destroy_node()
        rclpy.try_shutdown()
        events['exit_codes'] = stack.stop()
        for name, code in events['exit_codes'].items():
            log(f'stopped {name} (pid {stack.nodes[name].pid}): exit code {code}')
    return rec, events


def write_tree(path, demo):
    """The simulator's tree file: scenario 3's synthetic tree (apples 0 to n - 1, in its order), then scenario 1's
    apple (apple n)."""
    import yaml

    from picking_core.harvest import synthetic_tree
    n, seed = int(demo.get('harvest_apples', 20)), int(demo.get('harvest_seed', 1))
    apples = [[float(v) for v in T[:3, 3]] for T in synthetic_tree(n, seed=seed)] + [
        [float(v) for v in demo['apple_position']]]
    path.write_text(yaml.safe_dump({'apples': apples}, default_flow_style=None))
    return path


#: s the camera watches the tree from home once the planner's fruit map confirmed an apple, before the first goal.
LOOK = 1.0


def look_at_the_tree(node, spin_until):
    """How many apples the planner's fruit map has confirmed (its line on /diagnostics) after a look at the tree
    from home: as a user would, the demo lets the camera see the tree before it sends a goal among its apples."""
    from diagnostic_msgs.msg import DiagnosticArray

    from picking_common.status import DIAGNOSTICS, status_values
    confirmed = []

    def on_diagnostics(msg):
        for s in msg.status:
            if s.name.endswith('picking_planner: fruit map'):
                confirmed.append(int(status_values(s).get('confirmed', 0)))
    # (Kept to the end: destroyed while the demo's spinner waits on it, rclpy's wait set would throw.)
    node.create_subscription(DiagnosticArray, DIAGNOSTICS, on_diagnostics, 10)
    try:
        spin_until(lambda: confirmed and confirmed[-1] > 0, 15.0, "the planner's fruit map to see the tree")
    except RuntimeError:
        return 0                                 # (a tree out of the camera's view: the goals go on without)
    time.sleep(LOOK)
    n = len(confirmed)
    spin_until(lambda: len(confirmed) > n, 5.0, "the planner's fruit map after the look")
    return confirmed[-1]


def run_pick_scenario(node, pick, rec, demo, spin_until, events):
    """Scenario 1: one apple sent to the planner's pick action as a user would, its phases logged as they come;
    the plan's values (``events['plan']``), the cycle's wall time and the controller's word on it kept."""
    from geometry_msgs.msg import PoseStamped
    from picking_interfaces.action import Pick
    from scipy.spatial.transform import Rotation

    def status_after(topic, start, pred):
        return next((m for _, m in rec.messages(topic)[start:] if pred(m)), None)

    apple = PoseStamped()
    apple.header.frame_id = 'base_link'
    apple.header.stamp = node.get_clock().now().to_msg()
    x, y, z = demo['apple_position']
    apple.pose.position.x, apple.pose.position.y, apple.pose.position.z = float(x), float(y), float(z)
    qx, qy, qz, qw = Rotation.from_euler('xyz', demo['apple_rpy']).as_quat()
    apple.pose.orientation.x, apple.pose.orientation.y = float(qx), float(qy)
    apple.pose.orientation.z, apple.pose.orientation.w = float(qz), float(qw)
    t_sent = time.monotonic()
    progress = {'phase': None}

    def on_feedback(msg):
        if msg.feedback.phase != progress['phase']:
            progress['phase'] = msg.feedback.phase
            log(f'  {time.monotonic() - t_sent:5.2f} s  {msg.feedback.phase:<20} '
                f'{msg.feedback.time_left:5.2f} s left, tracking error {msg.feedback.tracking_error:.4f} rad')

    sent = pick.send_goal_async(Pick.Goal(target=apple), feedback_callback=on_feedback)
    log(f'pick goal sent: apple at {[x, y, z]} m')
    spin_until(lambda: sent.done(), 20.0, 'the planner to take the pick goal')
    handle = sent.result()
    key = bytes(handle.goal_id.uuid).hex()
    result = handle.get_result_async()

    def answer(state=None):
        return status_after('planner_status', 0, lambda m: {kv.key: kv.value for kv in m.values}.get('goal') == key
                            and (state is None or {kv.key: kv.value for kv in m.values}.get('state') == state))
    # The planner ends every goal with a result (the controller's, or the reason): no time-out needed
    # but a guard against a node that died (spin_until checks them).
    spin_until(lambda: answer('accepted') or result.done(), 60.0, 'the controller to accept the plan')
    accepted = answer('accepted')
    if accepted is None:
        raise RuntimeError(f'the planner refused the pick: {result.result().result.message}')
    values = {kv.key: kv.value for kv in accepted.values}
    events['plan'] = values
    log(f'planned: {accepted.message} in {values.get("planning_ms", "?")} ms; moving')
    spin_until(result.done, float(values['duration']) + 60.0, 'the pick result')
    done = result.result()
    if done.result.outcome != Pick.Result.SUCCEEDED:
        raise RuntimeError(f'the pick did not succeed: {done.result.message}')
    events['cycle_wall'] = time.monotonic() - t_sent
    reached = status_after('controller_status', 0, lambda m: m.message == 'goal reached')
    events['goal'] = {kv.key: kv.value for kv in reached.values} if reached is not None else {}
    log(f'cycle done: {done.result.message}, {events["cycle_wall"]:.2f} s after sending the pick goal')



def run_arc_scenario(demo, spin_until, rec):
    """Sec. 3.1: the arc through P1, P2, P3 (scaled into the workspace), sent with picking-goal."""
    scale, offset = demo['arc_scale'], np.asarray(demo['arc_offset'], float)
    pts = [np.asarray(p, float) * scale + offset for p in ((10, 3, 4), (11, 3, 5), (10, 3, 6))]
    log(f'scenario 2, Sec. 3.1 arc: P1 P2 P3 scaled by {scale} m, at {np.round(pts, 3).tolist()}')
    first = run_tool([HERE / 'picking-goal', 'pose', *pts[0], '--method', 'quintic'], 120)
    n = rec.count('planned_trajectory')
    arc = run_tool([HERE / 'picking-goal', 'path', '--arc', '--pose', *pts[1], '--pose', *pts[2]], 120)
    for what, run in (('the move to P1', first), ('the arc', arc)):
        if run.returncode != 0:
            said = (run.stderr.strip() or run.stdout.strip() or f'exit code {run.returncode}').splitlines()[-1]
            raise RuntimeError(f'the arc scenario failed: {what}: {said.strip()}')
    spin_until(lambda: rec.count('planned_trajectory') > n, 5.0, 'the arc trajectory')
    return {'points': [p.tolist() for p in pts], 'trajectory_index': n, 'scale': scale}


def run_harvest_scenario(demo, spin_until, rec, node):
    """A seeded synthetic tree, hanging in the simulator, harvested with picking-goal: the apples its camera
    sees (``harvest_from: camera``, the planner's fruit map) or the tree's own poses (``tree``); its apples and
    visiting order published as markers (recorded, so that Foxglove shows the tree)."""
    from visualization_msgs.msg import MarkerArray

    from picking_core.harvest import synthetic_tree

    from .demo_report import harvest_markers, harvest_statuses, on_the_tree
    n, seed = int(demo.get('harvest_apples', 20)), int(demo.get('harvest_seed', 1))
    seen = demo.get('harvest_from', 'camera') == 'camera'
    how = 'harvest --seen (the apples its camera sees)' if seen else f'harvest --tree {n} --seed {seed}'
    log(f'scenario 3, a tree: {n} apples (seed {seed}) in the simulator, harvested with picking-goal {how}')
    markers = node.create_publisher(MarkerArray, 'harvest_markers', 10)
    rec.add(node, {'harvest_markers': MarkerArray}, 10)
    first = rec.count('planned_trajectory')
    t0 = time.monotonic()
    command = ['harvest', '--seen'] if seen else ['harvest', '--tree', n, '--seed', seed]
    done = run_tool([HERE / 'picking-goal', *command], 60 + 10 * n)
    if done.returncode != 0:
        said = (done.stderr.strip() or done.stdout.strip() or f'exit code {done.returncode}').splitlines()[-1]
        raise RuntimeError(f'the harvest failed: {said.strip()}')
    key = done.stdout.split(' goal ')[1].split()[0]
    spin_until(lambda: rec.count('planned_trajectory') > first, 5.0, 'the harvest trajectory')
    trajectory = rec.messages('planned_trajectory')[first][1]
    tree = synthetic_tree(n, seed=seed)
    markers.publish(harvest_markers(tree, on_the_tree(harvest_statuses(rec, key), tree), trajectory.header))
    spin_until(lambda: rec.count('harvest_markers') > 0, 5.0, 'the harvest markers')
    return {'goal': key, 'trajectory_index': first, 'apples': n, 'seed': seed, 'wall': time.monotonic() - t0,
            'seen': seen}


def run_platform(rec, events, config, out, demo):
    """Scenario 4 after the one-arm scenarios (their stack stopped): its section appended to the report."""
    from .demo_platform import run_platform_scenario
    from .demo_report import harvest_statuses
    if 'harvest' in events:
        rate = harvest_statuses(rec, events['harvest']['goal'])['final'].get('apples_per_hour')
        demo = dict(demo, one_arm_rate=float(rate) if rate else None)
    return _section(out, events, 'platform', *run_platform_scenario(config, out, demo))


def run_orchard(events, config, out, demo):
    """Scenario 5 after the others (their stacks stopped): its section appended to the report."""
    from .demo_orchard import clear_apples, run_orchard_scenario
    from .shipped import shipped_orchard
    n, seed = int(demo.get('orchard_apples', 12)), int(demo.get('orchard_seed', 1))
    demo = dict(demo, clear_apples=clear_apples(shipped_orchard(n, seed, demo.get('arm'), config), config,
                                                demo.get('arm')))
    return _section(out, events, 'orchard', *run_orchard_scenario(config, out, demo))


def run_wind(events, config, out, demo):
    """Scenario 6 after the others (their stacks stopped): its section appended to the report."""
    from .demo_wind import run_wind_scenario
    return _section(out, events, 'wind', *run_wind_scenario(config, out, demo))


def _section(out, events, name, lines, files, checks):
    """A scenario's section appended to the report (its checks summed up in the log); its checks kept in ``events``; whether
    they all hold."""
    report = out / 'report.md'
    report.write_text(report.read_text() + '\n'.join(lines + ['', *[f'- `{f}`' for f in files]]) + '\n')
    log_checks(f'scenario {name}', checks)
    events[name] = checks
    return all(checks.values())


#: Status values that name something (a goal, a trajectory by its stamp): text, never numbers.
NAMES = ('goal', 'trajectory', 'stamp')


def _numbers(value):
    """Status values (text) as numbers where they are numbers, for run.json."""
    if isinstance(value, dict):
        return {k: v if k in NAMES else _numbers(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_numbers(v) for v in value]
    if isinstance(value, str):
        try:
            return float(value) if any(c in value for c in '.eE') else int(value)
        except ValueError:
            return value
    return value


#: What a run writes into --out (removed first, so that nothing left from an earlier run is taken for this one's).
OUTPUTS = ('report.md', 'report.json', 'run.json', 'demo.mcap', 'joints.png', 'tracking_error.png', 'tool_path.png',
           'harvest.png', 'platform.png', 'platform.mcap', 'orchard.png', 'orchard.mcap', 'wind.png', 'wind.mcap')
#: Lines of each node's log quoted in the report of a failed run.
LOG_TAIL = 30


def failure_report(rec, events, out):
    """report.md for a run that failed: why, the end of every node's log, and what was recorded (demo.mcap)."""
    lines = ['# Pick-and-place demo: FAILED', '', f'- {events.get("error", "a node exited with an error")}',
             f'- exit codes: {events.get("exit_codes")}']
    try:
        path, n_msgs = rec.write_mcap(out / 'demo.mcap')
        lines.append(f'- what was recorded until then: `{path.name}`, {n_msgs} messages')
    except Exception as exc:                 # the report of a failure must not fail itself
        lines.append(f'- the recording could not be written: {exc}')
    for name in ('picking-sim', 'picking-controller', 'picking-planner'):
        for logfile in sorted((out / 'logs').glob(f'*/{name}.*.log')):
            tail = logfile.read_text(errors='replace').splitlines()[-LOG_TAIL:]
            lines += ['', f'## {logfile.relative_to(out)} (last {len(tail)} lines)', '', '```', *tail, '```']
    (out / 'report.md').write_text('\n'.join(lines) + '\n')


def main(argv=None):
    parser = argparse.ArgumentParser(prog='picking-demo', description=__doc__.split('\n\n')[0])
    parser.add_argument('--out', type=Path, default=Path('out/demo'), help='report, plots, MCAP (default %(default)s)')
    parser.add_argument('--quick', action='store_true', help='the pick cycle only (no arc scenario, no comparison)')
    parser.add_argument('--arm', help='a shipped arm other than the default picking arm (ur5e or fr3, as '
                        'picking-stack --arm): every scenario but the platform\'s, whose arms its layout names')
    args = parser.parse_args(argv)
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    os.environ.setdefault('ROS_DOMAIN_ID', str(os.getpid() % 90 + 10))
    os.environ.setdefault('MPLBACKEND', 'Agg')
    from .shipped import check_arm, config_dir
    config = config_dir()
    if args.arm:
        try:
            check_arm(config, args.arm)
        except ValueError as exc:
            parser.error(str(exc))
    args.out.mkdir(parents=True, exist_ok=True)
    demo, planner_params = load_demo_settings(config, args.arm)
    demo = dict(demo, arm=args.arm)
    home = list(planner_params.get('home_positions', [0.0, 0.2, 1.6, 0.0, 1.3, 0.0]))
    initial = home + [float(planner_params.get('gripper_open', 0.09))]
    log(f'ROS_DOMAIN_ID={os.environ["ROS_DOMAIN_ID"]}, discovery on loopback only; output in {args.out}')
    for name in OUTPUTS:                     # a failed run must not leave an earlier run's report behind
        (args.out / name).unlink(missing_ok=True)
    t0 = time.monotonic()
    rec, events = run_ros_part(args, config, args.out, demo, initial)
    ok = events['ok'] and all(code == 0 for code in events['exit_codes'].values())
    report_ok = False
    if events['ok']:
        log('analysing the run')
        report_ok = analyse_and_report(rec, events, config, args.out, quick=args.quick, arm_name=args.arm)
        if not args.quick and args.arm:
            log(f'scenario 4 left out: the platform\'s arms are those its layout names, not the {args.arm}')
        elif not args.quick:
            report_ok = run_platform(rec, events, config, args.out, demo) and report_ok
        if not args.quick:
            report_ok = run_orchard(events, config, args.out, demo) and report_ok
        if not args.quick and args.arm:
            log(f'scenario 6 left out: its apples are placed where the camera sees them beside the picking arm, '
                f'not the {args.arm}')
        elif not args.quick:
            report_ok = run_wind(events, config, args.out, demo) and report_ok
    else:
        failure_report(rec, events, args.out)
    summary = {'ok': bool(ok and report_ok), 'events': _numbers({k: v for k, v in events.items() if k != 'plan'}),
               'wall_time_s': time.monotonic() - t0}
    (args.out / 'run.json').write_text(json.dumps(summary, indent=2, default=str))
    log(f'{"DONE" if summary["ok"] else "FAILED"} in {summary["wall_time_s"]:.1f} s; see {args.out}/report.md')
    return 0 if summary['ok'] else 1


if __name__ == '__main__':
    sys.exit(main())
