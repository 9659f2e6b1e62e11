"""A small tree harvested end to end by two arms, as `picking-stack --platform` and `picking-goal tree`
start it: every apple in a box, and the arms, watched through their own joint_states, never closer
than the clearance."""

import os
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from rosstack import RELIABLE, ensure_rclpy
from sensor_msgs.msg import JointState

from picking_bringup.shipped import shipped_harvest
from picking_common.joint_state import reorder
from picking_common.run import BackgroundSpin
from picking_core.kinematics.capsules import ArmCapsules, capsule_distances
from picking_core.platform import CLEARANCE, Coordinator, Platform
from picking_description import platform_path

NS = '/platform'
BIN = Path(sys.executable).parent


class Witness:
    """Both arms' joint states, as published, and the least distance between their capsules."""

    def __init__(self, node, platform, arms):
        self.lock = threading.Lock()
        self.latest, self.closest = {}, np.inf
        self.platform, self.arms = platform, arms
        self.caps = [ArmCapsules.from_arm(a) for a in arms]
        for k, m in enumerate(platform.arms):
            node.create_subscription(JointState, f'{NS}/{m.namespace}/joint_states',
                                     lambda msg, k=k: self._on(k, msg), RELIABLE)

    def _on(self, k, msg):
        q = reorder(msg.name, msg.position, self.arms[k].joint_names, 'joint_states')
        with self.lock:
            self.latest[k] = self.caps[k].segments(q[None], self.platform.arms[k].base)
            if len(self.latest) == 2:
                d = capsule_distances(self.latest[0], self.caps[0].radius, self.latest[1], self.caps[1].radius)
                self.closest = min(self.closest, float(d.min()))


@pytest.fixture(scope='module')
def platform(tmp_path_factory):
    from picking_bringup.stack import PlatformStack
    ensure_rclpy()
    stack = PlatformStack(layout='two', ns=NS, log_dir=tmp_path_factory.mktemp('logs'))
    try:
        stack.wait_ready()
        yield stack
    finally:
        codes = stack.stop()
    assert set(codes.values()) == {0}, codes


def test_two_arms_harvest_a_tree_and_never_come_within_the_clearance(platform):
    import rclpy
    node = rclpy.create_node(f'platform_witness_{os.getpid()}')
    p = Platform.from_yaml(platform_path(), 'two')
    witness = Witness(node, p, [h.arm for h in Coordinator.from_platform(p, shipped_harvest).harvests])
    spinner = BackgroundSpin(node)
    try:
        done = subprocess.run([str(BIN / 'picking-goal'), 'tree', '--tree', '8', '--seed', '2', '--layout', 'two',
                               '--timeout', '60', '--ros-args', '-r', f'__ns:={NS}'],
                              capture_output=True, text=True, timeout=400, env=os.environ.copy())
    finally:
        spinner.stop()
        node.destroy_node()
    out = done.stdout
    assert done.returncode == 0, out + done.stderr
    assert re.search(r'tree succeeded: 8 of 8 apples picked', out), out
    picked = {int(m) for m in re.findall(r'arm\d: apple (\d+) delivered', out)}
    assert picked == set(range(8)), out
    # Both arms took part, each from its own namespace.
    assert 'arm1: sent' in out and 'arm2: sent' in out, out
    # The coordinator's witness and the test's agree that the arms stayed apart.
    assert witness.closest >= CLEARANCE, f'the arms came within {witness.closest:.3f} m'
    measured = float(re.search(r'measured (-?[\d.]+) cm', out).group(1)) / 100
    assert measured >= CLEARANCE


def test_tf_from_every_arm_is_each_arms_fk_in_the_platform_frame(platform):
    """Each arm's links on /tf under its prefix, its base in the platform frame where the platform file puts it: the
    tool of every arm, looked up from the platform frame, is that arm's mount times its FK of its joint states."""
    import rclpy

    from picking_common.tf import FrameListener, stamp_seconds
    node = rclpy.create_node(f'platform_frames_{os.getpid()}')
    p = Platform.from_yaml(platform_path(), 'two')
    arms = [h.arm for h in Coordinator.from_platform(p, shipped_harvest).harvests]
    states = {}
    for k, m in enumerate(p.arms):
        node.create_subscription(JointState, f'{NS}/{m.namespace}/joint_states',
                                 lambda msg, k=k: states.__setitem__(k, msg), RELIABLE)
    frames = FrameListener(node, prefer='picking_core')
    spinner = BackgroundSpin(node)
    try:
        end = time.monotonic() + 10.0
        while len(states) < len(p.arms) and time.monotonic() < end:
            time.sleep(0.05)
        assert len(states) == len(p.arms), f'joint_states of arms {sorted(states)} only'
        for k, m in enumerate(p.arms):
            tool = f'{NS.strip("/")}/{m.namespace}/tool0'
            frames.transform(p.frame, tool, 0.0, 10.0)   # /tf heard (it may come after the first joint states) ...
            state = states[k]                     # ... then the tool at the newest state's stamp, against its FK
            T = frames.transform(p.frame, tool, stamp_seconds(state.header.stamp), 10.0)
            q = reorder(state.name, state.position, arms[k].joint_names, 'joint_states')
            assert np.abs(T[:3, 3] - (m.base @ arms[k].fk(q))[:3, 3]).max() < 1e-4, m.namespace
    finally:
        spinner.stop()
        frames.destroy()
        node.destroy_node()
