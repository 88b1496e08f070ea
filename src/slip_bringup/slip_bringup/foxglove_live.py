"""``foxglove_live``: the running cell in Foxglove without a full ROS install (no foxglove_bridge).

A node that serves the graph's topics on a Foxglove WebSocket server (``foxglove-sdk``):

* every matching topic with a publisher is advertised as a channel with its ``ros2msg``
  schema (the installed ``.msg`` text, `slip_cell_common.msg_definitions`) and ``cdr``
  encoding, so Foxglove decodes the messages itself: TF (``/tf``, ``/tf_static``), the URDF on
  ``robot_description``, wrenches, twists, grasp-force command and status, slip tracking,
  markers when someone publishes them;
* a ROS subscription exists only while a Foxglove client subscribes to the channel (as
  foxglove_bridge does), taking the raw CDR bytes, transient local where the publishers are,
  so latched topics arrive;
* under ``use_sim_time`` the server advertises the time capability and broadcasts the node
  clock, so Foxglove follows simulated time.

The server listens on ``127.0.0.1:8765`` by default (parameters ``host``, ``port``; port 0 =
any free port, logged). Open Foxglove → *Open connection* → *Foxglove WebSocket* →
``ws://127.0.0.1:8765``, then import ``docs/foxglove/slip_cell_layout.json``.
"""
from __future__ import annotations

import functools
import queue
import sys
import threading
from dataclasses import dataclass, field
from typing import Any

import foxglove
from foxglove.websocket import Capability
from rclpy.node import Node

from slip_cell_common.msg_definitions import DefinitionNotFound, full_definition
from slip_cell_common.node_main import run_node
from slip_cell_common.offered_qos import publishers_qos, subscription_profile
from slip_cell_common.param_binding import ParameterBinding
from slip_cell_common.recorder import import_message_type, is_hidden_topic, topic_matches


@dataclass(frozen=True)
class FoxgloveLiveParams:
    """Parameters of the ``foxglove_live`` node."""

    host: str = field(default='127.0.0.1', metadata={
        'read_only': True, 'description': 'address the WebSocket server listens on '
                                          '(127.0.0.1: this machine only)'})
    port: int = field(default=8765, metadata={
        'range': (0, 65535), 'read_only': True,
        'description': 'WebSocket port; 0 = any free port (logged)'})
    topics: tuple[str, ...] = field(default=('*',), metadata={
        'read_only': True, 'description': 'glob patterns of topics to serve'})
    exclude: tuple[str, ...] = field(default=('parameter_events',), metadata={
        'read_only': True, 'description': 'glob patterns never served'})
    discovery_period: float = field(default=1.0, metadata={
        'unit': 's', 'range': (0.1, 60.0), 'read_only': True,
        'description': 'period of the topic discovery'})


class _Listener(foxglove.websocket.ServerListener):
    """Forwards client (un)subscriptions from the SDK's thread to the node's executor."""

    def __init__(self, node: FoxgloveLiveNode) -> None:
        self._node = node

    def on_subscribe(self, client: Any, channel: Any) -> None:
        self._node.request(+1, channel.id)

    def on_unsubscribe(self, client: Any, channel: Any) -> None:
        self._node.request(-1, channel.id)


@dataclass
class _Served:
    """One advertised topic: its channel, client count and ROS subscription (while needed)."""

    topic: str
    msgtype: str
    channel: Any
    clients: int = 0
    subscription: Any = None


