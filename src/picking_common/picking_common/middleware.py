"""The middleware settings every picking process starts with (before ``rclpy.init``).

With Fast DDS (ROS 2 Jazzy's default middleware) and no profile of the user's own, the processes load
``fastdds.xml`` beside this module: each participant announces itself every 0.1 s, so that a process started beside
running nodes discovers them in a fraction of a second, and sends its data over loopback UDP, not through shared
memory ports a stall can leave unread (see docs/deployment.md). A user's own profile
(``FASTRTPS_DEFAULT_PROFILES_FILE`` or ``FASTDDS_DEFAULT_PROFILES_FILE``), or another middleware, is left alone.
"""

from __future__ import annotations

import os
from pathlib import Path

PROFILE = Path(__file__).with_name('fastdds.xml')
#: The middlewares that read a Fast DDS profile.
FAST_DDS = ('', 'rmw_fastrtps_cpp', 'rmw_fastrtps_dynamic_cpp')
#: The environment variables Fast DDS takes a profile file from (its 2.x name, then its 3.x one).
PROFILE_VARIABLES = ('FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_DEFAULT_PROFILES_FILE')


def use_fast_discovery(environ=os.environ):
    """Point Fast DDS at :data:`PROFILE` in ``environ`` (the process's environment, inherited by the processes it
    starts) unless the user chose a profile or another middleware; True when it did."""
    if environ.get('RMW_IMPLEMENTATION', '') not in FAST_DDS or any(environ.get(v) for v in PROFILE_VARIABLES):
        return False
    environ[PROFILE_VARIABLES[0]] = str(PROFILE)
    return True
