"""Record ROS topics to an MCAP file that Foxglove and ``ros2 bag`` open.

Messages are kept as the CDR bytes DDS delivered (raw subscriptions), and each
channel's schema is the message definition in the ``ros2msg`` form rosbag2
writes: the type's ``.msg`` text followed by every type it uses, each after a
``MSG: pkg/Type`` separator. The definitions are read from the installed
packages' ``share/<pkg>/msg`` folders.
"""

from __future__ import annotations

import importlib
import os
import re
import sys
import threading
import time
from pathlib import Path

from rclpy.serialization import deserialize_message

_BUILTIN = {'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16', 'int32',
            'uint32', 'int64', 'uint64', 'string', 'wstring'}
_SEPARATOR = '=' * 80


def _msg_file(pkg, name):
    """The .msg text of ``pkg/Name``: from the ament index, else beside the Python package."""
    prefixes = [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    prefixes.append(sys.prefix)
    try:
        # <prefix>/lib/pythonX.Y/site-packages/<pkg>/__init__.py: pip wheels set no ament index.
        prefixes.append(str(Path(importlib.import_module(pkg).__file__).resolve().parents[4]))
    except (ImportError, IndexError, TypeError):
        pass
    for prefix in prefixes:
        path = Path(prefix) / 'share' / pkg / 'msg' / f'{name}.msg'
        if path.exists():
            return path.read_text()
    raise FileNotFoundError(f'no message definition for {pkg}/{name} under {prefixes}')


def _field_types(text, pkg):
    """The non-builtin types a .msg text uses, as 'pkg/Name'."""
    out = []
    for line in text.splitlines():
        line = line.split('#', 1)[0].strip()
        if not line or '=' in line.split()[0] or len(line.split()) < 2:
            continue
        base = re.sub(r'\[.*\]$', '', line.split()[0])
        base = re.sub(r'<=\d+$', '', base)
        if base in _BUILTIN or base.startswith('string<') or base.startswith('wstring<'):
            continue
        if base == 'Header':
            base = 'std_msgs/Header'
        if '/' not in base:
            base = f'{pkg}/{base}'
        out.append(base.replace('/msg/', '/'))
    return out


def message_definition(type_name):
    """The full ros2msg schema text of ``pkg/msg/Name`` (or ``pkg/Name``)."""
    pkg, name = type_name.split('/')[0], type_name.split('/')[-1]
    main = _msg_file(pkg, name)
    parts, seen, queue = [main], set(), _field_types(main, pkg)
    while queue:
        dep = queue.pop(0)
        if dep in seen:
            continue
        seen.add(dep)
        dpkg, dname = dep.split('/')
        text = _msg_file(dpkg, dname)
        parts.append(f'{_SEPARATOR}\nMSG: {dpkg}/{dname}\n{text}')
        queue.extend(_field_types(text, dpkg))
    return '\n'.join(parts)


def type_name(msg_class):
    module = msg_class.__module__.split('.')          # e.g. sensor_msgs.msg._joint_state
    return f'{module[0]}/msg/{msg_class.__name__}'


class Recorder:
    """Raw subscriptions on a node; ``messages(topic)`` deserialises, ``write_mcap`` saves."""

    def __init__(self, node, topics, qos):
        self.lock = threading.Lock()
        self.records = []                                # (topic, receive time ns, bytes)
        self.types = {}
        self.add(node, topics, qos)

    def add(self, node, topics, qos):
        """Record more topics (with their own QoS)."""
        for topic, msg_class in topics.items():
            self.types[topic] = msg_class
            node.create_subscription(msg_class, topic, self._callback(topic), qos, raw=True)

    def add_frames(self, node, namespaces=('',)):
        """Record what a viewer needs to draw the arms with no other set-up: ``/tf``, ``/tf_static``, and each
        arm's ``robot_description`` and ``world_markers`` (latched: the recording starts with them)."""
        from std_msgs.msg import String
        from tf2_msgs.msg import TFMessage
        from visualization_msgs.msg import MarkerArray

        from picking_common.tf import TF_QOS, TF_STATIC_QOS
        from picking_common.topics import LATCHED
        self.add(node, {'/tf': TFMessage}, TF_QOS)
        self.add(node, {'/tf_static': TFMessage}, TF_STATIC_QOS)
        for ns in namespaces:
            prefix = f'/{ns.strip("/")}/' if ns.strip('/') else ''
            self.add(node, {f'{prefix}robot_description': String, f'{prefix}world_markers': MarkerArray}, LATCHED)

    def _callback(self, topic):
        def store(data):
            with self.lock:
                self.records.append((topic, time.time_ns(), bytes(data)))
        return store

    def messages(self, topic):
        """``[(receive time s, message)]`` for one topic, in arrival order."""
        with self.lock:
            rows = [(t, d) for tp, t, d in self.records if tp == topic]
        cls = self.types[topic]
        return [(t * 1e-9, deserialize_message(d, cls)) for t, d in rows]

    def count(self, topic):
        with self.lock:
            return sum(1 for tp, _, _ in self.records if tp == topic)

    def write_mcap(self, path, namespace=''):
        """Write every recorded message; returns the path and the number of messages."""
        from mcap.writer import Writer
        path = Path(path)
        with open(path, 'wb') as f:
            writer = Writer(f)
            writer.start(profile='ros2', library='picking_planner')
            channels = {}
            for topic, cls in self.types.items():
                schema = writer.register_schema(name=type_name(cls), encoding='ros2msg',
                                                data=message_definition(type_name(cls)).encode())
                full = f'{namespace.rstrip("/")}/{topic}' if not topic.startswith('/') else topic
                channels[topic] = writer.register_channel(topic=full, message_encoding='cdr', schema_id=schema)
            with self.lock:
                records = list(self.records)
            for seq, (topic, t, data) in enumerate(records):
                writer.add_message(channel_id=channels[topic], log_time=t, data=data, publish_time=t,
                                   sequence=seq)
            writer.finish()
        return path, len(records)
