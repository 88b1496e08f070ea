"""Record topics to a bag and replay bags, with rclpy (rosbag2 is not installable from PyPI).

* `slip_cell_common.recorder.TopicRecorder` records in-process (the runner uses it).
* ``bag_recorder`` node: records the chosen topics (or every topic) until stopped.
* ``bag_replay`` node: publishes a bag's messages with the original timing scaled by ``rate``,
  publishes ``/clock`` from bag time, filters topics, and never publishes command topics unless
  ``include_commands`` is set.

Bag stamps are receive times on the node clock (sim time under ``use_sim_time``), as rosbag2
does, so recordings of a simulated run are deterministic in time.
"""
from __future__ import annotations

import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rclpy.node import Node
from rosgraph_msgs.msg import Clock

from slip_cell_common.bag_io import BagError, iter_raw, validate_bag
from slip_cell_common.recorder import (TopicRecorder, import_message_type, is_command_topic,
                                      topic_matches)
from slip_cell_common.node_main import run_node
from slip_cell_common.param_binding import ParameterBinding
from slip_cell_common.qos import CLOCK, LATCHED, SENSOR_PUB
from slip_cell_common.core import names
from slip_cell_common.time_conv import nanoseconds_to_seconds, nanoseconds_to_stamp


@dataclass(frozen=True)
class RecorderParams:
    """Parameters of the ``bag_recorder`` node."""

    output: str = field(default='', metadata={
        'required': True, 'read_only': True, 'description': 'new bag directory'})
    topics: tuple[str, ...] = field(default=('*',), metadata={
        'read_only': True, 'description': 'glob patterns of topics to record'})
    exclude: tuple[str, ...] = field(default=('rosout', 'parameter_events'), metadata={
        'read_only': True, 'description': 'glob patterns never recorded'})
    discovery_period: float = field(default=0.25, metadata={
        'unit': 's', 'range': (0.01, 10.0), 'read_only': True,
        'description': 'period of the topic discovery'})


