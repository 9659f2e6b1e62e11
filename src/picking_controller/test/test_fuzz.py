"""The controller core and its spline over arbitrary input: refused with ValueError or an ERROR event, never a crash.

Run long with ``make fuzz`` (10 000 examples each).
"""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from picking_controller.core import ControllerCore
from picking_controller.sampler import from_points

pytestmark = pytest.mark.fuzz

WILD = st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                 st.sampled_from([0.0, -0.0, 1e-300, 1e300, -1e300, 1e-9]), st.floats(-5, 5))
NAMES = ['a', 'b', 'gripper']


def arrays():
    return hnp.arrays(np.float64, hnp.array_shapes(min_dims=0, max_dims=2, min_side=0, max_side=4), elements=WILD)


@given(st.lists(st.sampled_from(NAMES + ['x', '']), max_size=4), arrays(), arrays(), arrays(), arrays(), WILD, WILD)
def test_load_refuses_or_runs_within_the_limits(names, times, pos, vel, acc, start, now):
    c = ControllerCore(NAMES, [-3, -3, 0], [3, 3, 0.1], [2, 2, 0.3], [10, 10, 3], optional=['gripper'])
    c.on_state([0.0, 0.0, 0.05], None, 0.0, now=0.0)
    now = now if np.isfinite(now) else 0.0
    event = c.load(names, np.atleast_1d(times), np.atleast_2d(pos), np.atleast_2d(vel), np.atleast_2d(acc),
                   start, now)
    assert event.level in ('OK', 'ERROR')
    for t in np.linspace(now, now + 5.0, 11):
        (q, qd, qdd), _ = c.command(t)
        assert np.all(np.isfinite(q)) and np.all(q >= [-3, -3, 0]) and np.all(q <= [3, 3, 0.1])


@given(arrays(), arrays(), st.one_of(st.none(), arrays()), st.one_of(st.none(), arrays()), st.booleans())
def test_from_points(times, pos, vel, acc, smooth):
    try:
        traj = from_points(times, pos, vel, acc, smooth_positions=smooth)
    except ValueError:
        return
    assert np.all(np.isfinite(traj.coeffs))
