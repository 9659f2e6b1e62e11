"""QoS profiles and taking the newest message of a topic."""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message

#: Trajectories, statuses, paths: reliable, a few deep.
RELIABLE = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
#: Goals and their answers: reliable, and deep enough that a burst is kept whole (then coalesced:
#: only the newest waiting goal is planned). A message lost in transport is sent again only while
#: it is still in the sender's history, which must outlast Fast DDS's heartbeat period under a flood.
BURST = QoSProfile(depth=10_000, reliability=ReliabilityPolicy.RELIABLE)
#: What a late joiner must still get, as robot_state_publisher latches ``robot_description``.
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: A fast stream of which only the newest sample matters.
NEWEST = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT, history=HistoryPolicy.KEEP_LAST)


def newest_waiting(sub, msg, on_older):
    """The newest message waiting on subscription ``sub``: ``msg`` (just delivered by the
    executor) or a later one taken at once; ``on_older`` is called with each older one.

    A burst then never builds a backlog: the newest is handled, every older one is
    answered (as superseded) without being worked on.
    """
    while (got := sub.handle.take_message(sub.msg_type, sub.raw)) is not None:
        on_older(msg)
        msg = got[0]
    return msg


class LatestMessage:
    """The newest message of a fast topic, taken on demand instead of by a callback.

    A 1 kHz stream costs an rclpy executor a large share of a core in callbacks; a reader that
    needs only the newest sample (a servo loop, a planner when a goal comes) keeps a depth-1
    subscription that no executor waits on, and takes from it when it wants. The subscription
    belongs to the reading node itself, so graph tools (``ros2 node info``) show the data flow as it
    is; it is only left out of the list of subscriptions the node's executor waits on. With a
    ``reader`` (bytes -> message-like object, ValueError if it cannot), the messages are taken as
    bytes and only the newest is read; bytes the reader refuses are read by the message class instead.
    """

    def __init__(self, parent, msg_type, topic, reader=None, depth=1):
        self.msg_type = msg_type
        self.reader = reader
        self.node = parent
        qos = NEWEST if depth == 1 else QoSProfile(depth=depth, reliability=ReliabilityPolicy.BEST_EFFORT,
                                                    history=HistoryPolicy.KEEP_LAST)
        self.sub = parent.create_subscription(msg_type, topic, lambda msg: None, qos, raw=reader is not None)
        # rclpy's executor waits on every subscription in this list, and on its QoS event handlers: out of
        # both, this one is read here only (left in, its events kept an idle executor busy).
        parent._subscriptions.remove(self.sub)
        for handler in self.sub.event_handlers:
            parent.remove_waitable(handler)
        # Out of the node's list, destroy_node would leave it alive past its node (an rclpy subscription outliving
        # its node corrupts the heap at exit): destroy_latest destroys it with the node.
        parent.__dict__.setdefault('_latest_messages', []).append(self)
        self.last = None

    def take(self):
        """The newest message received so far (None before the first)."""
        raw = self.reader is not None
        newest = None
        while True:
            got = self.sub.handle.take_message(self.msg_type, raw)
            if got is None:
                break
            newest = got[0]
        if newest is not None:
            self.last = self._read(newest)
        return self.last

    def take_all(self):
        """Every message received since the last take (up to ``depth``, the newest), oldest first."""
        raw = self.reader is not None
        out = []
        while (got := self.sub.handle.take_message(self.msg_type, raw)) is not None:
            out.append(self._read(got[0]))
        if out:
            self.last = out[-1]
        return out

    def _read(self, msg):
        if self.reader is None:
            return msg
        try:
            return self.reader(msg)
        except ValueError:
            return deserialize_message(msg, self.msg_type)

    def publisher_count(self):
        return self.sub.get_publisher_count()

    def destroy(self):
        if self.sub is None:
            return
        for handler in self.sub.event_handlers:
            handler.destroy()
        self.sub.destroy()
        self.sub = None


def quiet_event_handlers(node):
    """Take ``node``'s QoS event handlers out of its executor's wait set (:func:`destroy_latest` puts them back
    before the node is destroyed, which expects them there).

    rclpy gives every publisher and subscription two, the incompatible-QoS and incompatible-type notices, and its
    executor adds each to its wait set and asks whether it is ready, in Python, on every wake: a node with a dozen
    topics spent more of its executor's time on them than on the callbacks that wake it, and the wait for them
    delayed every message. A mismatch is still reported by the node on the other side of it."""
    from rclpy.event_handler import EventHandler
    handlers = [w for w in node.waitables if isinstance(w, EventHandler)]
    for handler in handlers:
        node.remove_waitable(handler)
    node.__dict__.setdefault('_quiet_handlers', []).extend(handlers)


def destroy_latest(node):
    """Destroy every :class:`LatestMessage` of ``node`` not yet destroyed, and put back its quiet event handlers
    (:func:`quiet_event_handlers`), before ``node.destroy_node()``."""
    for latest in node.__dict__.get('_latest_messages', ()):
        latest.destroy()
    for handler in node.__dict__.pop('_quiet_handlers', ()):
        node.add_waitable(handler)
