"""Timing harness: interleaved repeats, medians and p99, ratios measured in one run.

The machines are shared and noisy, so every pair (ours, peer) is timed in
alternation within one process and reported as medians; no test asserts a time.
"""

from __future__ import annotations

import gc
import platform
import time
from pathlib import Path

import numpy as np


def time_calls(fns, repeats=15, warmup=2, seed=0):
    """Time each callable ``repeats`` times, interleaved; returns {name: seconds array}.

    Each round calls them in a new (seeded) random order: a call that writes megabytes
    runs at the speed of the caches and freed memory the call before it left (on the
    benchmark VM, a 14 MB fill took 0.35 ms after a call that freed such a block and
    1.4 ms after one that churned the L3 with smaller ones), so a fixed order would
    favour one of them in every round.
    """
    for fn in fns.values():
        for _ in range(warmup):
            fn()
    out = {name: [] for name in fns}
    names = list(fns)
    rng = np.random.default_rng(seed)
    gc_was = gc.isenabled()
    gc.disable()
    try:
        for _ in range(repeats):
            for name in rng.permutation(names):
                fn = fns[name]
                t0 = time.perf_counter()
                fn()
                out[name].append(time.perf_counter() - t0)
    finally:
        if gc_was:
            gc.enable()
    return {name: np.array(v) for name, v in out.items()}


def median(x):
    return float(np.median(x))


def p99(x):
    return float(np.percentile(x, 99))


def fmt_time(seconds):
    if seconds < 1e-3:
        return f'{seconds * 1e6:.1f} µs'
    if seconds < 1.0:
        return f'{seconds * 1e3:.2f} ms'
    return f'{seconds:.2f} s'


def machine():
    import os
    return (f'{cpu_model() or platform.processor() or platform.machine()}, {os.cpu_count()} cores, '
            f'Python {platform.python_version()}, numpy {np.__version__}')


def cpu_model():
    """The CPU's model name from ``/proc/cpuinfo`` (Linux), else ''."""
    try:
        for line in Path('/proc/cpuinfo').read_text().splitlines():
            if line.startswith('model name'):
                return f'{line.split(":", 1)[1].strip()} ({platform.machine()})'
    except OSError:
        pass
    return ''


def cpu_times():
    """The machine's CPU time so far (all cores, in clock ticks) from ``/proc/stat``: user, nice,
    system, idle, iowait, irq, softirq, steal; None where there is no such file (not Linux)."""
    try:
        with open('/proc/stat') as f:
            fields = f.readline().split()
    except OSError:
        return None
    return np.array(fields[1:9], dtype=np.int64) if fields and fields[0] == 'cpu' else None


def steal_share(before, after):
    """Of the CPU time the machine wanted between two :func:`cpu_times`, the share the hypervisor
    gave to other guests (steal / (busy + steal)), or None without both readings.

    On a virtual machine, a real-time loop that wakes while its virtual CPU is not running wakes
    late, whatever the code: this is the figure that says how often that could happen."""
    if before is None or after is None:
        return None
    d = after - before
    busy = d[0] + d[1] + d[2] + d[5] + d[6]
    wanted = busy + d[7]
    return float(d[7] / wanted) if wanted > 0 else 0.0


def table(rows, header):
    """A Markdown table from rows of strings."""
    lines = ['| ' + ' | '.join(header) + ' |', '| ' + ' | '.join('---' for _ in header) + ' |']
    lines += ['| ' + ' | '.join(str(c) for c in row) + ' |' for row in rows]
    return '\n'.join(lines)
