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
