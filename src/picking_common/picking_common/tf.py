"""The frames of the graph, as every ROS node sees them on ``/tf`` and ``/tf_static``.

:class:`FrameListener` is the one small interface the nodes use: ``transform(target, source, stamp,
timeout)`` gives the 4x4 transform from ``source`` to ``target``, or raises :class:`FrameError` naming
the frames and why. Where the environment has tf2_ros (an apt-installed Jazzy) it is tf2_ros's Buffer
and TransformListener; elsewhere (the pip route) the core's :class:`~picking_core.frames.TransformBuffer`
fed by a listener of our own with tf2_ros's QoS: ``/tf`` reliable and volatile, ``/tf_static`` reliable
and transient local.
"""

from __future__ import annotations

import time

import numpy as np
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from scipy.spatial.transform import Rotation

from picking_core.frames import LookupError_, TransformBuffer

TF_QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE,
                    history=HistoryPolicy.KEEP_LAST)
TF_STATIC_QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                           durability=DurabilityPolicy.TRANSIENT_LOCAL, history=HistoryPolicy.KEEP_LAST)
#: s between two looks at /tf while a lookup waits for a transform.
POLL = 0.005
#: Messages a look takes from each topic at most (the queue's depth).
DRAIN_MAX = TF_QOS.depth


class FrameError(LookupError):
    """A transform that cannot be had: the frames, and why."""


def stamp_seconds(stamp):
    """A builtin_interfaces/Time in s (0 stays 0: "the latest")."""
    return stamp.sec + stamp.nanosec * 1e-9


class FrameListener:
    """The transforms of the graph, for ``node``: tf2_ros where it exists (``backend`` 'tf2_ros'), else ours
    (``backend`` 'picking_core'); ``prefer`` names one to use (tests run both)."""

    def __init__(self, node, cache_time=10.0, prefer=None):
        self.node = node
        impl = None
        if prefer in (None, 'tf2_ros'):
            try:
                impl = _Tf2Ros(node, cache_time)
            except ImportError:
                if prefer == 'tf2_ros':
                    raise
        self._impl = impl or _Ours(node, cache_time)
        self.backend = self._impl.name

    def transform(self, target, source, stamp=0.0, timeout=0.0):
        """The 4x4 transform taking points in ``source`` to ``target`` at ``stamp`` (s on the ROS clock; 0: the
        latest), waiting up to ``timeout`` s for it; :class:`FrameError` naming the frames when none comes."""
        target, source = target.lstrip('/'), source.lstrip('/')
        if target == source:
            return np.eye(4)
        return self._impl.transform(target, source, stamp, timeout)

    def frames(self):
        return self._impl.frames()

    def destroy(self):
        self._impl.destroy()


class _Ours:
    """The core's buffer, fed from /tf and /tf_static whenever a lookup is made (and by a timer, so that history
    is kept): no executor callback per message."""

    name = 'picking_core'

    def __init__(self, node, cache_time):
        from tf2_msgs.msg import TFMessage

        from .codec import Codec
        self.type, self.codec = TFMessage, Codec()
        self.buffer = TransformBuffer(cache_time)
        self.subs = []
        for topic, qos, static in (('/tf', TF_QOS, False), ('/tf_static', TF_STATIC_QOS, True)):
            sub = node.create_subscription(TFMessage, topic, lambda _: None, qos, raw=self.codec.raw)
            node._subscriptions.remove(sub)             # taken by drain(), not by the executor
            for handler in sub.event_handlers:
                node.remove_waitable(handler)
            self.subs.append((sub, static))
        self.timer = node.create_timer(0.1, self.drain)
        self.refused = 0
        self.logger = node.get_logger()

    def drain(self):
        """The transforms received since the last look, into the buffer (at most a queue's depth of messages per
        topic: a look always ends, however fast /tf comes); one that is not a transform is counted and said
        (throttled), never taken."""
        for sub, static in self.subs:
            for _ in range(DRAIN_MAX):
                # (As bytes, read by our CDR reader: rclpy's message classes cost a planner much of its time at
                # a state publisher's rate.)
                got = sub.handle.take_message(self.type, self.codec.raw)
                if got is None:
                    break
                refused = self.buffer.set_transforms(self.codec.read_transforms(got[0]), static)
                for exc in refused:
                    self.refused += 1
                    self.logger.warning(f'{"/tf_static" if static else "/tf"}: {exc}; not taken',
                                        throttle_duration_sec=2.0)

    def transform(self, target, source, stamp, timeout):
        end = time.monotonic() + max(timeout, 0.0)
        while True:
            self.drain()
            try:
                return self.buffer.lookup(target, source, stamp)
            except LookupError_ as exc:
                if time.monotonic() >= end:
                    raise FrameError(f'no transform from {source!r} to {target!r}'
                                     f'{f" at {stamp:.3f} s" if stamp else ""} within {timeout:g} s: {exc}') from None
            time.sleep(POLL)

    def frames(self):
        self.drain()
        return self.buffer.frames()

    def destroy(self):
        self.timer.cancel()
        for sub, _ in self.subs:
            sub.destroy()


class _Tf2Ros:
    """tf2_ros's Buffer and TransformListener (its own thread spins its subscriptions)."""

    name = 'tf2_ros'

    def __init__(self, node, cache_time):
        import tf2_ros
        from rclpy.duration import Duration
        self.tf2_ros = tf2_ros
        self.buffer = tf2_ros.Buffer(cache_time=Duration(seconds=cache_time))
        self.listener = tf2_ros.TransformListener(self.buffer, node, spin_thread=True)

    def transform(self, target, source, stamp, timeout):
        from rclpy.duration import Duration
        from rclpy.time import Time
        try:
            tf = self.buffer.lookup_transform(target, source, Time(nanoseconds=int(stamp * 1e9)),
                                              timeout=Duration(seconds=timeout))
        except (self.tf2_ros.LookupException, self.tf2_ros.ConnectivityException,
                self.tf2_ros.ExtrapolationException, self.tf2_ros.InvalidArgumentException) as exc:
            raise FrameError(f'no transform from {source!r} to {target!r}{f" at {stamp:.3f} s" if stamp else ""} '
                             f'within {timeout:g} s: {exc}') from None
        t, r = tf.transform.translation, tf.transform.rotation
        T = np.eye(4)
        T[:3, :3] = Rotation.from_quat([r.x, r.y, r.z, r.w]).as_matrix()
        T[:3, 3] = [t.x, t.y, t.z]
        return T

    def frames(self):
        return sorted(self.buffer._getFrameStrings())  # noqa: SLF001 - tf2_ros has no public list of frames

    def destroy(self):
        self.listener.unregister()
