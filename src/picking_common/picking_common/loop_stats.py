"""How well a periodic loop keeps its clock: period error percentiles, missed deadlines, CPU.

Each tick records its start time; the statistics live in a fixed histogram of
the period error (1 µs bins), so recording costs no allocation and the
percentiles of a long run come without keeping every sample.
"""

from __future__ import annotations

import array
import math
import time

import numpy as np

BIN = 1e-6          # s per histogram bin
BINS = 100_000      # errors of 100 ms and more share the last bin
SCAN_BLOCK = 1024   # bins summed per numpy call when the percentiles are looked up


class LoopStats:
    """Period statistics of a loop meant to run every ``period`` s.

    A tick is *missed* when it starts more than 1.5 periods after the one before
    (the deadline of a whole tick was lost).
    """

    def __init__(self, period):
        if not (math.isfinite(period) and period > 0):
            raise ValueError(f'period must be > 0 s, got {period}')
        self.period = float(period)
        # A plain typed array: a Python-level increment costs far less than numpy indexing.
        self.counts = array.array('q', bytes(8 * BINS))
        self.reset()

    def reset(self):
        """Start counting afresh from the next tick."""
        self.counts = array.array('q', bytes(8 * BINS))
        self.ticks = 0
        self.missed = 0
        self.worst = 0.0
        self.first = self.last = None
        self.cpu_start = time.process_time()
        self.wall_start = time.monotonic()

    def record(self, t):
        """One tick that started at monotonic time ``t``, s."""
        if not math.isfinite(t):
            raise ValueError(f'tick time must be finite, got {t}')
        last = self.last
        self.last = t
        if last is None:
            self.first = t
            return
        dt = t - last
        err = abs(dt - self.period)
        if not err < BIN * BINS:                 # 100 ms and more (or a clock gone wrong)
            self.counts[BINS - 1] += 1
        else:
            self.counts[int(err / BIN)] += 1
        self.ticks += 1
        if err > self.worst:
            self.worst = err
        if dt > 1.5 * self.period:
            self.missed += 1

    def percentile(self, p):
        """The ``p``-th percentile of the period error, s (bin resolution 1 µs)."""
        return self.percentiles(p)[0]

    def percentiles(self, *ps):
        """The ``ps``-th percentiles of the period error, s, found in one scan of the histogram.

        The scan runs a block of bins at a time from the small errors up and stops at the
        last percentile, where nearly all ticks are, instead of summing the whole histogram
        once per percentile.
        """
        if self.ticks == 0:
            return [math.nan] * len(ps)
        wanted = sorted((max(p / 100.0 * self.ticks, 1), i) for i, p in enumerate(ps))
        counts = np.frombuffer(self.counts, dtype=np.int64)
        out = [math.nan] * len(ps)
        below = 0
        for start in range(0, BINS, SCAN_BLOCK):
            cumulative = np.cumsum(counts[start:start + SCAN_BLOCK])
            cumulative += below
            while wanted and cumulative[-1] >= wanted[0][0]:
                rank, i = wanted.pop(0)
                out[i] = (start + int(np.searchsorted(cumulative, rank)) + 0.5) * BIN
            if not wanted:
                break
            below = int(cumulative[-1])
        return out

    def summary(self):
        """A dict: ticks, achieved rate (Hz), period error p50/p99/max (µs), missed, CPU (% of one core)."""
        span = (self.last - self.first) if self.ticks else math.nan
        wall = time.monotonic() - self.wall_start
        p50, p99 = self.percentiles(50, 99)
        return {
            'ticks': self.ticks,
            'rate_hz': self.ticks / span if self.ticks and span > 0 else math.nan,
            'period_error_p50_us': p50 * 1e6,
            'period_error_p99_us': p99 * 1e6,
            'period_error_max_us': self.worst * 1e6,
            'missed': self.missed,
            'missed_percent': 100.0 * self.missed / self.ticks if self.ticks else math.nan,
            'cpu_percent': 100.0 * (time.process_time() - self.cpu_start) / wall if wall > 0 else math.nan,
        }

    @staticmethod
    def describe(s):
        """One line for a log."""
        return (f'{s["ticks"]} ticks at {s["rate_hz"]:.1f} Hz; period error p50 {s["period_error_p50_us"]:.0f} µs, '
                f'p99 {s["period_error_p99_us"]:.0f} µs, max {s["period_error_max_us"]:.0f} µs; '
                f'{s["missed"]} missed ({s["missed_percent"]:.3f} %); process CPU {s["cpu_percent"]:.1f} % of a core')
