"""The nodes as processes: goal latency over DDS, the 1 kHz loop, several arms on one machine.

Every process runs with ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST and the run's own
ROS_DOMAIN_ID (set by run.py before rclpy loads), and is stopped by its pid.
"""

from __future__ import annotations

import os
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from harness import fmt_time
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from scipy.spatial.transform import Rotation
from trajectory_msgs.msg import JointTrajectory

from picking_bringup.stack import Stack, stop_all
from picking_common.middleware import use_fast_discovery
from picking_common.run import SWITCH_INTERVAL
from picking_common.topics import BURST, LatestMessage

ROOT = Path(__file__).resolve().parents[1]
RELIABLE = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
# Two reachable tool positions near the home pose, visited in turn.
POSES = ([0.55, 0.10, 0.45], [0.50, -0.10, 0.40])
# What row 4 asks of a controller loop.
P99_GOAL_US, MISSED_GOAL_PERCENT, CPU_GOAL_PERCENT = 100.0, 0.1, 30.0


def cpu_seconds(pid):
    """User + system CPU time of a process so far, s (from /proc)."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


DOWN = Rotation.from_euler('xyz', [180, 0, 0], degrees=True).as_quat()


class Watcher:
    """Sends pose goals to one arm, times its trajectories and keeps its controller's loop figures."""

    def __init__(self, ns):
        if not rclpy.ok():
            use_fast_discovery()
            rclpy.init()
        self.node = rclpy.create_node(f'bench_watcher_{os.getpid()}_{ns.strip("/")}', namespace=ns)
        self.arrivals = []
        # Raw: the arrival time, without this client's own (slow, Python) deserialisation in it.
        self.node.create_subscription(JointTrajectory, 'planned_trajectory', self._on_trajectory, RELIABLE, raw=True)
        self.answers = []
        self.node.create_subscription(DiagnosticStatus, 'planner_status', self.answers.append, BURST)
        self.pub_pose = self.node.create_publisher(PoseStamped, 'goal_pose', BURST)
        # The controller's loop figures, taken on demand (no executor callback to starve when
        # several stacks load the machine).
        self.loop_tap = LatestMessage(self.node, DiagnosticStatus, 'controller_loop')
        self.event = threading.Event()
        self._executor = SingleThreadedExecutor()
        self._executor.add_node(self.node)
        self._closing = threading.Event()
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self):
        while not self._closing.is_set():
            self._executor.spin_once(timeout_sec=0.05)

    def _on_trajectory(self, msg):
        self.arrivals.append(time.monotonic())
        self.event.set()

    def wait_ready(self, timeout):
        """Until the planner hears this watcher's goals."""
        end = time.monotonic() + timeout
        while self.pub_pose.get_subscription_count() == 0:
            if time.monotonic() > end:
                raise RuntimeError(f'no planner subscribed to {self.pub_pose.topic_name} within {timeout:g} s')
            time.sleep(0.05)

    def send_pose(self, xyz):
        msg = PoseStamped()
        msg.header.frame_id = 'base_link'
        msg.header.stamp = self.node.get_clock().now().to_msg()
        msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = map(float, xyz)
        (msg.pose.orientation.x, msg.pose.orientation.y, msg.pose.orientation.z,
         msg.pose.orientation.w) = map(float, DOWN)
        self.pub_pose.publish(msg)

    def loop_report_after(self, previous, timeout=10.0):
        """The figures of the first controller_loop report newer than the message ``previous``
        (None if none comes within ``timeout`` s)."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            msg = self.loop_tap.take()
            if msg is not None and msg is not previous:
                return {kv.key: float(kv.value) for kv in msg.values}
            time.sleep(0.1)
        return None

    def close(self):
        self._closing.set()
        self._thread.join(timeout=10.0)
        self._executor.shutdown()
        self.loop_tap.destroy()
        self.node.destroy_node()


def _stacks(n, rate, log_dir, phased=True):
    # The loop threads under SCHED_FIFO as config/controller.yaml and config/sim.yaml set them (where allowed),
    # the controller's executor thread just below its loop and each loop at its own phase of the period, as the
    # README advises for several arms (phased=False: free running).
    stacks = []
    for i in range(n):
        cp, sp = ((i / n, (i + 0.5) / n) if phased else (-1.0, -1.0))
        rate_args = ('-p', f'update_rate:={rate}', '-p', 'thread_priority:=50', '-p', 'executor_priority:=40',
                     '-p', f'loop_phase:={cp}')
        sim_args = ('-p', 'initial_positions:=[0.0,0.2,1.6,0.0,1.3,0.0,0.09]', '-p', f'servo_rate:={rate}', '-p', f'publish_rate:={min(100.0, rate)}', '-p', 'thread_priority:=49',
                    '-p', f'loop_phase:={sp}')
        stacks.append(Stack(f'/bench{i}', log_dir, files={'picking-planner': ('planner.yaml',)},
                            args={'picking-sim': list(sim_args), 'picking-controller': list(rate_args)}))
    return stacks


def goal_latency(n_goals=200, gap=0.05):
    """Publish pose goals one by one; time from publish to the JointTrajectory's arrival."""
    with tempfile.TemporaryDirectory() as log_dir:
        (stack,) = _stacks(1, 1000.0, log_dir)
        watcher = Watcher('/bench0')
        try:
            stack.wait_ready(60.0)
            watcher.wait_ready(60.0)
            lat, lost = [], 0
            for i in range(n_goals + 5):
                watcher.event.clear()
                mark = len(watcher.answers)
                t0 = time.monotonic()
                watcher.send_pose(POSES[i % 2])
                if not watcher.event.wait(2.0):
                    lost += 1
                    answers = watcher.answers[mark:]
                    print(f'    goal {i}: no trajectory within 2 s; planner said: '
                          f'{answers[0].message if answers else "nothing"}', flush=True)
                    continue
                if i >= 5:                            # the first few warm the caches up
                    lat.append(watcher.arrivals[-1] - t0)
                time.sleep(gap)
                if i % 50 == 0:
                    print(f'    goal {i}/{n_goals + 5}', flush=True)
        finally:
            watcher.close()
            codes = stack.stop()
    lat = np.array(lat)
    print(f'    {len(lat)} goals, {lost} without a trajectory, exit codes {codes}', flush=True)
    return lat, lost


