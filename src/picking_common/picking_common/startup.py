"""A node process's first step: Ctrl-C or SIGTERM while it is still starting ends it quietly.

A node's module imports numpy, scipy, rclpy and its messages before it can handle a signal, and Python's own
handler turns Ctrl-C there into a KeyboardInterrupt traceback wherever the import happens to be (a stack stopped
while one of its nodes fails to start, or a user's Ctrl-C during bring-up). The console scripts therefore call
:func:`quietly`, which imports only the standard library, takes those signals as a request to stop (exit code 0,
nothing printed), then imports the node and runs it; once running, a node handles them itself (rclpy's handlers,
:func:`picking_common.run.run_node`). ``kill -USR1 <pid>`` writes every thread's stack from the start too (a node
that seems stuck while it starts), instead of killing it.
"""

from __future__ import annotations

import faulthandler
import importlib
import os
import signal

#: The variable a launcher sets to its process id: the node stops when that process is gone.
LAUNCHER_PID = 'PICKING_LAUNCHER_PID'


def launcher_gone(environ):
    """A check, True once the launcher named by :data:`LAUNCHER_PID` in ``environ`` is no longer this process's
    parent (always False without one): a node started in a process group of its own does not get the terminal's
    Ctrl-C, and must not outlive a launcher killed before it could stop the node. A variable inherited from further
    up (the launcher is not the parent at start) is ignored."""
    try:
        launcher = int(environ.get(LAUNCHER_PID, ''))
    except ValueError:
        return lambda: False
    if os.getppid() != launcher:
        return lambda: False
    return lambda: os.getppid() != launcher


#: This process's launcher check, decided by :func:`quietly` at its first step (None: not started through it).
_launcher = None


def launcher_check():
    """This process's :func:`launcher_gone` check: the one :func:`quietly` decided as the process started, while
    its launcher surely ran (a launcher killed while the node still imports is then noticed), else decided now."""
    return _launcher if _launcher is not None else launcher_gone(os.environ)


def _stop(signum, frame):
    raise SystemExit(0)


def quietly(target):
    """Run ``target`` (``'module:function'``), the signals that stop a node ending it quietly until it takes them
    over; its return value (the process's exit code)."""
    global _launcher
    _launcher = launcher_gone(os.environ)
    signal.signal(signal.SIGINT, _stop)
    signal.signal(signal.SIGTERM, _stop)
    if hasattr(signal, 'SIGUSR1'):
        faulthandler.register(signal.SIGUSR1, all_threads=True)
    module, function = target.split(':')
    return getattr(importlib.import_module(module), function)()
