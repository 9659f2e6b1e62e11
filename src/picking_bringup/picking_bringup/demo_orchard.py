"""The demo's scenario 5: a tree among branches harvested with branch awareness, then once more with
collision checking off as the baseline; the simulator counts the contacts of each. Recorded to
``orchard.mcap`` (joint states, statuses, contacts, the scene as MarkerArray, the cloud as
PointCloud2) and reported with ``orchard.png``."""

from __future__ import annotations

import os
import time

import numpy as np

from picking_common.middleware import use_fast_discovery
from picking_common.status import status_values

from .demo_report import _table, log, stop_stack
from .stack import Stack

FINAL = ('succeeded', 'aborted', 'refused', 'superseded', 'canceled')


def run_orchard_scenario(config, out, demo):
    """Start one arm, give it the tree's scene and cloud, harvest twice, stop it; returns
    ``(report lines, files, checks)``."""
    import rclpy
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient

    from picking_common.scene_msgs import cloud_message, scene_markers

    from .shipped import shipped_orchard

    n, seed = int(demo.get('orchard_apples', 12)), int(demo.get('orchard_seed', 1))
    orchard = shipped_orchard(n, seed, demo.get('arm'), config)
    log(f'scenario 5, a tree among branches: {n} apples (seed {seed}), {len(orchard.scene)} obstacles in the scene, '
        f'{len(orchard.twigs)} twigs in a cloud of {len(orchard.cloud)} points; harvested with branch awareness, '
        'then with collision checking off')
    arm = _OrchardArm('/orchard', config, out, demo.get('arm'))
    runs, codes = {}, {}
    try:
        arm.stack.wait_ready()
        arm.wait(lambda: arm.scene_pub.get_subscription_count() >= 2 and arm.cloud_pub.get_subscription_count() >= 1,
                 20.0, 'the planner and the simulator on scene and canopy_points')
        arm.scene_pub.publish(scene_markers(orchard.scene, 'base_link'))
        planner, sim = arm.stack.planner, arm.stack.sim
        arm.wait(lambda: 'canopy from canopy_points' in planner.output() and 'scene replaced' in planner.output()
                 and 'from the scene topic' in sim.output(), 20.0, 'the scene and the cloud',
                 (arm.cloud_pub, cloud_message(orchard.cloud, 'base_link')))
        runs['branch-aware'] = arm.harvest('branch-aware', orchard.apples)
        client = AsyncParameterClient(arm.node, 'picking_planner')
        client.wait_for_services(timeout_sec=10.0)
        done = client.set_parameters([Parameter('avoid_collisions', value=False)])
        arm.wait(done.done, 10.0, 'avoid_collisions set to false')
        runs['checking off'] = arm.harvest('checking off', orchard.apples)
    except RuntimeError as exc:
        log(f'FAILED: {exc}')
    finally:
        codes = stop_stack(arm.stack)
    arm.close()
    rclpy.try_shutdown()
    return orchard_report(arm.rec, arm.ns, runs, codes, orchard, n, seed, out, demo)


