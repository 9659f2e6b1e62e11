"""LatestMessage: a subscription of the reading node that its executor never waits on."""

import rclpy
from rclpy.executors import SingleThreadedExecutor
from sensor_msgs.msg import JointState

from picking_common.topics import LatestMessage, destroy_latest


def test_the_executor_waits_on_neither_the_subscription_nor_its_events_yet_the_newest_message_is_taken():
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node('latest_test', context=context,
                                 cli_args=['--ros-args', '-r', '__ns:=/latest_test'])
        latest = LatestMessage(node, JointState, 'states')
        waited = set(map(id, node.subscriptions)) | set(map(id, node.waitables))
        # (Left in, the QoS event handlers kept an idle executor spinning at full CPU.)
        assert id(latest.sub) not in waited
        assert not waited & set(map(id, latest.sub.event_handlers))
        pub = node.create_publisher(JointState, 'states', 10)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        for k in range(50):
            pub.publish(JointState(name=['a'], position=[float(k)]))
            executor.spin_once(timeout_sec=0.01)
            got = latest.take()
            if got is not None and got.position[0] == float(k):
                break
        assert got is not None and list(got.name) == ['a']
        latest.destroy()
        executor.shutdown()
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)


def test_a_node_destroys_its_latest_messages_with_it_once():
    """Out of the node's own list, a LatestMessage's subscription would outlive its node (rclpy then corrupted a
    state publisher's heap at exit, which never destroyed its own): destroy_latest destroys each once."""
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node('latest_teardown', context=context,
                                 cli_args=['--ros-args', '-r', '__ns:=/latest_teardown'])
        kept, closed = LatestMessage(node, JointState, 'a'), LatestMessage(node, JointState, 'b')
        closed.destroy()
        destroy_latest(node)
        destroy_latest(node)
        assert kept.sub is None and closed.sub is None
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)


def test_quiet_event_handlers_leave_the_wait_set_the_callbacks_run_and_the_node_is_destroyed_whole():
    """A node's QoS event handlers are out of what its executor waits on; its subscriptions still run and its
    action client still waits; destroy_latest puts them back, so that destroy_node finds them."""
    from control_msgs.action import FollowJointTrajectory
    from rclpy.action import ActionClient
    from rclpy.event_handler import EventHandler
    from trajectory_msgs.msg import JointTrajectory

    from picking_common.topics import quiet_event_handlers
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node('quiet_events', context=context, cli_args=['--ros-args', '-r', '__ns:=/quiet_events'])
        got = []
        node.create_subscription(JointState, 'states', got.append, 10)
        pub = node.create_publisher(JointState, 'states', 10)
        node.create_publisher(JointTrajectory, 'trajectory', 10)
        client = ActionClient(node, FollowJointTrajectory, 'follow_joint_trajectory')
        handlers = [w for w in node.waitables if isinstance(w, EventHandler)]
        assert len(handlers) >= 6                       # (two for each publisher and subscription)
        quiet_event_handlers(node)
        assert not any(isinstance(w, EventHandler) for w in node.waitables) and client in list(node.waitables)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        for _ in range(100):
            pub.publish(JointState(name=['a']))
            executor.spin_once(timeout_sec=0.01)
            if got:
                break
        assert got
        executor.shutdown()
        destroy_latest(node)
        assert sum(isinstance(w, EventHandler) for w in node.waitables) == len(handlers)
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)
