"""Run every benchmark, print one table and write docs/benchmarks.md.

    make bench            # or: .venv/bin/python benchmarks/run.py [--quick] [--only 1,2,7]

Rows (issue 6): 1 core sampling and IK against roboticstoolbox-python, 2 planning
the Table 1 cycle in process, 3 goal -> JointTrajectory over DDS, 4 the controller
loop at 1 kHz, 5 servo tracking through the cycle, 6 several arms side by side,
7 the jerk-limited cycle with the optimal method, 8 a tree harvested by one arm and by 2-4 arms, 9 collision
checks and a blocked apple planned around its twig, 10 apples counted by the simulator's fruit world, 11 a swaying
apple picked where it will be, 12 the UR5e's and the FR3's IK and cycle. Every ROS process runs with
ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST in a ROS_DOMAIN_ID of this run's own.
"""

from __future__ import annotations

import argparse
import datetime
import os
import sys
import time
from pathlib import Path

# The network rule, before anything loads rclpy: loopback only, a domain of our own.
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('ROS_DOMAIN_ID', str(os.getpid() % 90 + 10))
os.environ.setdefault('MPLBACKEND', 'Agg')
sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_ik  # noqa: E402
import bench_plan  # noqa: E402
import bench_trajectory  # noqa: E402
from harness import cpu_times, machine, steal_share, table  # noqa: E402

HEADER = ['#', 'figure', 'ours', 'detail (peer side by side, or the figures behind it)', 'goal', 'verdict']


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true', help='fewer repeats and shorter runs (a smoke run)')
    parser.add_argument('--only', default='1,2,3,4,5,6,7,8,9,10,11,12', help='comma-separated rows to run (default all)')
    parser.add_argument('--out', type=Path, default=Path('docs/benchmarks.md'))
    args = parser.parse_args(argv)
    rows_wanted = {int(x) for x in args.only.split(',')}
    repeats = 3 if args.quick else 15
    print(f'machine: {machine()}', flush=True)
    started, first_times = time.monotonic(), cpu_times()
    rows, steal = [], {}

    def measure(label, run):
        """``run()``'s rows, noting the CPU steal while it ran (see harness.steal_share)."""
        before = cpu_times()
        out = run()
        steal[label] = steal_share(before, cpu_times())
        if steal[label] is not None:
            print(f'  CPU steal during {_rows(label)}: {100 * steal[label]:.1f} % of the time the machine wanted',
                  flush=True)
        return out

    if 1 in rows_wanted:
        print('row 1: trajectory sampling and IK against roboticstoolbox-python', flush=True)
        rows += measure('1', lambda: bench_trajectory.run(repeats) + bench_ik.run(repeats))
    if 2 in rows_wanted:
        print('row 2: planning the Table 1 cycle in process', flush=True)
        rows += measure('2', lambda: bench_plan.planning_time(10 * repeats))     # 5 ms each: 150 runs
    if rows_wanted & {3, 4, 6}:
        import bench_nodes
        rows += measure('/'.join(str(r) for r in sorted(rows_wanted & {3, 4, 6})),
                        lambda: bench_nodes.run(args.quick, rows_wanted))
    if 5 in rows_wanted:
        print('row 5: servo tracking through the pick cycle (the demo on the simulator)', flush=True)
        rows += measure('5', bench_plan.tracking)
    if 7 in rows_wanted:
        print('row 7: the cycle within velocity, acceleration and jerk limits', flush=True)
        rows += measure('7', bench_plan.jerk_limited_cycle)
    if 8 in rows_wanted:
        import bench_harvest
        print('row 8: a tree harvested by one arm, planned and on the simulator', flush=True)
        rows += measure('8', lambda: bench_harvest.planned() + bench_harvest.run_on_simulator()
                        + bench_harvest.platforms())
    if 9 in rows_wanted:
        import bench_collision
        print('row 9: collision checks against the canopy and the scene, a blocked apple', flush=True)
        rows += measure('9', bench_collision.checks)
    if 10 in rows_wanted:
        import bench_world
        print("row 10: the branch scenario's trees harvested, counted by the fruit world", flush=True)
        rows += measure('10', bench_world.counted_by_the_world)
    if 11 in rows_wanted:
        import bench_sway
        import bench_world
        print('row 11: a swaying apple picked and a tree in the wind harvested, counted by the fruit world',
              flush=True)
        rows += measure('11', lambda: bench_sway.swaying_apples() + bench_world.in_the_wind())
    if 12 in rows_wanted:
        import bench_arms
        print("row 12: the UR5e's and the FR3's IK against roboticstoolbox, and the cycle on each", flush=True)
        rows += measure('12', lambda: bench_arms.run(repeats))
    rows.sort(key=lambda r: int(r[0]))
    total_steal = steal_share(first_times, cpu_times())
    text = table(rows, HEADER)
    print()
    print(text)
    minutes = (time.monotonic() - started) / 60
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(
        '# Benchmarks\n\n'
        f'Measured by `make bench` on {datetime.date.today()} in {minutes:.0f} min: {machine()}.\n'
        + _steal_line(total_steal, steal) +
        f'In-process figures are medians (and p99) over {repeats} interleaved repeats ({10 * repeats} for row 2, '
        'whose cycle takes milliseconds) (each round in a new '
        'random order); ratios are peer median / our median, measured side by side in the same run. No test '
        'asserts a time: these figures are measured here only.\n\n' + text + '\n\n' + NOTES)
    print(f'\nwrote {args.out}')
    return 0


def _rows(label):
    """'row 2' or 'rows 3/4/6'."""
    return f'row{"s" if "/" in label else ""} {label}'


def _steal_line(total, by_rows):
    """The docs' sentence on CPU steal (empty where it cannot be read)."""
    if total is None:
        return ''
    parts = ', '.join(f'{_rows(label)}: {100 * share:.1f} %' for label, share in by_rows.items() if share is not None)
    return (f'CPU steal (time this virtual machine wanted its cores and the hypervisor ran other guests, from '
            f'/proc/stat): {100 * total:.1f} % of the time it wanted over the run ({parts}).\n')


NOTES = (Path(__file__).resolve().parent / 'NOTES.md').read_text() if (
    Path(__file__).resolve().parent / 'NOTES.md').exists() else ''


if __name__ == '__main__':
    sys.exit(main())
