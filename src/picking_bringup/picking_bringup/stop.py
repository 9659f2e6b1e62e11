"""``picking-goal stop``: cancel every goal of one arm's planner and controller, at once.

A stop is a process started beside running nodes, and its start-up (Python's imports, the middleware, discovery)
is most of the time it takes to act. So a stop runs from here with the fewest imports and a node without services
of its own (fewer endpoints to discover); :mod:`picking_bringup.picking_goal` sends every other subcommand on to
:func:`picking_bringup.goal.main`.
"""

from __future__ import annotations

import os
import sys
import time

#: The actions a stop cancels: the planner's three and its controller's (which runs the plans of the topics' goals
#: and of a harvest too).
STOPPED = ('move_to_pose', 'follow_path', 'pick', 'follow_joint_trajectory')
#: s of discovery after which a tool says what it still waits for.
DISCOVERY = 2.0
#: picking-goal's exit codes (its docstring explains them).
EXIT_OK, EXIT_REFUSED, EXIT_ARGS, EXIT_FAILED, EXIT_TIMEOUT = 0, 1, 2, 3, 4
DEFAULT_TIMEOUT = 30.0


def stop_asked(argv):
    """The timeout of a plain ``picking-goal [--timeout T] stop [--timeout T]`` (ROS arguments aside), else None:
    help, anything else or a bad value go to picking-goal's full parser, which says what is wrong."""
    from rclpy._rclpy_pybind11 import RCLInvalidROSArgsError, UnknownROSArgsError
    from rclpy.utilities import remove_ros_args
    try:
        own = remove_ros_args(argv)[1:]
    except (RCLInvalidROSArgsError, UnknownROSArgsError):
        return None
    kind, timeout, i = None, DEFAULT_TIMEOUT, 0
    while i < len(own):
        word = own[i]
        if word.startswith('--timeout'):
            value = word.split('=', 1)[1] if '=' in word else (own[i + 1] if i + 1 < len(own) else '')
            i += 1 if '=' in word else 2
            try:
                timeout = float(value)
            except ValueError:
                return None
        elif word == '--no-wait':
            i += 1
        elif kind is None and not word.startswith('-'):
            kind, i = word, i + 1
        else:
            return None
    if kind != 'stop' or not (timeout > 0 and timeout < float('inf')):
        return None
    return timeout


def spin_until(node, predicate, timeout):
    """Spin ``node`` until ``predicate()`` is true (returns its value) or ``timeout`` s passed (None)."""
    import rclpy
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
        result = predicate()
        if result:
            return result
    return None


def stop(node, timeout):
    """Cancel every goal of :data:`STOPPED`, whoever sent it, at once: each cancel service is asked as soon as it is
    found (a cancel request naming no goal cancels all), the planner's without waiting for the controller's to be
    discovered (a canceled plan's goal at the controller is canceled by the planner too)."""
    from action_msgs.srv import CancelGoal
    clients = {name: node.create_client(CancelGoal, f'{name}/_action/cancel_goal') for name in STOPPED}
    futures = {}

    def ask():
        for name, client in clients.items():
            if name not in futures and client.service_is_ready():
                futures[name] = client.call_async(CancelGoal.Request())
        return len(futures) == len(clients) and all(f.done() for f in futures.values())
    import rclpy
    start = time.monotonic()
    waiting = False
    while not ask() and time.monotonic() - start < timeout:
        if not waiting and len(futures) < len(clients) and time.monotonic() - start > DISCOVERY:
            # (A process just started may need longer than that to discover the services on a busy machine.)
            print(f'picking-goal: waiting up to {timeout:g} s for the action servers', file=sys.stderr, flush=True)
            waiting = True
        # (Discovery wakes no executor: a short spin looks again soon.)
        rclpy.spin_once(node, timeout_sec=0.01)
    if not futures:
        print('picking-goal: no action server to stop (is the arm up, in this namespace?)', file=sys.stderr)
        return EXIT_TIMEOUT
    missing = sorted(set(clients) - set(futures))
    if missing:
        print(f'picking-goal: no {", ".join(missing)} server: not stopped there', file=sys.stderr)
    canceling = {name: len(f.result().goals_canceling) for name, f in futures.items() if f.done() and f.result()}
    total = sum(canceling.values())
    if total:
        where = ', '.join(f'{n} {name}' for name, n in canceling.items() if n)
        print(f'stop: {total} goal{"s" if total != 1 else ""} canceling ({where}): the arm brakes to rest',
              flush=True)
    else:
        print('stop: no goal was running; the arm holds where it is', flush=True)
    return EXIT_OK if len(canceling) == len(futures) else EXIT_TIMEOUT


def without_generators():
    """Keep rosidl's code generator out of this process, which only sends messages: a message type's first use
    imports ``rosidl_generator_py``, whose ``__init__`` also imports its generator (with lark and empy, slow to
    import) and goes on without it when that import fails, as it then does."""
    sys.modules.setdefault('rosidl_generator_py.generate_py_impl', None)


def in_a_node(make_node, argv, work, cut_short):
    """``work(node)``'s exit code, in a node ``make_node()`` of this process (rclpy started with ``argv``); an
    interrupt (Ctrl-C, or SIGTERM as `timeout` sends it) ends it with EXIT_TIMEOUT, saying it came before
    ``cut_short``; the node and rclpy are closed either way."""
    import rclpy
    from rclpy.executors import ExternalShutdownException

    from picking_common.middleware import use_fast_discovery
    use_fast_discovery()
    rclpy.init(args=argv)
    node = make_node()
    try:
        return work(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        print(f'picking-goal: stopped before {cut_short}', file=sys.stderr)
        return EXIT_TIMEOUT
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def main(argv, timeout):
    """A stop in a process of its own: ``argv`` may name the arm (``--ros-args -r __ns:=/arm2``)."""
    without_generators()

    def make_node():
        from rclpy.node import Node
        from rclpy.parameter import Parameter
        return Node(f'picking_goal_{os.getpid()}', start_parameter_services=False, enable_rosout=False,
                    parameter_overrides=[Parameter('start_type_description_service', value=False)])
    return in_a_node(make_node, argv, lambda node: stop(node, timeout), 'the stop was answered')
