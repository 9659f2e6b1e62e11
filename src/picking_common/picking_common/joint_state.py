"""The JointState layout: building one, and reading its values in a node's joint order."""

from __future__ import annotations

import functools

import numpy as np
from sensor_msgs.msg import JointState


def joint_state(names, stamp, position, velocity=None, effort=None):
    """A JointState; ``stamp`` a builtin_interfaces Time (None: left zero)."""
    msg = JointState()
    if stamp is not None:
        msg.header.stamp = stamp
    msg.name = list(names)
    msg.position = [float(x) for x in position]
    if velocity is not None:
        msg.velocity = [float(x) for x in velocity]
    if effort is not None:
        msg.effort = [float(x) for x in effort]
    return msg


def reorder(msg_names, values, names, what):
    """Values given in ``msg_names`` order, in ``names`` order; ValueError if any is missing."""
    values = np.asarray(values, dtype=float)
    return values[..., _order(tuple(msg_names), tuple(names), what)]


@functools.lru_cache(maxsize=64)
def _order(msg_names, names, what):
    """Where each of ``names`` sits in ``msg_names`` (cached: a stream repeats its names)."""
    index = {n: i for i, n in enumerate(msg_names)}
    missing = [n for n in names if n not in index]
    if missing:
        raise ValueError(f'{what} lacks joints {missing}')
    return np.array([index[n] for n in names], dtype=np.intp)


def seconds(stamp):
    """A builtin_interfaces/Time (or a header's stamp read from bytes) in s."""
    return stamp.sec + stamp.nanosec * 1e-9