def retarget_latency(seconds=10.0, rate=30.0):
    """A pose goal, then its target moved at ``rate`` Hz for ``seconds`` s (a point circling 5 cm): for each
    re-target the controller spliced, the time from its stamp (when it was published) to when the controller put
    its plan on the schedule (the ``spliced_at`` of its "trajectory accepted", on the same clock); and how many
    were replaced by a newer one."""
    with tempfile.TemporaryDirectory() as log_dir:
        (stack,) = _stacks(1, 1000.0, log_dir)
        watcher = Watcher('/bench0')
        accepted, by_stamp, sent = {}, {}, {}
        node = watcher.node
        # (Two plans may share a stamp: the newer one replaces the older at the same instant. Paired in order.)
        node.create_subscription(DiagnosticStatus, 'controller_status', lambda m: accepted.setdefault(
            _values(m).get('trajectory'), []).append(float(_values(m)['spliced_at'])) if m.message.startswith(
                'trajectory accepted') else None, BURST)
        retarget = node.create_publisher(PoseStamped, 'retarget', BURST)
        try:
            stack.wait_ready(60.0)
            watcher.wait_ready(60.0)
            while retarget.get_subscription_count() == 0:
                time.sleep(0.05)
            watcher.send_pose(POSES[0])
            time.sleep(1.0)
            start, k = time.monotonic(), 0
            while time.monotonic() - start < seconds:
                k += 1
                a = 2 * np.pi * k / (2 * rate)
                msg = _pose_msg(node, np.array(POSES[0]) + 0.05 * np.array([0.0, np.cos(a), np.sin(a)]))
                sent[f'{msg.header.stamp.sec}.{msg.header.stamp.nanosec:09d}'] = \
                    msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
                retarget.publish(msg)
                time.sleep(max(0.0, start + k / rate - time.monotonic()))
            time.sleep(2.0)
            for m in list(watcher.answers):
                values = _values(m)
                if values.get('state') == 'accepted' and values.get('retarget') in sent:
                    by_stamp[values['retarget']] = (values['trajectory'], sum(
                        1 for tr, _ in by_stamp.values() if tr == values['trajectory']))

        finally:
            watcher.close()
            codes = stack.stop()
    lat = np.array([accepted[tr][k] - sent[s] for s, (tr, k) in sorted(by_stamp.items())
                    if k < len(accepted.get(tr, ()))])
    print(f'    {len(sent)} re-targets, {len(lat)} spliced, exit codes {codes}', flush=True)
    return lat, len(sent)


