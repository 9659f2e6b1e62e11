"""Run every benchmark, print one table and write docs/benchmarks.md.

    make bench            # or: .venv/bin/python benchmarks/run.py [--quick]
"""

from __future__ import annotations

import argparse
import datetime
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_ik  # noqa: E402
import bench_trajectory  # noqa: E402
from harness import machine, table  # noqa: E402

HEADER = ['figure', 'ours (median)', 'ours (p99)', 'peer', 'peer (median)', 'speed-up']


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true', help='fewer repeats (a smoke run)')
    parser.add_argument('--out', type=Path, default=Path('docs/benchmarks.md'))
    args = parser.parse_args(argv)
    repeats = 3 if args.quick else 15
    print(f'machine: {machine()}')
    rows = []
    print('trajectory sampling:')
    rows += bench_trajectory.run(repeats)
    print('inverse kinematics:')
    rows += bench_ik.run(repeats)
    text = table(rows, HEADER)
    print()
    print(text)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(
        '# Benchmarks\n\n'
        f'Measured by `make bench` on {datetime.date.today()}: {machine()}.\n'
        f'Medians and p99 over {repeats} interleaved repeats; ratios are peer median / our median, '
        'measured side by side in the same run.\n\n' + text + '\n')
    print(f'\nwrote {args.out}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
