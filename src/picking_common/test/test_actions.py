"""ActionClient: a goal sent from a thread other than the spinning one is answered."""

import threading
import time

import rclpy
from control_msgs.action import GripperCommand
from rclpy.action import ActionServer
from rclpy.executors import SingleThreadedExecutor

from picking_common.actions import ActionClient


class SlowToRecord(dict):
    """The client's record of pending goal requests, slow to look into just after a request went out: the time
    a loaded host may take to run the sending thread again, during which the answer already came."""

    def __contains__(self, key):
        time.sleep(0.3)
        return super().__contains__(key)


def test_a_goal_sent_while_another_thread_spins_gets_its_answer_and_result():
    context = rclpy.Context()
    rclpy.init(context=context)
    executor = SingleThreadedExecutor(context=context)
    stop = threading.Event()
    spinner = threading.Thread(target=lambda: [executor.spin_once(timeout_sec=0.02) for _ in iter(stop.is_set, True)])
    try:
        node = rclpy.create_node('actions_test', context=context, cli_args=['--ros-args', '-r', '__ns:=/actions_test'])

        def execute(goal_handle):
            goal_handle.succeed()
            return GripperCommand.Result(position=goal_handle.request.command.position, reached_goal=True)

        server = ActionServer(node, GripperCommand, 'gripper', execute)
        client = ActionClient(node, GripperCommand, 'gripper')
        client._pending_goal_requests = SlowToRecord()
        executor.add_node(node)
        spinner.start()
        assert client.wait_for_server(timeout_sec=10.0)
        for k in range(3):
            goal = GripperCommand.Goal()
            goal.command.position = 0.01 * k
            sent = client.send_goal_async(goal)
            deadline = time.monotonic() + 10.0
            while not sent.done() and time.monotonic() < deadline:
                time.sleep(0.01)
            assert sent.done(), 'the goal response was dropped'
            assert sent.result().accepted
            result = sent.result().get_result_async()
            while not result.done() and time.monotonic() < deadline:
                time.sleep(0.01)
            assert result.done() and result.result().result.position == goal.command.position
        stop.set()
        spinner.join(timeout=5.0)
        server.destroy()
        client.destroy()
        node.destroy_node()
    finally:
        stop.set()
        executor.shutdown()
        rclpy.shutdown(context=context)
