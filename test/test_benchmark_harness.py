"""The benchmark harness's own arithmetic (no timing is asserted anywhere: speed lives in benchmarks/)."""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'benchmarks'))

import harness  # noqa: E402


def test_cpu_steal_is_the_share_of_the_wanted_time_that_other_guests_got():
    #                   user nice system idle iowait irq softirq steal
    before = np.array([100, 0, 50, 1000, 7, 1, 2, 10])
    after = np.array([160, 0, 70, 3000, 9, 2, 5, 40])
    # busy = 60 + 0 + 20 + 1 + 3 = 84 ticks; steal 30: 30 / 114 (idle and iowait wanted nothing)
    assert harness.steal_share(before, after) == pytest.approx(30 / 114)
    assert harness.steal_share(before, before) == 0.0
    assert harness.steal_share(None, after) is None and harness.steal_share(before, None) is None


def test_cpu_times_reads_this_machine_or_says_it_cannot():
    times = harness.cpu_times()
    if not Path('/proc/stat').exists():
        assert times is None
        return
    assert times.shape == (8,) and (times >= 0).all()
    later = harness.cpu_times()
    assert (later >= times).all()
    share = harness.steal_share(times, later)
    assert share is None or 0.0 <= share <= 1.0


def test_time_calls_times_every_function_each_round_in_a_new_order():
    calls = []
    fns = {name: (lambda name=name: calls.append(name)) for name in 'abc'}
    times = harness.time_calls(fns, repeats=20, warmup=1)
    assert {name: len(t) for name, t in times.items()} == {'a': 20, 'b': 20, 'c': 20}
    rounds = [tuple(calls[i:i + 3]) for i in range(3, len(calls), 3)]
    assert all(sorted(r) == ['a', 'b', 'c'] for r in rounds)
    assert len(set(rounds)) > 1                                # not one fixed order
    assert {r[0] for r in rounds} == {'a', 'b', 'c'}           # every function is sometimes first