class _OrchardArm:
    """The orchard's arm (a stack in ``ns``), this scenario's node on its topics, and what it records."""

    def __init__(self, ns, config, out, arm=None):
        import rclpy
        from diagnostic_msgs.msg import DiagnosticStatus
        from geometry_msgs.msg import PoseArray
        from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
        from sensor_msgs.msg import JointState, PointCloud2
        from visualization_msgs.msg import MarkerArray

        from picking_common.run import BackgroundSpin
        from picking_common.topics import BURST, LATCHED

        from .recording import Recorder
        self.ns = ns
        self.stack = Stack(ns, out / 'logs', config=config, arm=arm)
        use_fast_discovery()
        rclpy.init()
        self.node = rclpy.create_node(f'picking_demo_orchard_{os.getpid()}', namespace=ns)
        reliable = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        rec = self.rec = Recorder(self.node, {f'{ns}/planner_status': DiagnosticStatus,
                                              f'{ns}/sim_contacts': DiagnosticStatus}, reliable)
        rec.add(self.node, {f'{ns}/joint_states': JointState}, qos_profile_sensor_data)
        rec.add(self.node, {f'{ns}/scene': MarkerArray}, LATCHED)
        rec.add(self.node, {f'{ns}/canopy_points': PointCloud2}, reliable)
        rec.add_frames(self.node, [ns])
        self.scene_pub = self.node.create_publisher(MarkerArray, 'scene', LATCHED)
        self.cloud_pub = self.node.create_publisher(PointCloud2, 'canopy_points', reliable)
        self.harvest_pub = self.node.create_publisher(PoseArray, 'harvest_targets', BURST)
        self.spinner = BackgroundSpin(self.node)

    def close(self):
        self.spinner.stop(2.0)
        self.node.destroy_node()

    def wait(self, pred, timeout, what, publishing=None, progress=None):
        """Until ``pred()``; ``publishing = (publisher, msg)`` sent every 0.2 s meanwhile, as a camera
        sends its clouds (the planner takes them best effort: any one may be dropped); ``progress()`` called
        at every look (to log what happened since the last)."""
        end, sent = time.monotonic() + timeout, -1.0
        while not pred():
            if progress is not None:
                progress()
            if time.monotonic() > end:
                raise RuntimeError(f'timed out waiting for {what}')
            if not all(self.stack.alive().values()):
                raise RuntimeError(f'a node exited while waiting for {what}')
            if publishing is not None and time.monotonic() - sent >= 0.2:
                publishing[0].publish(publishing[1])
                sent = time.monotonic()
            time.sleep(0.05)

    def statuses(self, key):
        return [m for _, m in self.rec.messages(f'{self.ns}/planner_status') if status_values(m).get('goal') == key]

    def harvest(self, label, apples):
        """One harvest of ``apples`` (4x4 grasp poses) from where the arm rests, each status logged as it comes:
        ``(goal, final status values, statuses, contacts the simulator reported)``."""
        from geometry_msgs.msg import PoseArray

        from picking_common.poses import pose_msg
        msg = PoseArray(poses=[pose_msg(T) for T in apples])
        msg.header.frame_id = 'base_link'
        msg.header.stamp = self.node.get_clock().now().to_msg()
        key = f'{msg.header.stamp.sec}.{msg.header.stamp.nanosec:09d}'
        contacts_before = self.rec.count(f'{self.ns}/sim_contacts')
        self.harvest_pub.publish(msg)
        t0, told = time.monotonic(), [0]

        def ended():
            return next((m for m in self.statuses(key) if status_values(m).get('state') in FINAL), None)

        def progress():
            said = self.statuses(key)
            for m in said[told[0]:]:
                log(f'  {label} {time.monotonic() - t0:6.1f} s  {m.message}')
            told[0] = len(said)
        self.wait(lambda: ended() is not None, 120.0 + 15.0 * len(apples), f'the {label} harvest to end',
                  progress=progress)
        time.sleep(0.5)                                   # the witness's last look
        final = status_values(ended())
        contacts = [status_values(m) for _, m in self.rec.messages(f'{self.ns}/sim_contacts')[contacts_before:]
                    if status_values(m).get('state') == 'started']
        log(f'  {label}: {final.get("state")}, {final.get("picked", "0")} of {len(apples)} picked, '
            f'{len(contacts)} contacts reported by the simulator ({time.monotonic() - t0:.0f} s)')
        return key, final, self.statuses(key), contacts


