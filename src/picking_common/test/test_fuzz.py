"""The codec's readers and the loop statistics over arbitrary input: ValueError or values, never a crash.

Run long with ``make fuzz`` (10 000 examples each).
"""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from picking_common import cdr
from picking_common.loop_stats import LoopStats

pytestmark = pytest.mark.fuzz

WILD = st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                 st.sampled_from([0.0, -0.0, 1e-300, 1e300, -1e300, 1e-9]), st.floats(-5, 5))


def _cdr_messages():
    """Valid JointState, JointTrajectory and TFMessage bytes, to be damaged."""
    q = np.arange(6.0).reshape(2, 3)
    return [cdr.JointStateWriter(['a', 'bb', 'ccc'], 'base').write(5, q[0], q[1], q[0]),
            cdr.joint_trajectory(5, 'f', ['a', 'bb', 'ccc'], np.array([0.1, 0.2]), q, q, q),
            cdr.TransformWriter([('a', 'bb'), ('bb', 'ccc')]).write(5, q, np.ones((2, 4)))]


@given(st.one_of(st.binary(max_size=300),
                 st.tuples(st.sampled_from([0, 1, 2]), st.integers(0, 200), st.binary(min_size=1, max_size=8),
                           st.integers(0, 200))))
def test_cdr_readers_refuse_any_bytes_they_cannot_read(damage):
    """Arbitrary or damaged bytes: the readers the nodes take their messages with give
    ValueError (the node then reads the message class) or values, never another error."""
    if isinstance(damage, bytes):
        datas = [damage, b'\x00\x01\x00\x00' + damage]
    else:
        which, at, patch, cut = damage
        data = _cdr_messages()[which]
        datas = [data[:at] + patch + data[at + len(patch):], data[:len(data) - cut]]
    for data in datas:
        for read in (cdr.JointStateReader().read, cdr.read_joint_trajectory, cdr.read_transforms):
            try:
                read(data)
            except ValueError:
                pass


@given(WILD, st.lists(WILD, max_size=20))
def test_loop_stats(period, ticks):
    try:
        stats = LoopStats(period)
    except ValueError:
        return
    for t in ticks:
        try:
            stats.record(t)
        except ValueError:
            assert not np.isfinite(t)
    stats.summary()