class FoxgloveLiveNode(Node):
    """Serves the graph's topics on a Foxglove WebSocket server."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__('foxglove_live', **kwargs)
        self.cfg = ParameterBinding(self, FoxgloveLiveParams).load()
        self._sim_time = bool(self.get_parameter('use_sim_time').value)
        self._fox_context = foxglove.Context()
        self._served: dict[str, _Served] = {}
        self._by_channel: dict[int, _Served] = {}
        self._skipped: set[str] = set()
        self._requests: queue.SimpleQueue[tuple[int, int]] = queue.SimpleQueue()
        self._lock = threading.Lock()
        self.server = foxglove.start_server(
            name='slip_cell', host=self.cfg.host, port=self.cfg.port, context=self._fox_context,
            server_listener=_Listener(self), supported_encodings=['cdr'],
            capabilities=[Capability.Time] if self._sim_time else [])
        self.get_logger().info(f'Foxglove WebSocket server on ws://{self.cfg.host}:'
                               f'{self.server.port} (topics {list(self.cfg.topics)})')
        self._wake = self.create_guard_condition(self._apply_requests)
        self._discover()
        self._timer = self.create_timer(self.cfg.discovery_period, self._discover)
        self._clock_timer = (self.create_timer(0.05, self._broadcast_time)
                             if self._sim_time else None)

    @property
    def port(self) -> int:
        """The port the server listens on."""
        return int(self.server.port)

    @property
    def advertised(self) -> list[str]:
        """Topics advertised to clients."""
        return sorted(self._served)

    def request(self, delta: int, channel_id: int) -> None:
        """A client (un)subscribed (SDK thread); applied on the executor."""
        self._requests.put((delta, channel_id))
        self._wake.trigger()

    def _discover(self) -> None:
        for topic, types in self.get_topic_names_and_types():
            if topic in self._served or topic in self._skipped or not types \
                    or is_hidden_topic(topic) or not topic_matches(topic, self.cfg.topics) \
                    or topic_matches(topic, self.cfg.exclude):
                continue
            if self.count_publishers(topic) == 0:
                continue
            msgtype = types[0]
            try:
                definition = full_definition(msgtype)
                import_message_type(msgtype)
            except (DefinitionNotFound, ImportError, AttributeError, ValueError) as exc:
                self.get_logger().warn(f'not serving {topic}: {exc}')
                self._skipped.add(topic)
                continue
            channel = foxglove.Channel(
                topic, message_encoding='cdr', context=self._fox_context,
                schema=foxglove.Schema(name=msgtype, encoding=definition.encoding,
                                       data=definition.text.encode()))
            served = _Served(topic, msgtype, channel)
            with self._lock:
                self._served[topic] = served
                self._by_channel[channel.id()] = served

    def _apply_requests(self) -> None:
        while True:
            try:
                delta, channel_id = self._requests.get_nowait()
            except queue.Empty:
                return
            with self._lock:
                served = self._by_channel.get(channel_id)
            if served is None:
                continue
            served.clients = max(0, served.clients + delta)
            if served.clients and served.subscription is None:
                served.subscription = self.create_subscription(
                    import_message_type(served.msgtype), served.topic,
                    functools.partial(self._forward, served),
                    subscription_profile(publishers_qos(self, served.topic)), raw=True)
            elif not served.clients and served.subscription is not None:
                self.destroy_subscription(served.subscription)
                served.subscription = None

    def _forward(self, served: _Served, data: bytes) -> None:
        served.channel.log(bytes(data), log_time=self.get_clock().now().nanoseconds)

    def _broadcast_time(self) -> None:
        self.server.broadcast_time(self.get_clock().now().nanoseconds)

    def destroy_node(self) -> None:
        """Stop the server before the node goes away."""
        self.server.stop()
        for served in self._served.values():
            served.channel.close()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Console script ``foxglove_live`` (``--help`` prints this module's description)."""
    argv = list(sys.argv if args is None else args)
    own = argv[1:argv.index('--ros-args')] if '--ros-args' in argv else argv[1:]
    if {'-h', '--help'} & set(own):
        print(f'usage: foxglove_live [--ros-args -p port:=8765 -p host:=127.0.0.1 ...]\n\n'
              f'{__doc__}')
        return 0
    return run_node(FoxgloveLiveNode, argv)


if __name__ == '__main__':
    sys.exit(main())
