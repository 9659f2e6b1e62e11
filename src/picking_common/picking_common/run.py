"""Running a node: init, spin, clean exits on SIGINT and SIGTERM, stack dumps on SIGUSR1."""

from __future__ import annotations

import faulthandler
import gc
import os
import signal
import sys
import threading

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions

from .loop import make_normal
from .middleware import use_fast_discovery
from .startup import LAUNCHER_PID, launcher_check
from .topics import destroy_latest, quiet_event_handlers

#: s a node may take to stop once asked (its launcher kills it some seconds later).
STOP_LIMIT = 6.0
#: s a thread waiting for the GIL lets the holder run before asking for it: a 1 kHz loop thread
#: that wakes while another thread of its process runs Python code starts about that much late
#: (Python's default interval is several control periods long).
SWITCH_INTERVAL = 2e-5


def run_node(make_node, args=None, help=None):
    """Init, build the node, spin, and exit 0 without a traceback on SIGINT/SIGTERM.

    ``-h`` / ``--help`` before the ROS arguments prints ``help`` and exits 0; any other argument
    there is refused (exit 2): a node takes only ROS arguments.
    rclpy's own signal handling can race with a multi-threaded executor at
    shutdown (an RCLError from a wait set, or a spin that never wakes), so the
    signals only set a flag here and the main thread spins in short slices.
    """
    from rclpy._rclpy_pybind11 import RCLError
    argv = sys.argv if args is None else args
    prog = os.path.basename(argv[0]) if argv else 'node'
    refused = _own_arguments(argv, prog, help)
    if refused is not None:
        return refused
    orphaned = launcher_check()
    stop = threading.Event()

    def on_signal(signum, frame):
        stop.set()

    # A real-time loop thread that wakes while another thread runs Python code waits
    # for the GIL up to the switch interval: keep that short.
    sys.setswitchinterval(SWITCH_INTERVAL)
    try:
        use_fast_discovery()
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except RCLError as exc:
        print(f'{prog}: ROS could not start: {exc}{_security_hint()}', file=sys.stderr)
        return 1
    old = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    _stacks_on_request()
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
        except RCLError as exc:
            print(f'{prog}: ROS could not make the node: {exc}{_security_hint()}', file=sys.stderr)
            return 1
        gc.freeze()                              # the node's own objects too (no collection: cheap)
        _warn_if_named_twice(node)
        # One executor thread: rclpy's multi-threaded executor costs far more per
        # callback, and each node's real-time loop runs in a thread of its own.
        executor = SingleThreadedExecutor()
        quiet_event_handlers(node)
        executor.add_node(node)
        while not stop.is_set() and rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
            if orphaned():
                node.get_logger().warning(f'its launcher (pid {os.environ[LAUNCHER_PID]}) is gone: stopping')
                break
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        _teardown(node, executor)
        for sig, handler in old.items():
            signal.signal(sig, handler)
    return 0


def _stacks_on_request():
    """A node that does not stop: `kill -USR1 <pid>` writes every thread's Python stack to stderr (from C, even
    while a thread holds the GIL or waits in the middleware), and a crash writes its stack too."""
    faulthandler.enable()
    if hasattr(signal, 'SIGUSR1'):
        faulthandler.register(signal.SIGUSR1, all_threads=True)


def _teardown(node, executor):
    """Close the node (its own ``close`` first: loops, threads), the executor, then rclpy. A node that does not
    finish within STOP_LIMIT writes every thread's stack and exits 1 (from C: even a thread stuck holding the GIL
    in the middleware cannot hold the process up)."""
    faulthandler.dump_traceback_later(STOP_LIMIT, exit=True)
    make_normal()           # a node that made this thread real-time to serve tears down as any other
    if node is not None:
        close = getattr(node, 'close', None)
        if close:
            close()
    if executor is not None:
        executor.shutdown(timeout_sec=1.0)
    if node is not None:
        destroy_latest(node)
        node.destroy_node()
    rclpy.try_shutdown()


def _own_arguments(argv, prog, help):
    """The exit code for arguments a node does not run with (None when it takes them all): 0 after printing
    ``help`` for ``-h``/``--help`` before the ROS arguments, 2 naming a bad ROS argument or one of its own."""
    from rclpy._rclpy_pybind11 import RCLInvalidROSArgsError
    from rclpy.utilities import remove_ros_args
    try:
        own = remove_ros_args(argv)[1:]
    except RCLInvalidROSArgsError as exc:
        print(f'{prog}: error: {str(exc).split(", at ")[0]}', file=sys.stderr)
        return 2
    if help is not None and ('-h' in own or '--help' in own):
        print(help)
        return 0
    if own:
        print(f'{help.splitlines()[0] if help else prog}\n{prog}: error: unrecognized arguments: {" ".join(own)} '
              '(a node takes only ROS arguments, after --ros-args)', file=sys.stderr)
        return 2
    return None


def _security_hint():
    """Why a node asked to run secured fails to start, when it was: the Fast DDS of the PyPI wheels has no
    DDS-Security plugins, so an enforced secure start cannot succeed there whatever the keystore holds."""
    if os.environ.get('ROS_SECURITY_ENABLE', '').lower() != 'true':
        return ''
    return ('\nDDS security was asked for (ROS_SECURITY_ENABLE=true, ROS_SECURITY_STRATEGY='
            f'{os.environ.get("ROS_SECURITY_STRATEGY", "Permissive")}). Check ROS_SECURITY_KEYSTORE and the enclave '
            "of this node; and note the PyPI wheels' Fast DDS has no security plugins: secured nodes need an "
            'apt-installed Jazzy (docs/deployment.md, "Security").')


#: s between a node's looks for another of its name, and how many it takes (discovery may be slow on a
#: busy host); then its timer is gone.
NAME_CHECK, NAME_CHECKS = 2.0, 5


def _warn_if_named_twice(node):
    """An ERROR when another node of this name runs in this namespace (both would answer every
    message; one of them should stop): looked for every NAME_CHECK s, NAME_CHECKS times, until found."""
    looks = [0]

    def check():
        looks[0] += 1
        me = (node.get_name(), node.get_namespace())
        count = sum(1 for n in node.get_node_names_and_namespaces() if n == me)
        if count > 1:
            node.get_logger().error(f'{count} nodes named {node.get_fully_qualified_name()} run in this ROS domain: '
                                    'each answers every message (trajectories run twice, goals planned twice); '
                                    'stop all but one, or start this one in its own namespace (-r __ns:=/arm2)')
        if count > 1 or looks[0] >= NAME_CHECKS:
            timer.cancel()
    timer = node.create_timer(NAME_CHECK, check)


class BackgroundSpin:
    """``node``'s callbacks run on a thread of their own until :meth:`stop` (a tool or test that
    goes on doing its own work meanwhile)."""

    def __init__(self, node, period=0.05):
        self._executor = SingleThreadedExecutor()
        self._executor.add_node(node)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, args=(period,), daemon=True)
        self._thread.start()

    def _spin(self, period):
        while not self._stop.is_set():
            self._executor.spin_once(timeout_sec=period)

    def stop(self, timeout=5.0):
        self._stop.set()
        self._thread.join(timeout)
        self._executor.shutdown()
