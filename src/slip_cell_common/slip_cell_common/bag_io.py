"""rosbag2 bags on `rosbags` (no rclpy): MCAP storage, bag version 9, slip_msgs types registered.

Bags written here are regular Jazzy rosbag2 bags (``metadata.yaml`` version 9, MCAP, CDR,
RIHS01 type hashes), so ``ros2 bag info/play`` reads them on a full install, and bags recorded
there are read here.

Topic groups: command topics (anything that can move hardware) are kept apart from state
topics, so that replaying a state-only selection can never command the gripper.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Iterator

from rosbags.highlevel import AnyReader
from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness, QosReliability,
                                QosTime)
from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

#: Topics whose messages command hardware; excluded from replay unless asked for explicitly.
COMMAND_TOPICS = frozenset({'gripper/grasp_force_cmd', 'slip_control/set_mode'})

INTERFACE_PACKAGE = 'slip_msgs'


class BagError(RuntimeError):
    """A bag is missing, corrupt, truncated or holds unknown types; the message says which."""


def _interface_dir(package: str) -> Path:
    """Directory holding ``msg/*.msg`` of an installed (or source-tree) interface package."""
    try:
        from ament_index_python.packages import get_package_share_directory
        return Path(get_package_share_directory(package))
    except (ImportError, LookupError, ValueError):
        source = Path(__file__).resolve().parents[3] / package
        if (source / 'msg').is_dir():
            return source
        raise BagError(f'cannot find the {package} interface definitions '
                       '(source install/setup.bash)') from None


def slip_typestore(package: str = INTERFACE_PACKAGE) -> Typestore:
    """Jazzy typestore plus every message of ``package`` (nested types resolved)."""
    store = get_typestore(Stores.ROS2_JAZZY)
    types: dict[str, Any] = {}
    for path in sorted((_interface_dir(package) / 'msg').glob('*.msg')):
        types.update(get_types_from_msg(path.read_text(), f'{package}/msg/{path.stem}'))
    store.register(types)
    return store


def qos_profile(durability_transient_local: bool = False, depth: int = 10) -> Qos:
    """The offered-QoS record stored per topic (reliable; volatile or transient local)."""
    zero = QosTime(sec=0, nsec=0)
    return Qos(history=QosHistory.KEEP_LAST, depth=depth,
               reliability=QosReliability.RELIABLE,
               durability=(QosDurability.TRANSIENT_LOCAL if durability_transient_local
                           else QosDurability.VOLATILE),
               deadline=zero, lifespan=zero, liveliness=QosLiveliness.AUTOMATIC,
               liveliness_lease_duration=zero, avoid_ros_namespace_conventions=False)


class BagWriter:
    """Write CDR messages to a new MCAP bag. Refuses to overwrite an existing path.

    Args:
        path: Bag directory to create.
        typestore: Types for message definitions (default: Jazzy + slip_msgs).
        compress: zstd chunk compression inside the MCAP file (what rosbag2's MCAP plugin
            does with ``storage_preset_profile: zstd_fast``; ≈ 4× smaller for our topics).
    """

    def __init__(self, path: Path | str, typestore: Typestore | None = None,
                 compress: bool = True) -> None:
        self.path = Path(path)
        if self.path.exists():
            raise BagError(f'bag path {self.path} already exists; refusing to overwrite')
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.typestore = typestore or slip_typestore()
        self._writer = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
        if compress:
            self._writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        self._writer.open()
        self._connections: dict[str, Any] = {}
        self.message_count = 0

    def add_topic(self, topic: str, msgtype: str, latched: bool = False) -> None:
        """Declare a topic with its type (``pkg/msg/Name``) before writing to it."""
        if topic in self._connections:
            return
        if msgtype not in self.typestore.types:
            raise BagError(f'unknown message type {msgtype} for topic {topic}')
        self._connections[topic] = self._writer.add_connection(
            topic, msgtype, typestore=self.typestore,
            offered_qos_profiles=[qos_profile(latched, 1 if latched else 10)])

    def has_topic(self, topic: str) -> bool:
        """True when `add_topic` was called for ``topic``."""
        return topic in self._connections

    def write(self, topic: str, stamp_ns: int, data: bytes | memoryview) -> None:
        """Append serialized CDR bytes received at ``stamp_ns`` [ns]."""
        self._writer.write(self._connections[topic], int(stamp_ns), data)
        self.message_count += 1

    def write_message(self, topic: str, stamp_ns: int, msg: Any) -> None:
        """Serialize a rosbags message object and append it."""
        conn = self._connections[topic]
        self.write(topic, stamp_ns, self.typestore.serialize_cdr(msg, conn.msgtype))

    def close(self) -> None:
        """Finish the bag (writes metadata.yaml)."""
        self._writer.close()

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _open_reader(path: Path | str) -> AnyReader:
    path = Path(path)
    if not path.exists():
        raise BagError(f'bag {path} does not exist')
    reader = AnyReader([path], default_typestore=slip_typestore())
    try:
        reader.open()
    except Exception as exc:  # noqa: BLE001 - rosbags raises several unrelated types here
        raise BagError(f'cannot open bag {path}: {exc}') from exc
    return reader


@dataclass(frozen=True)
class TopicInfo:
    """One topic of a bag."""

    name: str
    msgtype: str
    count: int


@dataclass(frozen=True)
class BagInfo:
    """Summary of a bag: times in seconds (bag receive stamps)."""

    path: Path
    start_s: float
    end_s: float
    message_count: int
    topics: tuple[TopicInfo, ...]

    @property
    def duration_s(self) -> float:
        """Span between the first and the last message [s]."""
        return max(0.0, self.end_s - self.start_s)

    def format(self) -> str:
        """Human-readable table."""
        lines = [f'bag:       {self.path}', f'duration:  {self.duration_s:.3f} s',
                 f'start:     {self.start_s:.3f} s', f'messages:  {self.message_count}',
                 'topics:']
        width = max((len(t.name) for t in self.topics), default=0)
        for t in self.topics:
            lines.append(f'  {t.name:<{width}}  {t.count:>8}  {t.msgtype}')
        return '\n'.join(lines)


def bag_info(path: Path | str) -> BagInfo:
    """Read the summary of a bag (fails with BagError on missing or corrupt bags)."""
    reader = _open_reader(path)
    try:
        topics = tuple(sorted((TopicInfo(name, info.msgtype or '', info.msgcount)
                               for name, info in reader.topics.items()), key=lambda t: t.name))
        count = reader.message_count
        start, end = (reader.start_time, reader.end_time) if count else (0, 0)
    finally:
        reader.close()
    return BagInfo(Path(path), start * 1e-9, end * 1e-9, count, topics)


def iter_raw(path: Path | str, topics: Iterable[str] | None = None
             ) -> Iterator[tuple[str, str, int, bytes]]:
    """Yield ``(topic, msgtype, stamp_ns, cdr_bytes)`` in time order.

    Raises:
        BagError: on a missing, corrupt or truncated bag (also mid-iteration).
    """
    reader = _open_reader(path)
    try:
        wanted = None if topics is None else set(topics)
        conns = [c for c in reader.connections if wanted is None or c.topic in wanted]
        if wanted is not None:
            missing = wanted - {c.topic for c in reader.connections}
            if missing:
                raise BagError(f'bag {path} has no topic(s) {sorted(missing)}')
        try:
            for conn, stamp, data in reader.messages(connections=conns):
                yield conn.topic, conn.msgtype, stamp, bytes(data)
        except BagError:
            raise
        except Exception as exc:  # noqa: BLE001 - storage errors surface as many types
            raise BagError(f'bag {path} is corrupt or truncated: {exc}') from exc
    finally:
        reader.close()


def read_messages(path: Path | str, topics: Iterable[str] | None = None
                  ) -> dict[str, list[tuple[int, Any]]]:
    """All messages of the selected topics, deserialized: ``{topic: [(stamp_ns, msg), ...]}``.

    Messages are rosbags objects with the same field names as the rclpy messages.
    """
    store = slip_typestore()
    out: dict[str, list[tuple[int, Any]]] = {t: [] for t in topics} if topics else {}
    for topic, msgtype, stamp, data in iter_raw(path, topics):
        try:
            msg = store.deserialize_cdr(data, msgtype)
        except Exception as exc:  # noqa: BLE001
            raise BagError(f'cannot decode a {msgtype} message on {topic}: {exc}') from exc
        out.setdefault(topic, []).append((stamp, msg))
    return out


def stamp_s(msg: Any) -> float:
    """``header.stamp`` of a message in seconds (rosbags and rclpy messages alike)."""
    st = msg.header.stamp
    return st.sec + st.nanosec * 1e-9


def _flatten(prefix: str, value: Any, out: dict[str, Any]) -> None:
    if hasattr(value, '__dataclass_fields__'):
        for name in value.__dataclass_fields__:
            if name == '__msgtype__':
                continue
            _flatten(f'{prefix}{name}.', getattr(value, name), out)
    elif hasattr(value, 'tolist'):
        for i, item in enumerate(value.tolist()):
            out[f'{prefix}{i}'] = item
    elif isinstance(value, (list, tuple)):
        for i, item in enumerate(value):
            _flatten(f'{prefix}{i}.', item, out)
    else:
        out[prefix.rstrip('.')] = value


def export_csv(path: Path | str, out_dir: Path | str, topics: Iterable[str] | None = None
               ) -> list[Path]:
    """One CSV per topic: ``bag_time_s`` then every (flattened) message field.

    Returns:
        The written files (``<topic with / → __>.csv``).
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    for topic, items in read_messages(path, topics).items():
        rows = []
        for stamp, msg in items:
            row: dict[str, Any] = {'bag_time_s': stamp * 1e-9}
            _flatten('', msg, row)
            rows.append(row)
        file = out_dir / (topic.strip('/').replace('/', '__') + '.csv')
        with file.open('w', newline='') as fh:
            fields = list(rows[0]) if rows else ['bag_time_s']
            writer = csv.DictWriter(fh, fieldnames=fields, extrasaction='ignore')
            writer.writeheader()
            for row in rows:
                writer.writerow({k: ('nan' if isinstance(v, float) and math.isnan(v) else v)
                                 for k, v in row.items()})
        written.append(file)
    return written
