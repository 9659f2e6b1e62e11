"""Running a node: init, spin, clean exits on SIGINT and SIGTERM, stack dumps on SIGUSR1."""

from __future__ import annotations

import faulthandler
import gc
import signal
import sys
import threading

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions

#: s a thread waiting for the GIL lets the holder run before asking for it: a 1 kHz loop thread
#: that wakes while another thread of its process runs Python code starts about that much late
#: (Python's default interval is several control periods long).
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
    # for the GIL up to the switch interval: keep that short.
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
        # garbage collector's full passes, which would otherwise stall a loop thread.
        # Collected before the node starts its loop thread, which the collection would stall.
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
