"""Plumbing shared by the three nodes: start/stop, status messages, joint states.

This is ROS glue (it imports rclpy), kept out of the pure core.
"""

from __future__ import annotations

import faulthandler
import functools
import gc
import math
import os
import signal
import sys
import threading
import time

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState

from . import cdr

OK, WARN, ERROR = DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR
#: s a thread waiting for the GIL lets the holder run before asking for it. A 1 kHz loop
#: thread that wakes while another thread of its process runs Python code starts that much
#: (plus about 30 µs) late: measured here, 135 µs late at 1e-4 s, 50 µs at 2e-5 s, 3 ms at
#: Python's default 5e-3 s.
SWITCH_INTERVAL = 2e-5


def run_node(make_node, args=None):
    """Init, build the node, spin, and exit 0 without a traceback on SIGINT/SIGTERM.

    rclpy's own signal handling can race with a multi-threaded executor at
    shutdown (an RCLError from a wait set, or a spin that never wakes), so the
    signals only set a flag here and the main thread spins in short slices.
    """
    stop = threading.Event()

    def on_signal(signum, frame):
        stop.set()

    # A real-time loop thread that wakes while another thread runs Python code waits
    # for the GIL up to the switch interval (5 ms by default): keep that short.
    sys.setswitchinterval(SWITCH_INTERVAL)
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    old = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    # A node that does not stop: `kill -USR1 <pid>` writes every thread's Python stack to
    # stderr (from C, even while a thread holds the GIL or waits in the middleware), and a
    # crash writes its stack too.
    faulthandler.enable()
    if hasattr(signal, 'SIGUSR1'):
        faulthandler.register(signal.SIGUSR1, all_threads=True)
    node = executor = None
    try:
        # Everything loaded so far lives as long as the process: keep it out of the
        # garbage collector's full passes, which would otherwise stall a loop thread
        # for milliseconds. Collected before the node starts its loop thread: the
        # collection holds the GIL for about 0.1 s.
        gc.collect()
        gc.freeze()
        try:
            node = make_node()
        except (ValueError, FileNotFoundError) as exc:
            # A bad parameter or file: say what, exit non-zero, no traceback.
            print(f'{sys.argv[0]}: {exc}', file=sys.stderr)
            return 2
        gc.freeze()                              # the node's own objects too (no collection: cheap)
        # One executor thread: rclpy's multi-threaded executor costs far more per
        # callback, and each node's real-time loop runs in a thread of its own.
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        while not stop.is_set() and rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            close = getattr(node, 'close', None)
            if close:
                close()
        if executor is not None:
            executor.shutdown(timeout_sec=1.0)
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
        for sig, handler in old.items():
            signal.signal(sig, handler)
    return 0


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
    several arms on one machine, given different phases, wake at their own moments of each
    period instead of wherever they happened to start (in the benchmarks, four arms at 1 kHz on
    2 cores: the worst loop's p99 period error 64-130 µs phased, 128-390 µs free running)."""
    now = time.monotonic() if now is None else now
    if phase < 0.0:
        return now
    return (math.floor(now / period - phase) + phase) * period


def stamp_key(stamp):
    """A header stamp as text, ``'sec.nanosec'``: how goals and trajectories are named in status
    values. ``stamp``: a builtin_interfaces/Time, or integer nanoseconds."""
    sec, nanosec = divmod(stamp, 1_000_000_000) if isinstance(stamp, int) else (stamp.sec, stamp.nanosec)
    return f'{sec}.{nanosec:09d}'


def status(name, level, message, **values):
    """A DiagnosticStatus with key/value pairs (values formatted as text)."""
    msg = DiagnosticStatus()
    msg.level = level
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


def joint_state_reader():
    """A reader of JointState bytes for :class:`LatestMessage` (about a third of the message
    class's cost), or None where this middleware's bytes differ from ours."""
    return cdr.JointStateReader().read if cdr.check() else None


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


def newest_waiting(sub, msg, on_older):
    """The newest message waiting on subscription ``sub``: ``msg`` (just delivered by the
    executor) or a later one taken at once; ``on_older`` is called with each older one.

    A burst then never builds a backlog: the newest is handled, every older one is
    answered (as superseded) without being worked on.
    """
    while (got := sub.handle.take_message(sub.msg_type, sub.raw)) is not None:
        on_older(msg)
        msg = got[0]
    return msg


class LatestMessage:
    """The newest message of a fast topic, taken on demand instead of by a callback.

    A 1 kHz stream costs an rclpy executor a large share of a core in callbacks;
    a reader that needs only the newest sample (the simulator's servo loop, the
    planner when a goal comes) keeps a depth-1 subscription on a hidden helper
    node that no executor spins, and takes from it when it wants. With a
    ``reader`` (bytes -> message-like object, ValueError if it cannot), the
    messages are taken as bytes and only the newest is read; bytes the reader
    refuses are read by the message class instead.
    """

    def __init__(self, parent, msg_type, topic, reader=None):
        self.msg_type = msg_type
        self.reader = reader
        self.node = rclpy.create_node(f'_{parent.get_name()}_{topic.strip("/").replace("/", "_")}_tap',
                                      namespace=parent.get_namespace())
        qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT, history=HistoryPolicy.KEEP_LAST)
        self.sub = self.node.create_subscription(msg_type, topic, lambda msg: None, qos, raw=reader is not None)
        self.last = None

    def take(self):
        """The newest message received so far (None before the first)."""
        raw = self.reader is not None
        newest = None
        while True:
            got = self.sub.handle.take_message(self.msg_type, raw)
            if got is None:
                break
            newest = got[0]
        if newest is not None:
            if raw:
                try:
                    newest = self.reader(newest)
                except ValueError:
                    newest = deserialize_message(newest, self.msg_type)
            self.last = newest
        return self.last

    def publisher_count(self):
        return self.sub.get_publisher_count()

    def destroy(self):
        self.node.destroy_node()
