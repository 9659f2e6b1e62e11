"""Status levels and the DiagnosticStatus messages every node reports with."""

from __future__ import annotations

import enum

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue


class Level(enum.IntEnum):
    """A status level, as diagnostic_msgs/DiagnosticStatus numbers it."""

    OK = int.from_bytes(DiagnosticStatus.OK, 'little')
    WARN = int.from_bytes(DiagnosticStatus.WARN, 'little')
    ERROR = int.from_bytes(DiagnosticStatus.ERROR, 'little')
    STALE = int.from_bytes(DiagnosticStatus.STALE, 'little')

    @property
    def byte(self):
        """The level as the message's ``level`` field holds it (one byte)."""
        return bytes([self.value])

    @classmethod
    def of(cls, level):
        """The level of a message's ``level`` field (bytes or int) or of a name (``'WARN'``)."""
        if isinstance(level, cls):
            return level
        if isinstance(level, str):
            return cls[level]
        if isinstance(level, (bytes, bytearray)):
            return cls(int.from_bytes(level, 'little'))
        return cls(int(level))


def stamp_key(stamp):
    """A header stamp as text, ``'sec.nanosec'``: how trajectories are named in status values.
    ``stamp``: a builtin_interfaces/Time, or integer nanoseconds."""
    sec, nanosec = divmod(stamp, 1_000_000_000) if isinstance(stamp, int) else (stamp.sec, stamp.nanosec)
    return f'{sec}.{nanosec:09d}'


def status(name, level, message, **values):
    """A DiagnosticStatus with key/value pairs (values formatted as text); ``level`` a :class:`Level`,
    its name, or the message's own level value."""
    msg = DiagnosticStatus()
    msg.level = Level.of(level).byte
    msg.name = name
    msg.message = message
    msg.values = [KeyValue(key=str(k), value=_fmt(v)) for k, v in values.items()]
    return msg


def _fmt(v):
    if isinstance(v, float):
        return f'{v:.6g}'
    if isinstance(v, (list, tuple, np.ndarray)):
        return '[' + ', '.join(_fmt(float(x)) if isinstance(x, (float, np.floating)) else str(x)
                               for x in v) + ']'
    return str(v)


def status_values(msg):
    """The key/value pairs of a DiagnosticStatus as a dict of strings."""
    return {kv.key: kv.value for kv in msg.values}


#: Where diagnostic_aggregator and rqt_robot_monitor read a robot's diagnostics (one topic for all its nodes).
DIAGNOSTICS = '/diagnostics'


class Diagnostics:
    """A node's health on :data:`DIAGNOSTICS`, once a second: a diagnostic_msgs/DiagnosticArray of the
    statuses ``report()`` gives as ``(what, level, message, values)``, each named ``'<node>: <what>'``
    (the node's name with its namespace) with the arm's name, namespaced, as ``hardware_id``."""

    def __init__(self, node, arm_name, report, period=1.0):
        from diagnostic_msgs.msg import DiagnosticArray
        self._array = DiagnosticArray
        self.node = node
        self.report = report
        self.prefix = node.get_fully_qualified_name().lstrip('/')
        self.hardware_id = f'{node.get_namespace().strip("/")}/{arm_name}'.lstrip('/')
        self.pub = node.create_publisher(DiagnosticArray, DIAGNOSTICS, 10)
        self.timer = node.create_timer(period, self.publish)

    def publish(self):
        msg = self._array()
        msg.header.stamp = self.node.get_clock().now().to_msg()
        for what, level, message, values in self.report():
            s = status(f'{self.prefix}: {what}', level, message, **values)
            s.hardware_id = self.hardware_id
            msg.status.append(s)
        self.pub.publish(msg)
