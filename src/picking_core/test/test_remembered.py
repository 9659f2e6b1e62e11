"""The planner that remembers its moves: the same move asked again is answered from memory (the
trajectory, or the refusal), another is planned, and memory stays bounded."""

import numpy as np
import pytest
from conftest import shipped_harvest

from picking_core.kinematics import Unreachable
from picking_core.planning.remembered import Remembered

HOME = np.array([0.0, 0.2, 1.6, 0.0, -0.23, 0.0])


@pytest.fixture()
def planner():
    return shipped_harvest().cycle.planner


def test_a_move_asked_again_is_the_same_answer_and_another_is_planned(planner):
    memo = Remembered(getattr(planner, 'planner', planner))
    goal = HOME + 0.3
    a = memo.joint_move(HOME, goal, 'optimal')
    assert memo.joint_move(HOME.copy(), goal.copy(), 'optimal') is a
    assert (memo.asked, memo.answered) == (2, 1)
    b = memo.joint_move(HOME, goal + 0.1, 'optimal')
    assert b is not a and b.duration > a.duration
    # Everything else is the planner's own.
    assert memo.arm is planner.arm and memo.settings == planner.settings


def test_a_refusal_asked_again_is_refused_again_with_the_same_words(planner):
    memo = Remembered(getattr(planner, 'planner', planner))
    far = np.eye(4)
    far[:3, 3] = [3.0, 0.0, 0.5]
    words = []
    for _ in range(2):
        with pytest.raises(Unreachable) as refused:
            memo.line(HOME, planner.arm.fk(HOME), far)
        words.append(str(refused.value))
    assert words[0] == words[1] and 'reach' in words[0] and memo.answered == 1


def test_memory_keeps_the_most_recent_answers_only(planner):
    memo = Remembered(getattr(planner, 'planner', planner), size=3)
    goals = [HOME + 0.05 * k for k in range(1, 5)]
    first = [memo.joint_move(HOME, g, 'optimal') for g in goals]
    assert memo.joint_move(HOME, goals[-1], 'optimal') is first[-1]           # still remembered
    assert memo.joint_move(HOME, goals[0], 'optimal') is not first[0]         # forgotten, planned again
