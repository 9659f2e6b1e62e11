"""The real-time periodic loop of the controller and the simulator.

One loop, one stall policy: the loop wakes at absolute deadlines (``origin + k period``, so the
rate never drifts), optionally phase-aligned and under SCHED_FIFO, and calls its tick with the
number of periods that passed since the last call. Woken far behind its deadline (the process
was stopped, or the machine is saturated), it calls the tick once for all the periods missed and
goes on from the next deadline after now: never a burst of ticks. A loop that follows the newest
message of a stream (the simulator) may first let the process's other threads run briefly
(``catch_up_yield``), so that the middleware takes in what came meanwhile; a loop that must see
the stall before anything else runs (the controller, which delays its trajectory by it) does not.
The stalls are reported at most once a second.
"""

from __future__ import annotations

import math
import os
import threading
import time

from .loop_stats import LoopStats

#: s: a loop woken this much late counts it as a stall.
STALL = 0.02
#: s a loop sleeps at least between ticks, even when late: a real-time thread that never sleeps
#: starves the rest of the machine.
MIN_SLEEP = 5e-5


def make_realtime(priority, logger, what='the loop thread'):
    """Run the calling thread under SCHED_FIFO at ``priority`` (1-99); 0 leaves it alone.

    Needs CAP_SYS_NICE or an rtprio limit (``ulimit -r``); without them it says so
    (naming ``what``) and goes on at normal priority. Returns True when the thread is real-time.
    """
    if priority <= 0:
        return False
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(int(priority)))
    except (PermissionError, OSError, AttributeError) as exc:
        logger.warning(f'could not run {what} under SCHED_FIFO priority {priority} ({exc}); '
                       'running at normal priority (grant CAP_SYS_NICE or an rtprio limit to use it)')
        return False
    return True


def make_normal():
    """Run the calling thread under the normal scheduler again (nothing where it already does, or cannot change).

    A node's teardown waits on the middleware's own threads, which run at normal priority: a real-time thread
    waiting for them on their core would keep them from running."""
    try:
        if os.sched_getscheduler(0) != os.SCHED_OTHER:
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    except (PermissionError, OSError, AttributeError):
        pass


def check_priority(priority, name='thread_priority'):
    """A thread priority as an int: 0 (normal) or 1-99 (SCHED_FIFO); ValueError otherwise."""
    if isinstance(priority, float) and not priority.is_integer():
        raise ValueError(f'{name} must be a whole number, got {priority}')
    priority = int(priority)
    if not 0 <= priority <= 99:
        raise ValueError(f'{name} must be 0 (normal) or 1-99 (SCHED_FIFO), got {priority}')
    return priority


def check_loop_phase(phase):
    """``loop_phase`` as a float: -1 (free running) or a fraction of the period in [0, 1)."""
    phase = float(phase)
    if not (phase == -1.0 or 0.0 <= phase < 1.0):
        raise ValueError(f'loop_phase must be -1 (free running) or in [0, 1) of the period, got {phase}')
    return phase


def loop_origin(period, phase, now=None):
    """Where a loop at ``period`` s counts its deadlines from, on ``time.monotonic()``: ``now``
    itself for ``phase`` -1 (free running), else the latest instant at or before ``now`` that
    lies ``phase`` of a period after a whole number of periods of that clock. The loops of
    several arms on one machine, given different phases, then wake at their own moments of each
    period instead of wherever they happened to start."""
    now = time.monotonic() if now is None else now
    if phase < 0.0:
        return now
    return (math.floor(now / period - phase) + phase) * period


class PeriodicLoop:
    """Calls ``tick(deadline, due)`` once a period in a thread of its own.

    ``deadline`` is the monotonic time (s) of the deadline served, ``due`` how many periods
    passed since the last call (1 unless the loop stalled). ``on_stall(worst, count)`` hears of
    the stalls (the longest in s, and how many), at most once a second; by default they are
    logged. ``catch_up_yield``: s a stalled loop sleeps before its tick. ``stats`` (:class:`LoopStats`)
    records every wake.
    """

    def __init__(self, period, tick, *, name, logger, phase=-1.0, priority=0, on_stall=None, catch_up_yield=0.0):
        if not (math.isfinite(period) and period > 0):
            raise ValueError(f'the {name} loop period must be > 0 s, got {period}')
        self.period = float(period)
        self.tick = tick
        self.name = name
        self.logger = logger
        self.phase = check_loop_phase(phase)
        self.priority = check_priority(priority)
        self.on_stall = on_stall or self._log_stall
        self.catch_up_yield = float(catch_up_yield)
        self.stats = LoopStats(self.period)
        self.origin = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self):
        self.origin = loop_origin(self.period, self.phase)
        self._thread.start()

    def stop(self, timeout=1.0):
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=timeout)

    def _log_stall(self, worst, count):
        more = f' (the longest of {count} stalls since the last report)' if count > 1 else ''
        self.logger.warning(f'{self.name} loop stalled for {worst:.3f} s{more}: one tick served the missed periods')

    def _run(self):
        make_realtime(self.priority, self.logger, f'the {self.name} loop')
        period, origin = self.period, self.origin
        served = 0                                      # the index of the last deadline served
        reported, stalls, worst = -math.inf, 0, 0.0
        while not self._stop.is_set():
            deadline = origin + (served + 1) * period
            time.sleep(max(deadline - time.monotonic(), MIN_SLEEP))
            now = time.monotonic()
            if now - deadline > STALL:
                stalls, worst = stalls + 1, max(worst, now - deadline)
                if self.catch_up_yield > 0.0:
                    time.sleep(self.catch_up_yield)
                    now = time.monotonic()
            k = max(int((now - origin) / period), served + 1)
            due, served = k - served, k
            self.stats.record(now)
            self.tick(origin + k * period, due)
            if stalls and now - reported >= 1.0:
                self.on_stall(worst, stalls)
                reported, stalls, worst = now, 0, 0.0
