"""System-test fixtures: every ROS process stays on loopback, in a domain of this run's own."""

import os
import subprocess
import sys

import pytest

# Set before any rclpy import in this process and inherited by every child.
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('ROS_DOMAIN_ID', str(os.getpid() % 90 + 10))
os.environ.setdefault('MPLBACKEND', 'Agg')

BIN = os.path.dirname(sys.executable)


@pytest.fixture
def run_tool():
    """Run one of the project's console scripts; returns the CompletedProcess."""
    def run(name, *args, timeout=120):
        return subprocess.run([os.path.join(BIN, name), *map(str, args)], capture_output=True,
                              text=True, timeout=timeout, env=os.environ.copy())
    return run