class BagRecorderNode(Node):
    """Records topics to an MCAP bag until the process is stopped."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__('bag_recorder', **kwargs)
        cfg = ParameterBinding(self, RecorderParams).load()
        self.recorder = TopicRecorder(self, cfg.output, cfg.topics, cfg.exclude,
                                      cfg.discovery_period)
        self.get_logger().info(f'recording {list(cfg.topics)} to {self.recorder.path}')

    def destroy_node(self) -> None:
        """Close the bag before the node goes away."""
        path = self.recorder.stop()
        self.get_logger().info(f'bag closed: {path} ({self.recorder.message_count} messages)')
        super().destroy_node()


@dataclass(frozen=True)
class ReplayParams:
    """Parameters of the ``bag_replay`` node."""

    bag: str = field(default='', metadata={
        'required': True, 'read_only': True, 'description': 'bag directory to replay'})
    rate: float = field(default=1.0, metadata={
        'unit': '-', 'range': (0.0, 1000.0), 'read_only': True,
        'description': 'speed factor; 0 = as fast as possible'})
    topics: tuple[str, ...] = field(default=('*',), metadata={
        'read_only': True, 'description': 'glob patterns of topics to replay'})
    include_commands: bool = field(default=False, metadata={
        'read_only': True, 'description': 'also replay command topics (can move hardware)'})
    publish_clock: bool = field(default=True, metadata={
        'read_only': True, 'description': 'publish /clock from bag time'})
    start_delay: float = field(default=2.0, metadata={
        'unit': 's', 'range': (0.0, 120.0), 'read_only': True,
        'description': 'longest wall time to wait, before playing, until every replayed topic '
                       'has a subscriber (discovery of a new publisher can take seconds)'})
    exit_when_done: bool = field(default=True, metadata={
        'read_only': True, 'description': 'stop the process at the end of the bag'})


class BagReplayNode(Node):
    """Publishes the messages of a bag with their original timing (scaled by ``rate``)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__('bag_replay', **kwargs)
        self.cfg = ParameterBinding(self, ReplayParams).load()
        if not Path(self.cfg.bag).exists():
            raise BagError(f'bag {self.cfg.bag} does not exist')
        # The whole bag is read once before anything is published: a damaged bag, counts that
        # disagree with metadata.yaml or a bag without messages fail here, not mid-replay.
        # Create every publisher before the start delay so discovery happens during the delay.
        self._pubs: dict[str, Any] = {}
        for info in validate_bag(self.cfg.bag).topics:
            if info.name != names.CLOCK and self._selected(info.name):
                self._publisher(info.name, info.msgtype, info.latched)
        self._clock_pub = (self.create_publisher(Clock, names.CLOCK, CLOCK)
                           if self.cfg.publish_clock else None)
        self.published = 0
        self.done = threading.Event()
        self.error: str | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name='bag_replay', daemon=True)
        self._thread.start()

    def _selected(self, topic: str) -> bool:
        if not topic_matches(topic, self.cfg.topics):
            return False
        return self.cfg.include_commands or not is_command_topic(topic)

    def _publisher(self, topic: str, msgtype: str, latched: bool = False) -> Any:
        """Publisher of a replayed topic: latched where the recorded publishers were."""
        pub = self._pubs.get(topic)
        if pub is None:
            pub = self.create_publisher(import_message_type(msgtype), topic,
                                        LATCHED if latched else SENSOR_PUB)
            self._pubs[topic] = pub
        return pub

    def _run(self) -> None:
        try:
            deadline = time.monotonic() + self.cfg.start_delay
            while time.monotonic() < deadline and not all(
                    pub.get_subscription_count() > 0 for pub in self._pubs.values()):
                if self._stop.wait(0.02):
                    return
            # The writer side matches first; give the readers a moment to match back, or
            # the first samples are lost for best-effort subscribers.
            if self._stop.wait(min(0.5, self.cfg.start_delay)):
                return
            wall0 = time.monotonic()
            bag0: int | None = None
            for topic, msgtype, stamp, data in iter_raw(self.cfg.bag):
                if self._stop.is_set():
                    return
                if topic == names.CLOCK or not self._selected(topic):
                    continue
                bag0 = stamp if bag0 is None else bag0
                if self.cfg.rate > 0.0:
                    delay = (wall0 + nanoseconds_to_seconds(stamp - bag0) / self.cfg.rate
                             - time.monotonic())
                    if delay > 0.0 and self._stop.wait(delay):
                        return
                if self._clock_pub is not None:
                    self._clock_pub.publish(Clock(clock=nanoseconds_to_stamp(stamp)))
                self._publisher(topic, msgtype).publish(data)
                self.published += 1
        except BagError as exc:
            self.error = str(exc)
            self.get_logger().error(self.error)
        finally:
            self.done.set()
            if not self._stop.is_set():
                self.get_logger().info(f'replay finished: {self.published} messages')
                if self.cfg.exit_when_done:
                    self.context.try_shutdown()

    def destroy_node(self) -> None:
        """Stop the replay thread, then the node."""
        self._stop.set()
        self._thread.join(timeout=5.0)
        super().destroy_node()


def recorder_main(args: list[str] | None = None) -> int:
    """Console script ``bag_recorder``."""
    return run_node(BagRecorderNode, args)


def replay_main(args: list[str] | None = None) -> int:
    """Console script ``bag_replay``; exit code 2 when the bag failed while playing."""
    nodes: list[BagReplayNode] = []

    def factory() -> BagReplayNode:
        nodes.append(BagReplayNode())
        return nodes[-1]
    code = run_node(factory, args)
    if code == 0 and nodes and nodes[0].error:
        print(f'bag_replay: error: {nodes[0].error}', file=sys.stderr)
        return 2
    return code


if __name__ == '__main__':
    sys.exit(recorder_main())