def stop_latency(runs=10):
    """A pose goal moving the arm slowly, then ``picking-goal stop`` started as a user would from another shell: for
    each run, from the stop's process start to the controller's "braking" status (the arm decelerating), and to
    the process's exit."""
    import subprocess
    with tempfile.TemporaryDirectory() as log_dir:
        stack = Stack('/bench0', log_dir, files={'picking-planner': ('planner.yaml',)},
                      args={'picking-planner': ['-p', 'speed_scale:=0.2']})
        watcher = Watcher('/bench0')
        braking = []
        watcher.node.create_subscription(DiagnosticStatus, 'controller_status', lambda m: braking.append(
            time.monotonic()) if m.message.startswith('goal canceled: braking') else None, BURST)
        brake, leave = [], []
        try:
            stack.wait_ready(60.0)
            watcher.wait_ready(60.0)
            for i in range(runs):
                watcher.event.clear()
                watcher.send_pose(POSES[i % 2])
                if not watcher.event.wait(5.0):
                    print(f'    stop {i}: the pose goal planned no trajectory', flush=True)
                    continue
                time.sleep(0.5)                                    # the arm under way
                mark = len(braking)
                t0 = time.monotonic()
                done = subprocess.run([str(Path(sys.executable).parent / 'picking-goal'), 'stop', '--ros-args', '-r',
                                       '__ns:=/bench0'], capture_output=True, text=True, timeout=60)
                leave.append(time.monotonic() - t0)
                end = time.monotonic() + 5.0
                while len(braking) == mark and time.monotonic() < end:
                    time.sleep(0.01)
                if len(braking) > mark:
                    brake.append(braking[mark] - t0)
                else:
                    print(f'    stop {i}: no braking reported ({done.stdout.strip() or done.stderr.strip()})', flush=True)
                time.sleep(1.0)                                    # at rest again
        finally:
            watcher.close()
            codes = stack.stop()
    print(f'    {len(brake)} of {runs} stops braked the arm, exit codes {codes}', flush=True)
    return np.array(brake), np.array(leave), runs


def _values(msg):
    return {kv.key: kv.value for kv in msg.values}


def _pose_msg(node, xyz):
    msg = PoseStamped()
    msg.header.frame_id = 'base_link'
    msg.header.stamp = node.get_clock().now().to_msg()
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = map(float, xyz)
    (msg.pose.orientation.x, msg.pose.orientation.y, msg.pose.orientation.z, msg.pose.orientation.w) = map(float, DOWN)
    return msg


#: s for a run's stacks to come up (planners and controllers discovered by the benchmark's clients).
READY_TIMEOUT = 90.0


class StacksNotReady(RuntimeError):
    """The stacks' planners and controllers did not all come up in time (an overloaded machine)."""


def run_stacks(n, rate, seconds, goal_every=2.0, ready_timeout=READY_TIMEOUT):
    """N stacks at ``rate`` Hz for ``seconds`` with a goal every ``goal_every`` s each.

    Returns one dict per controller: its own loop figures (since it began
    commanding) and its process CPU over the window, % of one core. Raises
    StacksNotReady if they are not all up within ``ready_timeout`` s.
    """
    with tempfile.TemporaryDirectory() as log_dir:
        stacks = _stacks(n, rate, log_dir)
        watchers = []
        try:
            watchers = [Watcher(s.ns) for s in stacks]
            for s, w in zip(stacks, watchers):
                try:
                    s.wait_ready(ready_timeout)
                    w.wait_ready(ready_timeout)
                except RuntimeError as exc:
                    raise StacksNotReady(f'{n} stacks at {rate:g} Hz: {exc}') from None
            time.sleep(1.0)
            cpu0 = [cpu_seconds(s.controller.pid) for s in stacks]
            t0 = time.monotonic()
            k = 0
            while time.monotonic() - t0 < seconds:
                for w in watchers:
                    w.send_pose(POSES[k % 2])
                k += 1
                time.sleep(goal_every)
            wall = time.monotonic() - t0
            cpu = [100.0 * (cpu_seconds(s.controller.pid) - c) / wall for s, c in zip(stacks, cpu0)]
            # One more loop report after the window from every controller.
            last = [w.loop_tap.take() for w in watchers]
            out = []
            for w, c, previous in zip(watchers, cpu, last):
                figures = w.loop_report_after(previous) or {}
                figures['cpu_window_percent'] = c
                out.append(figures)
        finally:
            for w in watchers:
                w.close()
            stop_all([p for s in stacks for p in s.processes])
    return out


def meets_row4(f):
    return (f.get('period_error_p99_us', np.inf) <= P99_GOAL_US
            and f.get('missed_percent', np.inf) < MISSED_GOAL_PERCENT
            and f.get('cpu_window_percent', np.inf) <= CPU_GOAL_PERCENT)


