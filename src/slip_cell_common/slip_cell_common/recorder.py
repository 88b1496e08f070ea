"""Record a node's topics to a bag in-process (raw CDR, no deserialisation), and name helpers.

Bag stamps are receive times on the node clock (sim time under ``use_sim_time``), as rosbag2
does, so recordings of a simulated run are deterministic in time.
"""
from __future__ import annotations

import fnmatch
import importlib
import threading
from pathlib import Path
from typing import Any

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile

from slip_cell_common.bag_io import COMMAND_TOPICS, BagWriter, slip_typestore
from slip_cell_common.qos import LATCHED, SENSOR_PUB


def import_message_type(msgtype: str) -> type:
    """``'pkg/msg/Name'`` → the rclpy message class."""
    pkg, kind, name = msgtype.split('/')
    return getattr(importlib.import_module(f'{pkg}.{kind}'), name)


def is_command_topic(topic: str) -> bool:
    """True for topics that command hardware (namespaces allowed)."""
    bare = topic.strip('/')
    return any(bare == c or bare.endswith('/' + c) for c in COMMAND_TOPICS)


def _matches(topic: str, patterns: tuple[str, ...]) -> bool:
    bare = topic.lstrip('/')
    return any(fnmatch.fnmatchcase(bare, p.lstrip('/')) for p in patterns if p)


class TopicRecorder:
    """Subscribes (raw CDR) to matching topics of a node's graph and writes them to a bag.

    Args:
        node: Node used for discovery and subscriptions.
        path: New bag directory (refused if it exists).
        topics: Glob patterns of topics to record (``('*',)`` = all). ``/diagnostics`` is always
            recorded.
        exclude: Glob patterns never recorded.
        discovery_period_s: How often new topics are looked for [s, node clock].
    """

    def __init__(self, node: Node, path: Path | str, topics: tuple[str, ...] = ('*',),
                 exclude: tuple[str, ...] = (), discovery_period_s: float = 0.25) -> None:
        self._node = node
        self._writer = BagWriter(path, slip_typestore())
        self.path = self._writer.path
        self._topics = tuple(topics) + ('diagnostics',)
        self._exclude = tuple(exclude)
        self._subs: dict[str, Any] = {}
        self._lock = threading.Lock()
        self._closed = False
        self._discover()
        self._timer = node.create_timer(discovery_period_s, self._discover)

    @property
    def message_count(self) -> int:
        """Messages written so far."""
        return self._writer.message_count

    @property
    def topics(self) -> list[str]:
        """Topics subscribed so far."""
        return sorted(self._subs)

    def _discover(self) -> None:
        for topic, types in self._node.get_topic_names_and_types():
            if topic in self._subs or not types or not _matches(topic, self._topics):
                continue
            if _matches(topic, self._exclude):
                continue
            msgtype = types[0]
            if msgtype not in self._writer.typestore.types:
                self._node.get_logger().warn(f'recorder: skipping {topic}: unknown type {msgtype}')
                self._subs[topic] = None
                continue
            latched = any(info.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
                          for info in self._node.get_publishers_info_by_topic(topic))
            qos = QoSProfile(**{**_qos_kwargs(LATCHED if latched else SENSOR_PUB),
                                'depth': 1 if latched else 100})
            self._writer.add_topic(topic, msgtype, latched=latched)
            self._subs[topic] = self._node.create_subscription(
                import_message_type(msgtype), topic,
                lambda data, t=topic: self._write(t, data), qos, raw=True)

    def _write(self, topic: str, data: bytes) -> None:
        with self._lock:
            if not self._closed:
                self._writer.write(topic, self._node.get_clock().now().nanoseconds, data)

    def stop(self) -> Path:
        """Unsubscribe and close the bag; returns its path."""
        with self._lock:
            if self._closed:
                return self.path
            self._closed = True
        self._node.destroy_timer(self._timer)
        for sub in self._subs.values():
            if sub is not None:
                self._node.destroy_subscription(sub)
        self._writer.close()
        return self.path


def _qos_kwargs(profile: QoSProfile) -> dict[str, Any]:
    return {'history': profile.history, 'depth': profile.depth,
            'reliability': profile.reliability, 'durability': profile.durability}
