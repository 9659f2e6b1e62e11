"""Timing harness: interleaved repeats, medians and p99, ratios measured in one run.

The machines are shared and noisy, so every pair (ours, peer) is timed in
alternation within one process and reported as medians; no test asserts a time.
"""

from __future__ import annotations

import gc
import platform
import time

import numpy as np


def time_calls(fns, repeats=15, warmup=2):
    """Time each callable ``repeats`` times, interleaved; returns {name: seconds array}."""
    for fn in fns.values():
        for _ in range(warmup):
            fn()
    out = {name: [] for name in fns}
    gc_was = gc.isenabled()
    gc.disable()
    try:
        for _ in range(repeats):
            for name, fn in fns.items():
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
    return (f'{platform.processor() or platform.machine()}, {os.cpu_count()} cores, '
            f'Python {platform.python_version()}, numpy {np.__version__}')


def table(rows, header):
    """A Markdown table from rows of strings."""
    lines = ['| ' + ' | '.join(header) + ' |', '| ' + ' | '.join('---' for _ in header) + ' |']
    lines += ['| ' + ' | '.join(str(c) for c in row) + ' |' for row in rows]
    return '\n'.join(lines)
