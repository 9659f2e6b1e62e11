"""The gripper on its own GripperCommand action (gripper_action_controller's semantics), without ROS."""

import numpy as np
import pytest

from picking_controller.core import ControllerCore

NAMES = ['a', 'b', 'gripper_joint']


def core():
    c = ControllerCore(NAMES, [-3, -3, 0.0], [3, 3, 0.1], [2, 2, 0.4], [5, 5, 5.0], optional=['gripper_joint'],
                       gripper='gripper_joint')
    c.on_state(np.array([0.0, 0.0, 0.09]), None, 0.0, 0.0)
    return c


def run(c, until, measured_at, t=0.0, dt=0.01):
    """Tick to ``until``; the measured opening follows the command down to ``measured_at`` (an apple's width)."""
    answer = None
    while t < until and answer is None:
        t += dt
        ref, _ = c.command(t)
        g = max(ref[0][2], measured_at)
        c.on_state(np.array([ref[0][0], ref[0][1], g]), None, t, t)
        answer = c.gripper.judge(t, c.measured_gripper())
    return answer, t


def test_a_command_moves_only_the_gripper_within_its_limits_and_succeeds_there():
    c = core()
    c.command_gripper(0.055, 0.0)
    answer, t = run(c, 2.0, 0.0)
    assert answer.word == 'succeeded' and answer.reached and not answer.stalled
    assert answer.position == pytest.approx(0.055, abs=1e-6) and t < 0.5
    ref, _ = c.command(t)
    assert ref[0][:2] == pytest.approx([0.0, 0.0])                       # the arm held


def test_closing_on_an_apple_stalls_and_ends_aborted_after_the_stall_timeout():
    c = core()
    c.command_gripper(0.055, 0.0)
    answer, t = run(c, 3.0, 0.07)
    assert answer.word == 'aborted' and answer.stalled and not answer.reached
    assert answer.position == pytest.approx(0.07) and 1.0 <= t < 1.5


def test_a_target_beyond_the_joint_is_refused_and_an_arm_without_gripper_has_none():
    with pytest.raises(ValueError, match='beyond the joint'):
        core().command_gripper(0.2, 0.0)
    c = ControllerCore(['a'], [-1], [1], [1], [1])
    with pytest.raises(ValueError, match='no gripper'):
        c.command_gripper(0.05, 0.0)


def test_a_trajectory_naming_the_gripper_takes_it_back():
    c = core()
    c.command_gripper(0.055, 0.0)
    assert c.gripper.owns
    c.gripper.release()
    ref, _ = c.command(0.5)
    assert ref[0][2] == pytest.approx(0.09)                               # the schedule's own reference again
