"""Faults mid-motion, each on a stack of its own: the goal ends in a reported result and the arm in
a safe hold. Run calm by `make test` and beside four CPU-bound processes by `make test-load`."""

import os
import signal
import time

import pytest
from action_msgs.msg import GoalStatus
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from picking_interfaces.action import MoveToPose, Pick
from rosstack import GOALS, KILLED, make_pose, reach, running_stack

from picking_common.actions import ActionClient
from picking_common.status import status_values

pytestmark = pytest.mark.load


def stamped(xyz):
    msg = PoseStamped()
    msg.header.frame_id = 'base_link'
    msg.pose = make_pose(xyz)
    return msg


def start_goal(client, kind, name, goal):
    action = ActionClient(client, kind, name)
    assert action.wait_for_server(timeout_sec=20.0), f'no {name} server'
    feedback = []
    sent = action.send_goal_async(goal, feedback_callback=lambda fb: feedback.append(fb.feedback))
    handle = client.wait_for(lambda: sent.done() and sent.result(), 20.0, 'the goal response')
    client.wait_for(lambda: any(f.phase not in ('sent', 'accepted', 'starting') for f in feedback), 30.0,
                    'the motion to start')
    return action, handle


def held(client, seconds=0.5):
    """The arm at rest: every joint's measured velocity below 1 mrad/s over ``seconds``."""
    time.sleep(seconds)
    with client.lock:
        last = [m for _, m in client.states[-20:]]
    return max(abs(v) for m in last for v in m.velocity[:6]) < 1e-3


def test_a_controller_paused_mid_motion_goes_on_later_and_the_goal_succeeds(tmp_path):
    """SIGSTOP for 0.5 s at speed (a loaded machine stops a process): the simulated drive holds the
    arm; the trajectory goes on later instead of jumping ahead, the feedback watchdog (0.5 s) not
    counting the controller's own stall, and the goal succeeds within the limits."""
    with running_stack('/flt1', tmp_path) as (stack, client):
        action, handle = start_goal(client, MoveToPose, 'move_to_pose', MoveToPose.Goal(pose=stamped([0.5, -0.3, 0.5])))
        client.wait_for(lambda: max(abs(v) for v in client.states[-1][1].velocity[:6]) > 0.2, 10.0,
                        'the arm to move at speed')
        os.kill(stack.controller.pid, signal.SIGSTOP)
        time.sleep(0.5)
        os.kill(stack.controller.pid, signal.SIGCONT)
        result = handle.get_result_async()
        done = client.wait_for(lambda: result.done() and result.result(), 60.0, 'the result')
        assert done.status == GoalStatus.STATUS_SUCCEEDED, done.result.message
        assert held(client)
        log = stack.controller.output()
        assert 'goes on' in log and 'command limited' not in log and 'tolerance violated' not in log
        client.retire(action)


def test_a_planner_killed_mid_cycle_leaves_the_arm_held_and_a_restarted_one_carries_on(tmp_path):
    """SIGKILL to the planner during a pick: the controller finishes the plan it accepted (its
    result on controller_status) and holds; a restarted planner takes the next goal."""
    with running_stack('/flt2', tmp_path) as (stack, client):
        mark = client.mark()
        action, handle = start_goal(client, Pick, 'pick', Pick.Goal(target=stamped([0.55, 0.15, 0.35])))
        client.retire(action)
        stack.planner.proc.kill()
        stack.planner.proc.wait()
        reached = client.controller_event(mark, 'goal reached', 60.0)
        assert reached.level == DiagnosticStatus.OK and held(client)
        # Its planner is gone: the pick's result is the controller's, not an action result.
        GOALS[f'{client.get_namespace()} {bytes(handle.goal_id.uuid).hex()}'] = KILLED
        stack.restart_planner()
        stack.wait_ready(90.0)                          # a loaded machine starts a node slowly
        answer = reach(client, lambda: client.send_pose([0.55, 0.05, 0.45]), timeout=60.0)
        # The new planner's first word on it: accepted, or (when it said that before this client had matched its
        # new planner_status writer, which a killed planner's stale one hides for its lease) executing.
        assert status_values(answer)['state'] in ('accepted', 'executing'), answer.message


def test_a_simulator_killed_mid_motion_aborts_the_goal_with_the_reason_and_the_controller_holds(tmp_path):
    with running_stack('/flt3', tmp_path) as (stack, client):
        mark = client.mark()
        action, handle = start_goal(client, MoveToPose, 'move_to_pose', MoveToPose.Goal(pose=stamped([0.5, -0.3, 0.5])))
        stack.sim.proc.kill()
        stack.sim.proc.wait()
        result = handle.get_result_async()
        done = client.wait_for(lambda: result.done() and result.result(), 30.0, 'the result')
        assert done.status == GoalStatus.STATUS_ABORTED and done.result.outcome == MoveToPose.Result.ABORTED
        assert 'feedback lost' in done.result.message
        client.controller_event(mark, 'feedback lost', 10.0)
        stack.restart_sim()                              # the nodes then stop cleanly, each with 0
        client.controller_event(mark, 'feedback restored', 30.0)
        client.retire(action)
