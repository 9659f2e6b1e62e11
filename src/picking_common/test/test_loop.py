"""Loop statistics: percentiles, missed deadlines and the achieved rate from tick times."""

import math

import numpy as np
import pytest

from picking_common.loop_stats import LoopStats


def test_regular_ticks_with_known_errors():
    stats = LoopStats(0.001)
    rng = np.random.default_rng(3)
    t = np.cumsum(0.001 + rng.choice([-20e-6, 0.0, 20e-6], 10_000))
    for x in t:
        stats.record(x)
    s = stats.summary()
    assert s['ticks'] == len(t) - 1
    assert s['rate_hz'] == pytest.approx(1000.0, rel=1e-3)
    assert s['period_error_p50_us'] == pytest.approx(20.5, abs=1.0)       # two thirds are 20 µs off
    assert s['period_error_max_us'] == pytest.approx(20.0, abs=0.01)
    assert s['missed'] == 0


def test_a_lost_tick_is_missed_and_counted_in_the_tail():
    stats = LoopStats(0.001)
    times = [i * 0.001 for i in range(1000)]
    times[500:] = [x + 0.002 for x in times[500:]]                       # one 3 ms gap
    for x in times:
        stats.record(x)
    s = stats.summary()
    assert s['missed'] == 1
    assert s['period_error_max_us'] == pytest.approx(2000.0, abs=0.01)
    assert s['period_error_p50_us'] < 1.0
    assert 'missed' in LoopStats.describe(s)


@pytest.mark.parametrize('seed', [0, 1])
def test_percentiles_match_numpy_on_the_same_errors(seed):
    """Errors spread over many scan blocks, a far tail (90 ms) and the overflow bin (> 100 ms):
    each percentile is the bin numpy's lower percentile of the binned errors falls in."""
    stats = LoopStats(0.001)
    rng = np.random.default_rng(seed)
    errors = np.concatenate([rng.exponential(30e-6, 5000), rng.uniform(0.0, 0.09, 300), [0.2, 0.5]])
    rng.shuffle(errors)
    t = np.concatenate([[0.0], np.cumsum(0.001 + errors)])
    for x in t:
        stats.record(x)
    binned = np.minimum(np.floor((np.diff(t) - 0.001) / 1e-6), 99_999)
    ps = (0.01, 50, 90, 99, 99.9, 100)
    got = stats.percentiles(*ps)
    for p, value in zip(ps, got):
        expected = (np.percentile(binned, p, method='inverted_cdf') + 0.5) * 1e-6
        assert value == pytest.approx(expected, abs=1.01e-6), p
    assert got[1] == stats.percentile(50)


def test_reset_and_empty():
    stats = LoopStats(0.004)
    stats.record(0.0)
    stats.record(0.1)
    stats.reset()
    s = stats.summary()
    assert s['ticks'] == 0 and math.isnan(s['period_error_p99_us'])


@pytest.mark.parametrize('period', [0.0, -1.0, math.nan, math.inf])
def test_bad_period(period):
    with pytest.raises(ValueError):
        LoopStats(period)


@pytest.mark.parametrize('phase', [0.0, 0.25, 0.5, 0.999])
@pytest.mark.parametrize('now', [10.0004, 12345.6789012, 0.0])
def test_a_phased_loop_counts_from_its_own_moment_of_the_period(phase, now):
    """The origin lies ``phase`` of a period past a whole number of periods, within one period
    before ``now``: loops given different phases wake at different moments whenever they start."""
    from picking_common.loop import loop_origin
    period = 1e-3
    origin = loop_origin(period, phase, now)
    assert now - period < origin <= now + 1e-12
    assert (origin / period - phase) == pytest.approx(round(origin / period - phase), abs=1e-6)


def test_a_free_running_loop_counts_from_now_and_a_phase_outside_the_period_is_refused():
    from picking_common.loop import check_loop_phase, loop_origin
    assert loop_origin(1e-3, -1.0, 3.14159) == 3.14159
    assert check_loop_phase(-1) == -1.0 and check_loop_phase(0.5) == 0.5
    for bad in (1.0, -0.5, 2.0, math.nan):
        with pytest.raises(ValueError, match='loop_phase must be -1'):
            check_loop_phase(bad)


class _Logger:
    def __init__(self):
        self.warnings = []

    def warning(self, text):
        self.warnings.append(text)


def test_the_periodic_loop_serves_every_period_once_and_a_stall_in_one_tick():
    """The deadlines are absolute: after a tick that overran many periods, the next call is told
    how many periods passed (no burst of calls), and the stall is reported."""
    import threading
    import time

    from picking_common.loop import PeriodicLoop
    calls, stalls, done = [], [], threading.Event()

    def tick(deadline, due):
        calls.append((deadline, due))
        if len(calls) == 5:
            time.sleep(0.1)                    # a stall of about 50 periods
        if len(calls) == 12:
            done.set()

    loop = PeriodicLoop(2e-3, tick, name='test', logger=_Logger(), on_stall=lambda w, n: stalls.append((w, n)))
    loop.start()
    assert done.wait(5.0)
    loop.stop()
    deadlines = [d for d, _ in calls[:12]]
    assert all(b > a for a, b in zip(deadlines, deadlines[1:]))
    # Every deadline lies on the loop's grid, and the periods told add up to the grid index.
    k = [round((d - loop.origin) / 2e-3) for d in deadlines]
    assert all(abs(d - loop.origin - i * 2e-3) < 1e-9 for d, i in zip(deadlines, k))
    assert sum(due for _, due in calls[:12]) == k[11]
    assert calls[5][1] >= 40                   # the stall's periods came in one call
    assert stalls and stalls[0][0] >= 0.05


def test_the_periodic_loop_refuses_a_bad_period_priority_or_phase():
    from picking_common.loop import PeriodicLoop
    for kwargs in ({'period': 0.0}, {'period': 1e-3, 'priority': 100}, {'period': 1e-3, 'phase': 1.5}):
        period = kwargs.pop('period')
        with pytest.raises(ValueError):
            PeriodicLoop(period, lambda d, n: None, name='x', logger=_Logger(), **kwargs)


def test_make_normal_takes_a_real_time_thread_back_to_the_normal_scheduler():
    import os
    import threading

    from picking_common.loop import make_normal, make_realtime
    seen = {}

    def run():
        seen['realtime'] = make_realtime(10, _Logger())
        seen['before'] = os.sched_getscheduler(0)
        make_normal()
        seen['after'] = os.sched_getscheduler(0)
    thread = threading.Thread(target=run)
    thread.start()
    thread.join()
    if not seen['realtime']:
        pytest.skip('this machine does not let a thread run under SCHED_FIFO')
    assert (seen['before'], seen['after']) == (os.SCHED_FIFO, os.SCHED_OTHER)