def loop_row(figures, label):
    f = figures
    return ['4', label, f'p99 {f["period_error_p99_us"]:.0f} µs, {f["missed_percent"]:.3f} % missed, '
                        f'CPU {f["cpu_window_percent"]:.1f} %',
            f'{f["rate_hz"]:.1f} Hz; period error p50 {f["period_error_p50_us"]:.0f} µs, max '
            f'{f["period_error_max_us"]:.0f} µs; {f["missed"]:.0f} of {f["ticks"]:.0f} ticks missed',
            'p99 ≤ 100 µs, < 0.1 % missed, ≤ 30 % CPU', 'met' if meets_row4(f) else 'missed']


def arms(rate, max_n, seconds):
    """N = 1..max_n stacks side by side: ``(best, seen, missed)``, the largest N whose controllers all
    meet row 4, each N's figures, and the smaller N that missed (a noisy minute can fail N = 1 while
    more arms meet it; the table says so instead of hiding either).

    Every N is measured (and reported) until the controllers no longer keep even
    90 % of their rate, or the stacks do not all come up.
    """
    best, seen, missed = 0, [], []
    for n in range(1, max_n + 1):
        try:
            figures = run_stacks(n, rate, seconds)
        except StacksNotReady as exc:
            # Too loaded even to start: no larger N would do better (the table keeps the rows so far).
            seen.append(f'N={n}: not all up within {READY_TIMEOUT:g} s (overloaded)')
            print(f'    {rate:g} Hz, {seen[-1]}: {exc}', flush=True)
            break
        reported = [f for f in figures if 'period_error_p99_us' in f]
        ok = len(reported) == n and all(meets_row4(f) for f in figures)
        if reported:
            seen.append(f'N={n}: worst p99 {max(f["period_error_p99_us"] for f in reported):.0f} µs, '
                        f'missed {max(f["missed_percent"] for f in reported):.2f} %, CPU '
                        f'{max(f["cpu_window_percent"] for f in figures):.0f} %, slowest '
                        f'{min(f["rate_hz"] for f in reported):.0f} Hz')
        else:
            seen.append(f'N={n}: no controller reported')
        if len(reported) < n:
            # Too loaded to send its loop figures within 10 s: it does not meet row 4.
            seen[-1] += f' ({n - len(reported)} of {n} controllers sent no loop figures: overloaded)'
        slowest = min(f.get('rate_hz', 0.0) for f in figures) if figures else 0.0
        print(f'    {rate:g} Hz, {seen[-1]}', flush=True)
        if ok:
            best = n
        else:
            missed.append(n)
        if slowest < 0.9 * rate:
            break
    return best, seen, [n for n in missed if n < best]


LOOP_SCRIPT = """
import os, random, sys, threading, time
sys.path[:0] = sys.argv[2:3]
from picking_common.loop_stats import LoopStats
from picking_common.run import SWITCH_INTERVAL
sys.setswitchinterval(SWITCH_INTERVAL)
period, seconds, contended = 1e-3, float(sys.argv[1]), sys.argv[3] == 'contended'
stats = LoopStats(period)
done = threading.Event()
def loop():
    try:                                   # as the controller's loop thread, where allowed
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(50))
    except (PermissionError, OSError):
        pass
    next_t = time.monotonic()
    while not done.is_set():
        stats.record(time.monotonic())
        next_t += period
        delay = next_t - time.monotonic()
        if delay > 0:
            time.sleep(delay)
thread = threading.Thread(target=loop)
thread.start()
end, x = time.monotonic() + seconds, 0
while time.monotonic() < end:
    if not contended:
        time.sleep(0.1)
        continue
    burst = time.monotonic() + random.uniform(0.0, 2e-3)     # Python in bursts of up to 2 ms
    while time.monotonic() < burst:
        for i in range(100):
            x += i * i
    time.sleep(random.uniform(0.0, 2e-3))
done.set()
thread.join()
s = stats.summary()
print(s['period_error_p50_us'], s['period_error_p99_us'], s['period_error_max_us'], s['missed_percent'])
"""


def bare_loop(seconds):
    """The machine's floor: a Python thread that only sleeps to 1 ms deadlines (real-time where allowed, as the
    controller's), nothing else running."""
    return _loop_figures(seconds, 'bare')


def contended_loop(seconds):
    """The GIL's share: the same loop while another thread of its process runs Python code in bursts
    of up to 2 ms (with the nodes' switch interval)."""
    return _loop_figures(seconds, 'contended')


