"""``picking-goal``'s entry point: a plain stop takes :mod:`.stop`'s quick path, everything else :mod:`.goal`."""

from __future__ import annotations

import os
import sys

from .stop import stop_asked


def main(argv=None):
    argv = sys.argv if argv is None else argv
    timeout = stop_asked(argv)
    if timeout is not None:
        from .stop import main as stop_main
        code = stop_main(argv, timeout)
        # The stop is done and rclpy shut down: the interpreter's own teardown would only keep the shell waiting.
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    from .goal import main as goal_main
    return goal_main(argv)
