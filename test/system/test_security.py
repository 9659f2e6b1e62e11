"""DDS security on the pip route: the wheels' Fast DDS has no security plugins, so a node asked to run secured
(enforced) does not run unsecured instead: it exits 1 saying why, with no traceback; a bad ROS argument exits 2."""

import os
import subprocess

from rosstack import BIN


def start(tmp_path, *args, **env):
    return subprocess.run([str(BIN / 'picking-state-publisher'), *args], capture_output=True, text=True, timeout=60,
                          env={**os.environ, **env})


def test_a_node_asked_for_enforced_security_refuses_to_run_and_says_why(tmp_path):
    (tmp_path / 'enclaves' / 'picking_state_publisher').mkdir(parents=True)
    done = start(tmp_path, '--ros-args', '--enclave', '/picking_state_publisher', ROS_SECURITY_ENABLE='true',
                 ROS_SECURITY_STRATEGY='Enforce', ROS_SECURITY_KEYSTORE=str(tmp_path))
    assert done.returncode == 1, (done.stdout, done.stderr)
    assert 'DDS security was asked for' in done.stderr and 'apt-installed Jazzy' in done.stderr, done.stderr
    assert 'Traceback' not in done.stderr


def test_a_bad_ros_argument_exits_2_naming_it():
    done = subprocess.run([str(BIN / 'picking-controller'), '--ros-args', '-p', 'bad'], capture_output=True,
                          text=True, timeout=60, env=os.environ.copy())
    assert done.returncode == 2 and "'-p bad'" in done.stderr and 'Traceback' not in done.stderr, done.stderr
