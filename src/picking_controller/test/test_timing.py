"""Loop statistics: percentiles, missed deadlines and the achieved rate from tick times."""

import math

import numpy as np
import pytest

from picking_controller.timing import LoopStats


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