def orchard_report(rec, ns, runs, codes, orchard, n, seed, out, demo):
    """The scenario's section: its checks, a table of both runs, the contacts, ``orchard.png`` and ``orchard.mcap``;
    ``(lines, files, checks)``."""
    from picking_core.kinematics import ArmModel
    from picking_description import DEFAULT_ARM, urdf_path

    from .plots import plot_orchard
    checks = {'every node of the orchard arm exited with 0': set(codes.values()) == {0}}
    title = '## Scenario 5: a tree among branches'
    if len(runs) < 2:
        checks['both harvests ended'] = False
        return ['', title, '', 'A harvest did not end: see the logs.'], [], checks
    arm = ArmModel.from_urdf(urdf_path(demo.get('arm') or DEFAULT_ARM))
    states = [m for _, m in rec.messages(f'{ns}/joint_states') if set(arm.joint_names) <= set(m.name)]
    q = np.array([[m.position[list(m.name).index(j)] for j in arm.joint_names] for m in states])
    t = np.array([m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in states])
    tool = arm.fk(q)[:, :3, 3] if len(q) else np.empty((0, 3))
    second = float(runs['checking off'][0])                  # the baseline's goal stamp: its tool path after it
    tools = {'branch-aware': tool[t < second], 'checking off': tool[t >= second]}
    picked = _apples(runs['branch-aware'][2], 'picked')
    skipped = {i: why for i, why in _apples(runs['branch-aware'][2], 'skipped', reasons=True)}
    files = [plot_orchard(out / 'orchard.png', orchard, picked, sorted(skipped), tools,
                          f'Scenario 5: {n} apples among branches')]
    path, count = rec.write_mcap(out / 'orchard.mcap')
    files.append(path)
    clear = demo.get('clear_apples')
    aware, base = runs['branch-aware'], runs['checking off']
    rows = []
    for label, (_, final, _, contacts) in runs.items():
        rows.append((label, f'{final.get("picked", "0")} of {n}', str(len(contacts)),
                     f'{float(final.get("harvest_time", "nan")):.1f}', f'{float(final.get("apples_per_hour", "nan")):.0f}'))
    per = [float(r[1].get('harvest_time', 'nan')) / max(1, int(r[1].get('picked', 0))) for r in (aware, base)]
    checks['the branch-aware harvest made no contact'] = aware[3] == []
    checks['the baseline without checking touched a branch (the witness sees)'] = len(base[3]) > 0
    if clear:
        checks['at least 90 % of the apples with a clear approach were picked'] = len(picked) >= 0.9 * clear
    lines = ['', title, '',
             f'A seeded orchard tree (`orchard_tree({n}, seed={seed})`): {len(orchard.scene)} obstacles in the '
             f'scene (trunk, scaffold branches, two trellis wires, the workcell), published on `scene`; '
             f'{len(orchard.twigs)} twigs hanging across the straight approach of apples '
             f'{", ".join(str(i) for i in orchard.blocked) or "none"} (in the scene, and with the scaffolds and the '
             f'trunk in a cloud of {len(orchard.cloud)} points on `canopy_points`). The same tree harvested twice '
             'from home: with branch awareness, then with `avoid_collisions` set to false (the baseline); the '
             'simulator, as a witness, reports every contact of the measured arm with the scene on `sim_contacts`.',
             '',
             _table(['run', 'apples picked', 'contacts (simulator)', 'harvest time [s]', 'apples an hour'], rows), '',
             (f'{clear} of the {n} apples have a clear cycle within the 45° cone when each is planned alone from home '
              f'(the planner\'s own check): {len(picked)} picked, {100 * len(picked) / clear:.0f} %. ' if clear else '')
             + f'Time per picked apple: {per[0]:.2f} s with branch awareness, {per[1]:.2f} s without '
             f'({per[0] - per[1]:+.2f} s: the detours). Skipped: '
             + ('; '.join(f'{i} ({why})' for i, why in sorted(skipped.items())) if skipped else 'none') + '.',
             '', 'Contacts of the baseline (t from its harvest goal): '
             + ('; '.join(f'{c["link"]} on {c["obstacle"]} at t = {float(c["start"]) - float(base[0]):.2f} s, '
                          f'{float(c["depth"]) * 100:.1f} cm deep' for c in base[3][:6]) if base[3] else 'none') + '.', '',
             '`orchard.png`: the tree from the front and from above, branches and wires as wide as they are, the '
             'twigs, both runs\' tool paths; `orchard.mcap` ({count} messages): joint states, statuses, the '
             'simulator\'s contacts, the scene as MarkerArray on `scene` and the cloud as PointCloud2 on '
             '`canopy_points`, for Foxglove.'.replace('{count}', str(count))]
    lines += ['', *[f'- {k}: {"yes" if ok else "NO"}' for k, ok in checks.items()]]
    return lines, files, checks


def _apples(statuses, word, reasons=False):
    """The apple indices a harvest's statuses report as ``word`` (picked, skipped), in order."""
    out = []
    for m in statuses:
        v = status_values(m)
        if v.get('apple_state') == word and 'apple' in v:
            out.append((int(v['apple']), m.message.split(f'{word}: ', 1)[-1]) if reasons else int(v['apple']))
    return out


def clear_apples(orchard, config, arm=None):
    """How many of the tree's apples have a clear cycle within the cone, each planned alone from home
    with the planner's own check (the benchmark's denominator)."""
    from picking_core.collision import Canopy, CollisionChecker
    from picking_core.kinematics import Unreachable
    from picking_core.kinematics.capsules import ArmCapsules
    from picking_core.pick_cycle import PickCycle

    from .shipped import shipped_harvest
    cycle = shipped_harvest(config, arm).cycle
    checker = CollisionChecker(ArmCapsules.from_arm(cycle.arm), orchard.scene, Canopy(orchard.cloud))
    pick = PickCycle(cycle.planner, cycle.s, checker)
    home = np.asarray(cycle.s.home_positions, float)
    count = 0
    for T in orchard.apples:
        try:
            pick.plan((home, 0 * home, 0 * home), T)
            count += 1
        except Unreachable:
            pass
    return count
