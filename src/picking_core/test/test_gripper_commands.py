"""The gripper as an action of its own: the commands a plan's opening column becomes, and their answers."""

import numpy as np
import pytest

from picking_core.goals.gripper import GripperCommand, GripperSchedule, gripper_moves, judge
from picking_core.pick_cycle import GRIPPER_JOINT, PickCycle, PickSettings
from picking_core.planning import Planner


def test_each_move_of_the_opening_becomes_one_command_at_its_start_to_its_end():
    t = np.arange(10) * 0.1
    g = np.array([0.09, 0.09, 0.08, 0.06, 0.055, 0.055, 0.055, 0.07, 0.09, 0.09])
    assert gripper_moves(t, g) == [(pytest.approx(0.1), 0.055), (pytest.approx(0.6), 0.09)]
    assert gripper_moves(t, np.full(10, 0.09)) == []


def test_a_pick_cycle_closes_at_the_grasp_and_opens_at_the_release(arm):
    from scipy.spatial.transform import Rotation

    from picking_core.goals.runner import waypoints
    from picking_core.kinematics import pose_matrix
    s = PickSettings()
    home = np.asarray(s.home_positions)
    plan = PickCycle(Planner(arm), s).plan((home, 0 * home, 0 * home),
                                          pose_matrix([0.7, 0.15, 0.65], Rotation.from_euler('y', 90, degrees=True)
                                                      .as_quat()))
    names = plan.joint_names
    t, q, _, _ = waypoints(plan.trajectory, 0.1)
    moves = gripper_moves(t, q[:, list(names).index(GRIPPER_JOINT)])
    grasp = next(seg for seg in plan.segments if seg.label == 'grasp')
    release = next(seg for seg in plan.segments if seg.label == 'release')
    assert [target for _, target in moves] == [pytest.approx(s.gripper_closed), pytest.approx(s.gripper_open)]
    assert moves[0][0] == pytest.approx(grasp.start) and moves[1][0] == pytest.approx(release.start)


@pytest.mark.parametrize('answer, failed', [
    ((True, 'succeeded', 0.055, False, True), ''),
    ((True, 'aborted', 0.07, True, False), ''),                        # stalled on the apple: holding it
    ((True, 'aborted', 0.09, False, False), 'ended aborted at 0.09'),  # did not move
    ((False, 'rejected', 0.0, False, False), 'refused the command'),
])
def test_an_answer_is_a_failure_only_when_the_gripper_did_not_do_its_job(answer, failed):
    why = judge(GripperCommand(1.0, 0.055), *answer)
    assert (why == '') if not failed else failed in why


def test_a_newer_plan_drops_the_commands_due_after_its_start_and_a_cancel_its_own():
    s = GripperSchedule()
    s.plan(1, 10.0, [(1.0, 0.055), (3.0, 0.09)])
    assert [k for k, _ in s.due(11.5)] == [1]                          # the close went
    s.plan(2, 12.0, [(0.5, 0.055)])
    assert [c.at for c in s.commands[1]] == [11.0]                     # its open at 13.0 is the new plan's now
    assert s.next_time() == 12.5
    s.drop(2)
    assert s.next_time() is None
    done, failure = s.settled(1)
    assert not done
    s.commands[1][0].done, s.commands[1][0].failure = True, 'x'
    assert s.settled(1) == (True, 'x')
