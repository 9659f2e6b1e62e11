"""The servo over arbitrary commands and parameters: refused with ValueError, never a NaN state.

Run long with ``make fuzz`` (10 000 examples each).
"""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from picking_sim.servo import Servo, ServoParams

pytestmark = pytest.mark.fuzz

WILD = st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                 st.sampled_from([0.0, -0.0, 1e-300, 1e300, -1e300]), st.floats(-10, 10))


def vectors():
    return st.one_of(WILD, hnp.arrays(np.float64, st.integers(0, 4), elements=WILD))


@given(vectors(), vectors(), vectors(), WILD)
def test_commands(q, qd, qdd, age):
    servo = Servo(np.zeros(3), params=ServoParams(max_velocity=3.0))
    try:
        servo.command(q, qd, qdd, age=age)
    except ValueError:
        pass
    servo.step(200)
    assert np.all(np.isfinite(servo.q)) and np.all(np.isfinite(servo.qd))


@given(st.fixed_dictionaries({'bandwidth': WILD, 'damping': WILD, 'integral': WILD, 'inertia': WILD,
                              'friction': WILD, 'max_torque': WILD, 'max_velocity': WILD}), WILD)
def test_parameters(values, dt):
    try:
        servo = Servo(np.zeros(2), dt=dt, params=ServoParams(**values))
    except ValueError:
        return
    servo.command([1.0, -1.0])
    servo.step(10)
