"""The demo's scenario 4: a wider tree harvested by two arms (``picking-stack --platform``, ``picking-goal
tree``), recorded to ``platform.mcap`` and reported with ``platform.png``."""

from __future__ import annotations

import os
import time
from functools import partial

import numpy as np

from picking_common.middleware import use_fast_discovery
from picking_common.status import status_values
from picking_description import platform_path

from .demo_report import _table, log, run_tool, stop_stack
from .shipped import shipped_harvest
from .stack import BIN, PlatformStack


def run_platform_scenario(config, out, demo):
    """Start the platform, harvest the tree, stop it; returns ``(report lines, files, checks)``."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticStatus
    from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
    from sensor_msgs.msg import JointState
    from visualization_msgs.msg import MarkerArray

    from picking_common.run import BackgroundSpin
    from picking_core.platform import Platform

    from .demo_report import harvest_markers
    from .recording import Recorder

    n, seed = int(demo.get('platform_apples', 40)), int(demo.get('platform_seed', 1))
    layout = str(demo.get('platform_layout', 'two'))
    platform = Platform.from_yaml(platform_path(), layout)
    names = [m.namespace for m in platform.arms]
    log(f'scenario 4, one tree, {len(names)} arms ({", ".join(names)}, layout {layout!r} of platform.yaml): '
        f'{n} apples (seed {seed}), harvested with picking-goal tree')
    stack = PlatformStack(platform_path(), layout, '/', out / 'logs', config=config)
    for p in stack.processes:
        log(f'started {p.name} ({p.log_path.parent.name}, pid {p.pid})')
    use_fast_discovery()
    rclpy.init()
    node = rclpy.create_node(f'picking_demo_platform_{os.getpid()}')
    reliable = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    rec = Recorder(node, {'/harvester_status': DiagnosticStatus, '/tree_markers': MarkerArray}, reliable)
    rec.add(node, {f'/{ns}/joint_states': JointState for ns in names}, qos_profile_sensor_data)
    rec.add_frames(node, names)
    markers = node.create_publisher(MarkerArray, '/tree_markers', 10)
    spinner = BackgroundSpin(node)
    done, wall = None, float('nan')
    try:
        log(f'waiting for the {len(names)} arms and the coordinator to come up')
        stack.wait_ready()
        t0 = time.monotonic()
        done = run_tool([BIN / 'picking-goal', 'tree', '--tree', n, '--seed', seed, '--platform', platform_path(),
                         '--layout', layout, '--timeout', 120], 180 + 10 * n)
        wall = time.monotonic() - t0
    except RuntimeError as exc:
        log(f'FAILED: {exc}')
    finally:
        codes = stop_stack(stack)
    tree = platform.tree(n, seed=seed)
    statuses = [m for _, m in rec.messages('/harvester_status')]
    final = next((m for m in reversed(statuses) if status_values(m).get('state') in ('succeeded', 'aborted')), None)
    by_arm = {ns: [] for ns in names}
    for m in statuses:
        for ns in names:
            if m.message.startswith(f'{ns}: apple ') and ' delivered' in m.message:
                by_arm[ns].append(int(m.message.split()[2]))
    left = {int(m.message.split()[1]): m.message.split(': ', 1)[1] for m in statuses
            if m.message.startswith('apple ') and 'left on the tree' in m.message}
    from std_msgs.msg import Header
    said = {'picked': [(i, 0.0) for ns in names for i in by_arm[ns]], 'skipped': list(left.items())}
    markers.publish(harvest_markers(tree, said, Header(frame_id=platform.frame)))
    deadline = time.monotonic() + 5.0
    while rec.count('/tree_markers') == 0 and time.monotonic() < deadline:
        time.sleep(0.05)
    spinner.stop(2.0)
    node.destroy_node()
    rclpy.try_shutdown()

    return platform_report(rec, platform, names, tree, by_arm, left, final, statuses, codes, done, wall, n, seed,
                           layout, config, out, demo)


def platform_report(rec, platform, names, tree, by_arm, left, final, statuses, codes, done, wall, n, seed, layout,
                    config, out, demo):
    """The scenario's section: its checks, the arms' rates, the decisions that kept them apart, ``platform.png``
    and ``platform.mcap``; ``(lines, files, checks)``."""
    from picking_core.platform import Coordinator

    from .plots import plot_platform
    coordinator = Coordinator.from_platform(platform, partial(shipped_harvest, config))
    files, checks = [], {}
    ok_run = done is not None and done.returncode == 0 and final is not None
    checks['the two-arm harvest succeeded'] = ok_run and status_values(final).get('state') == 'succeeded'
    checks['every node of the platform exited with 0'] = set(codes.values()) == {0}
    if final is None:
        return ['', '## Scenario 4: one tree, two arms', '', 'The harvest did not end: see the logs.'], files, checks
    v = status_values(final)
    measured = float(v.get('closest_measured', 'nan'))
    checks['the arms never came within 5 cm (measured)'] = measured >= coordinator.clearance
    checks['every apple the coordinator counts is drawn for its arm'] = (
        sum(len(apples) for apples in by_arm.values()) == int(v.get('picked', -1)))
    tools = {}
    for k, (ns, mount) in enumerate(zip(names, platform.arms)):
        arm = coordinator.harvests[k].arm
        q = np.array([list(m.position)[:arm.dof] for _, m in rec.messages(f'/{ns}/joint_states')
                      if len(m.position) >= arm.dof])
        tools[ns] = (mount.base @ arm.fk(q))[:, :3, 3] if len(q) else np.empty((0, 3))
    drawn = _grasp_drawings(coordinator, tree, by_arm)
    files.append(plot_platform(out / 'platform.png', tree, by_arm, sorted(left), tools,
                               [m.base[:3, 3] for m in platform.arms], drawn,
                               f'Scenario 4: {n} apples, {len(names)} arms'))
    path, count = rec.write_mcap(out / 'platform.mcap')
    files.append(path)
    per = [(ns, v.get(f'{ns}_picked', '0'), f'{float(v.get(f"{ns}_apples_per_hour", "nan")):.0f}') for ns in names]
    total = float(v.get('apples_per_hour', 'nan'))
    one = demo.get('one_arm_rate')
    decisions = [m.message.split(': ', 1)[1] for m in statuses if m.message.startswith('round ') and
                 ('waits' in m.message or 'went from' in m.message or 'postponed' in m.message.split(';')[0])]
    lines = ['', '## Scenario 4: one tree, two arms', '',
             f'{n} apples of a tree {len(names)} arms wide (`picking-goal tree --tree {n} --seed {seed}`, '
             f'layout `{layout}` of `picking_description/platforms/platform.yaml`, the arms\' loops at the shared rates of `picking-stack '
             f'--platform`): **{v.get("picked")} of {v.get("apples")} picked** in {float(v.get("harvest_time", "nan")):.1f} s '
             f'from the first plan\'s start, **{total:.0f} apples an hour in all**'
             + (f' ({total / one:.2f} times scenario 3\'s one arm, which drops into its side box; these drop onto '
                'the platform\'s conveyor in front of them)' if one else '') +
             f'; {float(v.get("closest_planned", "nan")) * 100:.1f} cm the closest approach between the arms as '
             f'planned, **{measured * 100:.1f} cm as measured** from their joint states (the clearance kept: '
             f'{coordinator.clearance * 100:.0f} cm). {wall:.0f} s from sending the tree, its planning included.', '',
             _table(['arm', 'apples picked', 'apples an hour'], per), '',
             'Decisions that kept the arms apart: ' + ('; '.join(decisions) if decisions else 'none were needed')
             + '. Apples left: ' + ('; '.join(f'{i} ({why})' for i, why in sorted(left.items())) if left else 'none')
             + '.', '',
             '`platform.png`: the tree from the front and from above, each arm\'s apples and tool path, the arms '
             f'drawn at their first and last grasps; `platform.mcap` ({count} messages): both arms\' joint states, '
             'the coordinator\'s statuses and the tree as visualization_msgs/MarkerArray on `/tree_markers`.']
    lines += ['', *[f'- {k}: {"yes" if ok else "NO"}' for k, ok in checks.items()]]
    return lines, files, checks


def _grasp_drawings(coordinator, tree, by_arm):
    """Each arm's links (joint origins, platform frame) at the grasps of its first and last apples."""
    from picking_core.kinematics import Unreachable
    out = []
    for k, (ns, picked) in enumerate(by_arm.items()):
        if not picked:
            continue
        arm, base = coordinator.harvests[k].arm, coordinator.platform.arms[k].base
        for i in (picked[0], picked[-1]):
            try:
                q = arm.ik(coordinator.in_base(k, [tree[i]])[0], seed=coordinator.harvests[k].home)
            except Unreachable:
                continue
            frames = base @ arm.joint_frames(q[None])[0]
            out.append((ns, np.vstack([base[:3, 3], frames[:, :3, 3]])))
    return out
