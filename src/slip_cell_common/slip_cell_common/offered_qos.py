"""The QoS a topic's publishers really offer, read from the ROS graph, as rosbag2 records it.

``Node.get_publishers_info_by_topic`` gives each publisher's reliability, durability,
deadline, lifespan and liveliness. DDS discovery does not carry history and depth (Fast DDS
reports ``unknown``/0, which is what ``ros2 bag record`` stores); a publisher created with QoS
overriding options declares them as read-only parameters
(``qos_overrides.<topic>.publisher.history|depth``), so `QosLookup` asks the publisher's node
for them. Infinite durations are written as rosbag2 writes ``RMW_DURATION_INFINITE``.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

from rcl_interfaces.srv import GetParameters
from rclpy.node import Node
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy)
from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness, QosReliability,
                                QosTime)

#: What rmw_fastrtps reports as the node of an endpoint whose node it does not know yet.
UNKNOWN_NODE = '_NODE_NAME_UNKNOWN_'

_HISTORY_NAMES = {'keep_last': QosHistory.KEEP_LAST, 'keep_all': QosHistory.KEEP_ALL,
                  'system_default': QosHistory.SYSTEM_DEFAULT}


def _time(duration: Any) -> QosTime:
    ns = int(duration.nanoseconds)
    return QosTime(sec=ns // 1_000_000_000, nsec=ns % 1_000_000_000)


def qos_record(profile: QoSProfile) -> Qos:
    """rclpy profile (as reported by the graph) → the record rosbag2 stores."""
    return Qos(history=QosHistory(int(profile.history)), depth=int(profile.depth),
               reliability=QosReliability(int(profile.reliability)),
               durability=QosDurability(int(profile.durability)),
               deadline=_time(profile.deadline), lifespan=_time(profile.lifespan),
               liveliness=QosLiveliness(int(profile.liveliness)),
               liveliness_lease_duration=_time(profile.liveliness_lease_duration),
               avoid_ros_namespace_conventions=bool(profile.avoid_ros_namespace_conventions))


def node_name(namespace: str, name: str) -> str:
    """Fully qualified node name."""
    return f'{namespace.rstrip("/")}/{name}'


@dataclass
class PublisherQos:
    """One publisher of a topic: its node and offered QoS (history/depth may be unknown)."""

    node: str
    qos: Qos
    type_hash: str = ''
    gid: tuple[int, ...] = ()
    future: Any = None
    sent_at: float = 0.0
    resolved: bool = False

    @property
    def needs_depth(self) -> bool:
        """Discovery did not carry history/depth."""
        return self.qos.history == QosHistory.UNKNOWN or self.qos.depth == 0

    @property
    def node_known(self) -> bool:
        """The graph has already mapped the endpoint to its node (it may lag discovery)."""
        return UNKNOWN_NODE not in self.node


def publishers_qos(node: Node, topic: str) -> list[PublisherQos]:
    """Every publisher of ``topic`` with the QoS the graph reports."""
    out = []
    for info in node.get_publishers_info_by_topic(topic):
        type_hash = str(getattr(info, 'topic_type_hash', '') or '')
        if not type_hash.startswith('RIHS01_') or set(type_hash[7:]) <= {'0'}:
            type_hash = ''
        out.append(PublisherQos(node_name(info.node_namespace, info.node_name),
                                qos_record(info.qos_profile), type_hash,
                                tuple(info.endpoint_gid)))
    return out


def subscription_profile(publishers: list[PublisherQos], depth: int = 100) -> QoSProfile:
    """A profile that matches every publisher and receives what latched ones hold.

    Reliable only if all publishers are (a reliable reader never matches a best-effort writer);
    transient local only if all publishers are (same rule for durability).
    """
    reliable = all(p.qos.reliability == QosReliability.RELIABLE for p in publishers)
    latched = bool(publishers) and all(p.qos.durability == QosDurability.TRANSIENT_LOCAL
                                       for p in publishers)
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=(ReliabilityPolicy.RELIABLE if reliable
                                   else ReliabilityPolicy.BEST_EFFORT),
                      durability=(DurabilityPolicy.TRANSIENT_LOCAL if latched
                                  else DurabilityPolicy.VOLATILE))


@dataclass
class QosLookup:
    """Completes unknown history/depth of a topic's publishers from their QoS-override
    parameters, without blocking: call `poll` from the node's executor until `done`.

    Args:
        node: Node whose executor delivers the responses.
        topic: Fully qualified topic name.
        publishers: From `publishers_qos`.
        clients: ``GetParameters`` clients by node name, shared by the lookups of one owner
            (a new client needs up to seconds of discovery); the owner destroys them
            (`destroy_clients`).
        timeout_s: Give up (keep unknown/0, as rosbag2 records) after this wall time [s].
        resend_after_s: Ask again when an answer takes longer than this [s].
    """

    node: Node
    topic: str
    publishers: list[PublisherQos]
    clients: dict[str, Any] = field(default_factory=dict)
    timeout_s: float = 10.0
    resend_after_s: float = 1.5
    _deadline: float = 0.0

    def __post_init__(self) -> None:
        self._deadline = time.monotonic() + self.timeout_s
        for pub in self.publishers:
            pub.resolved = not pub.needs_depth

    @property
    def done(self) -> bool:
        """Every publisher resolved, or the time is up."""
        return all(p.resolved for p in self.publishers) or time.monotonic() >= self._deadline

    def _names(self) -> list[str]:
        prefix = f'qos_overrides.{self.topic}.publisher.'
        return [prefix + 'history', prefix + 'depth']

    def _learn_nodes(self) -> None:
        """Endpoints are discovered before the node that owns them; ask the graph again."""
        nodes = {p.gid: p.node for p in publishers_qos(self.node, self.topic) if p.node_known}
        for pub in self.publishers:
            if not pub.node_known and pub.gid in nodes:
                pub.node = nodes[pub.gid]

    def poll(self) -> bool:
        """Send requests whose service is up, take answers that arrived; returns `done`."""
        if any(not p.resolved and not p.node_known for p in self.publishers):
            self._learn_nodes()
        for pub in self.publishers:
            if pub.resolved or not pub.node_known:
                continue
            if pub.future is None:
                client = self.clients.get(pub.node)
                if client is None:
                    client = self.node.create_client(GetParameters, f'{pub.node}/get_parameters')
                    self.clients[pub.node] = client
                if client.service_is_ready():
                    pub.future = client.call_async(GetParameters.Request(names=self._names()))
                    pub.sent_at = time.monotonic()
            elif pub.future.done():
                pub.resolved = True
                self._apply(pub, pub.future.result())
            elif time.monotonic() - pub.sent_at > self.resend_after_s:
                # A first request can be lost while the response path is still being matched
                # (the service looked ready); ask again.
                self.clients[pub.node].remove_pending_request(pub.future)
                pub.future = None
        return self.done

    def _apply(self, pub: PublisherQos, response: Any) -> None:
        if response is None or len(response.values) != 2:
            return
        history, depth = response.values
        qos = pub.qos
        if history.type == 4 and history.string_value in _HISTORY_NAMES:  # PARAMETER_STRING
            qos = qos._replace(history=_HISTORY_NAMES[history.string_value])
        if depth.type == 2 and depth.integer_value > 0:  # PARAMETER_INTEGER
            qos = qos._replace(depth=int(depth.integer_value))
        pub.qos = qos

    def close(self) -> list[Qos]:
        """Drop open requests; returns the offered profiles as known now."""
        for pub in self.publishers:
            client = self.clients.get(pub.node)
            if pub.future is not None and not pub.future.done() and client is not None:
                client.remove_pending_request(pub.future)
        return [p.qos for p in self.publishers]


def destroy_clients(node: Node, clients: dict[str, Any]) -> None:
    """Destroy the shared ``GetParameters`` clients of `QosLookup` objects."""
    for client in clients.values():
        node.destroy_client(client)
    clients.clear()
