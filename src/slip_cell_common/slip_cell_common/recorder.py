"""Record a node's topics to a bag in-process (raw CDR, no deserialisation), and name helpers.

What ``ros2 bag record`` does, in the recording node's own executor:

* topics are taken once they have a publisher; hidden topics (a name part starting with
  ``_``) are skipped;
* the subscription matches every publisher, transient local where they all are, so latched
  topics (``/tf_static``, ``robot_description``, ``contact/properties``) are received;
* each topic's metadata holds the publishers' real offered QoS (`slip_cell_common.offered_qos`)
  and type hash; messages arriving while that is looked up are kept and written once known;
* ``/diagnostics``, ``/tf``, ``/tf_static`` and ``robot_description`` are recorded whenever
  they exist, whatever the patterns.

Bag stamps are receive times on the node clock (sim time under ``use_sim_time``), as rosbag2
does, so recordings of a simulated run are deterministic in time.
"""
from __future__ import annotations

import fnmatch
import functools
import importlib
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rclpy.node import Node

from slip_cell_common.bag_io import COMMAND_TOPICS, BagError, BagWriter, ensure_type, slip_typestore
from slip_cell_common.core import names
from slip_cell_common.offered_qos import (QosLookup, destroy_clients, publishers_qos,
                                          subscription_profile)

#: Recorded whenever present (patterns, namespaces allowed for robot_description).
ALWAYS_RECORDED = (names.DIAGNOSTICS, names.TF, names.TF_STATIC, names.ROBOT_DESCRIPTION,
                   '*/' + names.ROBOT_DESCRIPTION)


def import_message_type(msgtype: str) -> type:
    """``'pkg/msg/Name'`` → the rclpy message class."""
    pkg, kind, name = msgtype.split('/')
    return getattr(importlib.import_module(f'{pkg}.{kind}'), name)


def is_command_topic(topic: str) -> bool:
    """True for topics that command hardware (namespaces allowed)."""
    bare = topic.strip('/')
    return any(bare == c or bare.endswith('/' + c) for c in COMMAND_TOPICS)


def is_hidden_topic(topic: str) -> bool:
    """True when a part of the name starts with ``_`` (action internals, private topics)."""
    return any(part.startswith('_') for part in topic.strip('/').split('/'))


def topic_matches(topic: str, patterns: tuple[str, ...]) -> bool:
    """True when ``topic`` matches a glob pattern (leading ``/`` optional on both)."""
    bare = topic.lstrip('/')
    return any(fnmatch.fnmatchcase(bare, p.lstrip('/')) for p in patterns if p)



@dataclass
class _Pending:
    """A subscribed topic whose offered QoS is still being looked up."""

    msgtype: str
    lookup: QosLookup
    messages: list[tuple[int, bytes]] = field(default_factory=list)


class TopicRecorder:
    """Subscribes (raw CDR) to matching topics of a node's graph and writes them to a bag.

    Args:
        node: Node used for discovery and subscriptions.
        path: New bag directory (refused if it exists).
        topics: Glob patterns of topics to record (``('*',)`` = all). `ALWAYS_RECORDED` topics
            are added.
        exclude: Glob patterns never recorded.
        discovery_period_s: How often new topics are looked for [s, node clock].
    """

    def __init__(self, node: Node, path: Path | str, topics: tuple[str, ...] = ('*',),
                 exclude: tuple[str, ...] = (), discovery_period_s: float = 0.25) -> None:
        self._node = node
        self._writer = BagWriter(path, slip_typestore())
        self.path = self._writer.path
        self._topics = tuple(topics) + ALWAYS_RECORDED
        self._exclude = tuple(exclude)
        self._subs: dict[str, Any] = {}
        self._pending: dict[str, _Pending] = {}
        self._param_clients: dict[str, Any] = {}
        self._lock = threading.Lock()
        self._closed = False
        self._stopping = False
        self._discover()
        self._timer = node.create_timer(discovery_period_s, self._discover)

    @property
    def message_count(self) -> int:
        """Messages written so far."""
        return self._writer.message_count

    @property
    def topics(self) -> list[str]:
        """Topics subscribed so far."""
        return sorted(t for t, s in self._subs.items() if s is not None)

    @property
    def pending(self) -> list[str]:
        """Subscribed topics whose offered QoS is still being looked up (messages kept)."""
        with self._lock:
            return sorted(self._pending)

    def _discover(self) -> None:
        for topic, types in self._node.get_topic_names_and_types():
            if self._stopping:
                return
            if topic in self._subs or not types or is_hidden_topic(topic) \
                    or not topic_matches(topic, self._topics) \
                    or topic_matches(topic, self._exclude):
                continue
            publishers = publishers_qos(self._node, topic)
            if not publishers:
                continue  # no QoS to match yet (only subscribers); look again later
            msgtype = types[0]
            try:
                ensure_type(self._writer.typestore, msgtype)
                msg_class = import_message_type(msgtype)
            except (BagError, ImportError, AttributeError, ValueError) as exc:
                self._node.get_logger().warn(f'recorder: skipping {topic}: {exc}')
                self._subs[topic] = None
                continue
            with self._lock:
                self._pending[topic] = _Pending(msgtype, QosLookup(
                    self._node, topic, publishers, self._param_clients))
            self._subs[topic] = self._node.create_subscription(
                msg_class, topic, functools.partial(self._write, topic),
                subscription_profile(publishers), raw=True)
        with self._lock:
            pending = list(self._pending.items())
        for topic, item in pending:
            if item.lookup.poll():
                self._declare(topic)

    def _declare(self, topic: str) -> None:
        """Write the topic's metadata (QoS known or given up on) and the messages kept."""
        with self._lock:
            pending = self._pending.pop(topic, None)
            if pending is None or self._closed:
                return
            qos = pending.lookup.close()
            hashes = {p.type_hash for p in pending.lookup.publishers if p.type_hash}
            self._writer.add_topic(topic, pending.msgtype, offered_qos=qos,
                                   type_hash=hashes.pop() if len(hashes) == 1 else '')
            for stamp, data in pending.messages:
                self._writer.write(topic, stamp, data)

    def _write(self, topic: str, data: bytes) -> None:
        stamp = self._node.get_clock().now().nanoseconds
        with self._lock:
            if self._closed:
                return
            pending = self._pending.get(topic)
            if pending is not None:
                pending.messages.append((stamp, data))
            else:
                self._writer.write(topic, stamp, data)

    def stop(self) -> Path:
        """Unsubscribe and close the bag; returns its path."""
        with self._lock:
            if self._stopping:
                return self.path
            self._stopping = True
        self._node.destroy_timer(self._timer)
        with self._lock:
            pending = list(self._pending)
        for topic in pending:
            self._declare(topic)
        with self._lock:
            self._closed = True
        for sub in self._subs.values():
            if sub is not None:
                self._node.destroy_subscription(sub)
        destroy_clients(self._node, self._param_clients)
        self._writer.close()
        return self.path