def _loop_figures(seconds, mode):
    import subprocess
    out = subprocess.run([sys.executable, '-c', LOOP_SCRIPT, str(seconds), str(ROOT / 'src' / 'picking_common'), mode],
                         capture_output=True, text=True, timeout=seconds + 30)
    p50, p99, worst, missed = map(float, out.stdout.split())
    return p50, p99, worst, missed


def run(quick=False, rows=(3, 4, 6)):
    out = []
    if 3 in rows:
        print('row 3: goal -> JointTrajectory over DDS', flush=True)
        lat, lost = goal_latency(40 if quick else 200)
        out.append(['3', f'goal → JointTrajectory over DDS ({len(lat)} pose goals, one at a time)',
                    f'p99 {fmt_time(np.percentile(lat, 99))}',
                    f'median {fmt_time(np.median(lat))}, max {fmt_time(lat.max())}; {lost} goals lost',
                    'p99 ≤ 10 ms', 'met' if np.percentile(lat, 99) <= 0.010 and lost == 0 else 'missed'])
        print('  ' + ' | '.join(out[-1]), flush=True)
        print('row 3: re-target -> spliced at the controller', flush=True)
        lat, n = retarget_latency(5.0 if quick else 10.0)
        p99 = np.percentile(lat, 99) if len(lat) else np.inf
        out.append(['3', f're-target → spliced at the controller ({n} re-targets at 30 Hz on a pose goal)',
                    f'p99 {fmt_time(p99)}', f'median {fmt_time(np.median(lat))}, max {fmt_time(lat.max())}; '
                    f'{len(lat)} spliced, {n - len(lat)} replaced by a newer one before they were planned',
                    'p99 ≤ 20 ms', 'met' if p99 <= 0.020 else 'missed'])
        print('  ' + ' | '.join(out[-1]), flush=True)
        print('row 3: picking-goal stop -> the arm braking', flush=True)
        brake, leave, runs = stop_latency(4 if quick else 10)
        median = np.median(brake) if len(brake) else np.inf
        out.append(['3', f'`picking-goal stop` started beside a moving arm → the controller braking ({runs} stops)',
                    f'median {fmt_time(median)}', (f'max {fmt_time(brake.max())}; ' if len(brake) else '')
                    + f'{len(brake)} of {runs} braked; the process exits after a median {fmt_time(np.median(leave))} '
                    '(its start, rclpy, a DDS participant and discovery of the planner\'s and the controller\'s '
                    'cancel services)', '≤ 0.5 s', 'met' if len(brake) == runs and median <= 0.5 else 'missed'])
        print('  ' + ' | '.join(out[-1]), flush=True)
    if 4 in rows:
        seconds = 10 if quick else 60
        print(f'row 4: the controller at 1 kHz for {seconds} s with the simulator and the planner', flush=True)
        p50, p99, worst, missed = bare_loop(10)
        c50, c99, _, c_missed = contended_loop(5)
        (figures,) = run_stacks(1, 1000.0, seconds)
        row = loop_row(figures, f'controller loop at 1 kHz for {seconds} s (simulator and planner running)')
        row[3] += (f'; floor: a bare Python sleep loop alone on this machine (SCHED_FIFO where allowed, as the '
                   f'controller): p50 {p50:.0f} µs, p99 {p99:.0f} µs, '
                   f'max {worst:.0f} µs, {missed:.2f} % missed; the same loop while another thread of its '
                   f'process runs Python (GIL switch interval {SWITCH_INTERVAL * 1e6:.0f} µs): p50 {c50:.0f} µs, '
                   f'p99 {c99:.0f} µs, {c_missed:.2f} % missed')
        out.append(row)
        print('  ' + ' | '.join(out[-1]), flush=True)
    if 6 in rows:
        for rate, max_n in ((1000.0, 4), (250.0, 6)):
            print(f'row 6: arms side by side at {rate:g} Hz', flush=True)
            best, seen, missed = arms(rate, max_n if not quick else 2, 8 if quick else 20)
            fewer = f' (but N = {", ".join(map(str, missed))} missed it)' if missed else ''
            out.append(['6', f'arms side by side at {rate:g} Hz (simulator + controller + planner each, '
                             'every loop at its own phase)',
                        f'{best} arm(s) meet row 4{fewer}', '; '.join(seen),
                        '4 arms at 1 kHz' if rate == 1000.0 else '—',
                        ('met' if best >= 4 else 'missed') if rate == 1000.0 else '—'])
            print('  ' + ' | '.join(out[-1]), flush=True)
    return out
