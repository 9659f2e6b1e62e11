"""``picking-foxglove``: the arm live in Foxglove, through the Foxglove SDK's WebSocket server.

Every topic of the graph (``topics`` empty) or the ones named is forwarded as it arrives: its CDR bytes
as they are, on a Foxglove channel with the type's ``ros2msg`` schema (the message definition as rosbag2
writes it), so that Foxglove decodes them as ROS 2 messages: the arm from ``/tf`` and
``robot_description``, its plans (``planned_path``), the scene, the canopy, the statuses. New topics are
found every ``refresh`` s. ``picking-stack --foxglove`` starts it with the stack and stops it with it;
open Foxglove's "Open connection" on ``ws://127.0.0.1:8765``. A viewer that connects or leaves changes
nothing for the arm: the bridge only listens.
"""

from __future__ import annotations

import collections
import importlib
import threading
import time

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from picking_common.params import Param, declare, usage
from picking_common.run import run_node

from .recording import message_definition

#: Topics forwarded only when named: their rate would cost the bridge more than a viewer gains.
SKIPPED = ('joint_commands',)
#: Topics a late subscriber must still get (published transient local): their newest messages are sent again to
#: each viewer that subscribes.
LATCHED_TOPICS = ('/tf_static', 'robot_description', 'scene', 'world_markers')
#: Messages of a latched topic kept to send again (one per publisher of it, at the least).
LATCHED_KEPT = 64

PARAMS = (
    Param('host', '127.0.0.1', 'the address the WebSocket server listens on (127.0.0.1: this machine only)',
          read_only=True),
    Param('port', 8765, 'the WebSocket port (Foxglove\'s default)', '', (1, 65535), read_only=True),
    Param('topics', [''], 'the topics to forward; [""]: every topic of the graph but joint_commands', read_only=True),
    Param('refresh', 2.0, 'how often the graph is looked at for new topics', 's', (0.1, 60.0), read_only=True),
)


class _Latch:
    """The Foxglove server's listener: the topics viewers subscribed to since the last look."""

    def __init__(self):
        self._topics, self._lock = set(), threading.Lock()

    def on_subscribe(self, client, channel):
        with self._lock:
            self._topics.add(channel.topic)

    def take(self):
        with self._lock:
            out, self._topics = self._topics, set()
        return out


def get_message(type_name):
    """The message class of ``pkg/msg/Name``."""
    pkg, _, name = type_name.split('/')
    return getattr(importlib.import_module(f'{pkg}.msg'), name)


class FoxgloveBridge(Node):
    """ROS topics to Foxglove channels, bytes for bytes."""

    def __init__(self, **kwargs):
        super().__init__('picking_foxglove', **kwargs)
        import foxglove
        self.foxglove = foxglove
        p = declare(self, PARAMS)
        self.wanted = [t for t in p['topics'] if t]
        self.latch = _Latch()
        self.server = foxglove.start_server(name='picking-stack', host=p['host'], port=int(p['port']),
                                            server_listener=self.latch)
        self.channels, self.subs, self.refused, self.latched = {}, {}, set(), {}
        self.create_timer(p['refresh'], self._discover)
        self.create_timer(0.1, self._send_latched)
        self._discover()
        self.get_logger().info(f'Foxglove WebSocket server on ws://{p["host"]}:{self.server.port}: '
                               f'open it in Foxglove ("Open connection")')

    def _discover(self):
        for topic, types in self.get_topic_names_and_types():
            if topic in self.subs or topic in self.refused or not self._forwards(topic):
                continue
            try:
                self._forward(topic, types[0])
            except (FileNotFoundError, AttributeError, ModuleNotFoundError, ValueError) as exc:
                self.refused.add(topic)
                self.get_logger().warning(f'{topic} ({types[0]}) not forwarded: {exc}')

    def _forwards(self, topic):
        if self.wanted:
            return topic in self.wanted
        return topic.rsplit('/', 1)[-1] not in SKIPPED and '/_action/' not in topic and not topic.endswith(
            ('/parameter_events', '/rosout')) and topic not in ('/parameter_events', '/rosout')

    def _forward(self, topic, type_name):
        msg_class = get_message(type_name)
        schema = self.foxglove.Schema(name=type_name.replace('/msg/', '/'), encoding='ros2msg',
                                      data=message_definition(type_name).encode())
        channel = self.foxglove.Channel(topic, schema=schema, message_encoding='cdr')
        latched = any(topic == t or topic.endswith('/' + t) for t in LATCHED_TOPICS)
        # (Best effort matches every publisher: a viewer never slows one down; latched topics need reliable.)
        qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE if latched else ReliabilityPolicy.BEST_EFFORT,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)
        self.channels[topic] = channel
        kept = self.latched[topic] = collections.deque(maxlen=LATCHED_KEPT) if latched else None

        def forward(data, channel=channel, kept=kept):
            data = bytes(data)
            if kept is not None:
                kept.append(data)
            channel.log(data, log_time=time.time_ns())
        self.subs[topic] = self.create_subscription(msg_class, topic, forward, qos, raw=True)

    def _send_latched(self):
        """A viewer that subscribed to a latched topic gets its newest messages again (as a late ROS subscriber
        would)."""
        for topic in self.latch.take():
            for data in self.latched.get(topic) or ():
                self.channels[topic].log(data, log_time=time.time_ns())

    def close(self):
        self.server.stop()


def main(args=None):
    return run_node(FoxgloveBridge, args, help=usage('picking-foxglove', __doc__, PARAMS))


if __name__ == '__main__':
    raise SystemExit(main())
