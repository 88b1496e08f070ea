"""rosbag2 bags on `rosbags` (no rclpy): MCAP storage, bag version 9, any installed interface.

Bags written here are what a Jazzy ``ros2 bag record`` writes, so every tool reads them like
rosbag2's own:

* ``metadata.yaml`` version 9 with ``ros_distro: jazzy`` (also in the MCAP ``rosbag2``
  metadata record);
* MCAP profile ``ros2``, zstd chunks with CRC-32 of every chunk (a flipped bit is detected),
  CDR messages;
* each schema is the installed ``.msg`` text with comments (units) and every dependency
  (`slip_cell_common.msg_definitions`), encoding ``ros2msg``;
* each channel carries ``offered_qos_profiles`` (the publishers' real QoS, given by the
  recorder) and ``topic_type_hash`` (RIHS01).

Reading checks a bag before trusting it: a folder without ``metadata.yaml``, an empty or
foreign folder, a truncated or corrupt MCAP file, and a ``metadata.yaml`` whose message counts
disagree with the data each raise `BagError` with a one-line message naming the problem.
Counts always come from the data.

Topic groups: command topics (anything that can move hardware) are kept apart from state
topics, so that replaying a state-only selection can never command the gripper.
"""
from __future__ import annotations

import csv
import math
import os
import re
from binascii import crc32
from dataclasses import dataclass
from io import BytesIO
from pathlib import Path
from typing import Any
from collections.abc import Callable, Iterable, Iterator, Sequence

from rosbags.highlevel import AnyReader
from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness, QosReliability,
                                QosTime)
from rosbags.rosbag2 import CompressionFormat, CompressionMode, Reader, StoragePlugin, Writer
from rosbags.rosbag2 import storage_mcap
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

from slip_cell_common.core import names
from slip_cell_common.msg_definitions import (DefinitionNotFound, full_definition, msg_directory,
                                              register_type)
from slip_cell_common.time_conv import nanoseconds_to_seconds, stamp_to_seconds

#: Topics whose messages command hardware; excluded from replay unless asked for explicitly.
COMMAND_TOPICS = frozenset({names.GRASP_FORCE_CMD, names.SLIP_SET_MODE_SRV})

INTERFACE_PACKAGE = 'slip_msgs'

#: ``ros_distro`` written to bag metadata when the environment names none.
DEFAULT_ROS_DISTRO = 'jazzy'

#: Environment variable that moves every default output (bags, demo runs) somewhere else.
DATA_DIR_ENV = 'SLIP_DATA_DIR'

_MCAP_MAGIC = b'\x89MCAP0\r\n'
#: Infinite QoS durations as rosbag2 writes them (RMW_DURATION_INFINITE).
INFINITE_TIME = QosTime(sec=9223372036, nsec=854775807)


class BagError(RuntimeError):
    """A bag is missing, corrupt, truncated, inconsistent or foreign; the message says which.

    The message is always one line (tools print it as their only error output).
    """

    def __init__(self, message: str) -> None:
        super().__init__(re.sub(r'\s*\n\s*', '; ', str(message)).strip())


def default_data_directory() -> Path:
    """Where tools write when no output is given: ``$SLIP_DATA_DIR`` or
    ``$XDG_DATA_HOME/slip_cell`` (``~/.local/share/slip_cell``) — never the source tree."""
    env = os.environ.get(DATA_DIR_ENV)
    if env:
        return Path(env).expanduser()
    xdg = os.environ.get('XDG_DATA_HOME') or str(Path.home() / '.local' / 'share')
    return Path(xdg).expanduser() / 'slip_cell'


def default_bag_directory() -> Path:
    """Default directory of recorded bags: ``<default_data_directory()>/bags``."""
    return default_data_directory() / 'bags'


def ros_distro() -> str:
    """``$ROS_DISTRO`` (as rosbag2 records it), ``jazzy`` when unset (wheels)."""
    return os.environ.get('ROS_DISTRO') or DEFAULT_ROS_DISTRO


def slip_typestore(package: str = INTERFACE_PACKAGE) -> Typestore:
    """Jazzy typestore plus every message of ``package`` (from its installed ``.msg`` files)."""
    store = get_typestore(Stores.ROS2_JAZZY)
    try:
        directory = msg_directory(package)
    except DefinitionNotFound as exc:
        raise BagError(f'cannot find the {package} interface definitions: {exc}') from None
    for path in sorted(directory.glob('*.msg')):
        ensure_type(store, f'{package}/msg/{path.stem}')
    return store


def ensure_type(store: Typestore, msgtype: str) -> None:
    """Make ``store`` know ``msgtype`` (loaded from the installed ``.msg`` files if needed).

    Raises:
        BagError: the type is not installed.
    """
    if msgtype in store.fielddefs:
        return
    try:
        register_type(store, msgtype)
    except DefinitionNotFound as exc:
        raise BagError(f'unknown message type {msgtype}: {exc}') from None


def qos_profile(durability_transient_local: bool = False, depth: int = 10) -> Qos:
    """An offered-QoS record (reliable, keep last; volatile or transient local), for writers
    that know their publisher's profile rather than reading it from the graph."""
    return Qos(history=QosHistory.KEEP_LAST, depth=depth,
               reliability=QosReliability.RELIABLE,
               durability=(QosDurability.TRANSIENT_LOCAL if durability_transient_local
                           else QosDurability.VOLATILE),
               deadline=INFINITE_TIME, lifespan=INFINITE_TIME,
               liveliness=QosLiveliness.AUTOMATIC, liveliness_lease_duration=INFINITE_TIME,
               avoid_ros_namespace_conventions=False)


def _with_ros_distro(text: str) -> str:
    """rosbags writes ``ros_distro: rosbags``; rosbag2 writes the distribution."""
    out, n = re.subn(r'(?m)^(\s*)ros_distro: .*$', rf'\g<1>ros_distro: {ros_distro()}', text)
    if n != 1:
        raise BagError('bag metadata has no single ros_distro entry (rosbags changed its format)')
    return out


class _McapStorage(storage_mcap.McapWriter):
    """rosbags' MCAP writer with what rosbag2's MCAP plugin also writes: chunk CRCs, the
    ``topic_type_hash`` channel metadata and the real ``ros_distro``."""

    def add_connection(self, connection: Any, offered_qos_profiles: str) -> None:
        """Channel record with ``offered_qos_profiles`` and ``topic_type_hash``."""
        entries = BytesIO()
        for key, value in (('offered_qos_profiles', offered_qos_profiles),
                           ('topic_type_hash', connection.digest)):
            storage_mcap.write_string(entries, key)
            storage_mcap.write_string(entries, value)
        self.channels.append(storage_mcap.Channel(
            connection.id, connection.msgtype, connection.topic,
            connection.ext.serialization_format, entries.getvalue()))
        self.channel_stats[connection.id] = 0
        storage_mcap.write_channel(self.chunk.bio, self.channels[-1], self.schemas)

    def close_chunk(self) -> None:
        """Same chunk layout as rosbags writes, with the CRC-32 of the uncompressed records."""
        raw = self.chunk.bio.getvalue()
        rec = BytesIO()
        storage_mcap.write_uint64(rec, self.chunk.message_start_time)
        storage_mcap.write_uint64(rec, self.chunk.message_end_time)
        storage_mcap.write_uint64(rec, len(raw))
        storage_mcap.write_uint32(rec, crc32(raw))
        compressed = self.compressor(raw)
        storage_mcap.write_string(rec, self.compression)
        storage_mcap.write_uint64(rec, len(compressed))
        rec.write(compressed)
        chunk_start = self.bio.tell()
        storage_mcap.write_record(self.bio, 0x06, rec)
        chunk_end = self.bio.tell()
        offsets: list[tuple[int, int]] = []
        for cid, msgs in self.chunk.msgs.items():
            offsets.append((cid, self.bio.tell()))
            rec = BytesIO()
            storage_mcap.write_uint16(rec, cid)
            storage_mcap.write_uint32(rec, len(msgs) * 16)
            for ts, offset in msgs:
                storage_mcap.write_uint64(rec, ts)
                storage_mcap.write_uint64(rec, offset)
            storage_mcap.write_record(self.bio, 0x07, rec)
        rec = BytesIO()
        storage_mcap.write_uint64(rec, self.chunk.message_start_time)
        storage_mcap.write_uint64(rec, self.chunk.message_end_time)
        storage_mcap.write_uint64(rec, chunk_start)
        storage_mcap.write_uint64(rec, chunk_end - chunk_start)
        storage_mcap.write_uint32(rec, len(offsets) * 10)
        for cid, offset in offsets:
            storage_mcap.write_uint16(rec, cid)
            storage_mcap.write_uint64(rec, offset)
        storage_mcap.write_uint64(rec, self.bio.tell() - chunk_end)
        storage_mcap.write_string(rec, self.compression)
        storage_mcap.write_uint64(rec, len(compressed))
        storage_mcap.write_uint64(rec, len(raw))
        self.chunks.append(rec)
        self.chunk = storage_mcap.PendingChunk(2**63 - 1, 0, BytesIO(),
                                               storage_mcap.defaultdict(list))

    def close(self, version: int, metadata: str) -> None:
        """Write the summary with the real ``ros_distro`` in the ``rosbag2`` metadata record."""
        super().close(version, _with_ros_distro(metadata))


class _Rosbag2Writer(Writer):
    STORAGE_PLUGINS = {**Writer.STORAGE_PLUGINS, StoragePlugin.MCAP: _McapStorage}

    def close(self) -> None:
        super().close()
        self.metapath.write_text(_with_ros_distro(self.metapath.read_text()))


class BagWriter:
    """Write CDR messages to a new MCAP bag. Refuses to overwrite an existing path.

    Args:
        path: Bag directory to create.
        typestore: Types used by `write_message` (default: Jazzy + slip_msgs; other installed
            types are added on demand).
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
        self._writer = _Rosbag2Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
        if compress:
            self._writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        self._writer.open()
        self._connections: dict[str, Any] = {}
        self.message_count = 0

    def add_topic(self, topic: str, msgtype: str, latched: bool = False,
                  offered_qos: Sequence[Qos] | None = None, type_hash: str = '') -> None:
        """Declare a topic with its type (``pkg/msg/Name``) before writing to it.

        Args:
            offered_qos: The publishers' QoS profiles (one per publisher), as read from the
                graph; default one reliable keep-last profile (depth 1 and transient local
                when ``latched``, else depth 10).
            type_hash: RIHS01 hash of the type as the publishers report it; default computed
                from the installed definition.
        """
        if topic in self._connections:
            return
        ensure_type(self.typestore, msgtype)
        try:
            definition = full_definition(msgtype)
            msgdef = definition.text
        except DefinitionNotFound:
            msgdef, _ = self.typestore.generate_msgdef(msgtype, ros_version=2)
        if offered_qos is None:
            offered_qos = [qos_profile(latched, 1 if latched else 10)]
        self._connections[topic] = self._writer.add_connection(
            topic, msgtype, msgdef=msgdef,
            rihs01=type_hash or self.typestore.hash_rihs01(msgtype),
            offered_qos_profiles=list(offered_qos))

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


# --------------------------------------------------------------------------- reading

def _check_mcap_file(bag: Path, file: Path) -> None:
    """Magic at both ends: a file cut short has no footer (readers would guess)."""
    size = file.stat().st_size
    with file.open('rb') as fh:
        head = fh.read(len(_MCAP_MAGIC))
        if head != _MCAP_MAGIC:
            raise BagError(f'bag {bag}: {file.name} is not an MCAP file')
        if size < 2 * len(_MCAP_MAGIC):
            raise BagError(f'bag {bag}: {file.name} is truncated ({size} bytes)')
        fh.seek(size - len(_MCAP_MAGIC))
        if fh.read() != _MCAP_MAGIC:
            raise BagError(f'bag {bag}: {file.name} is truncated (no MCAP footer; the recording '
                           'was cut off or the file was cut short)')


def check_bag_folder(path: Path | str) -> Path:
    """Fail with a one-line `BagError` unless ``path`` looks like a complete rosbag2 folder.

    Checks existence, that it is a folder with ``metadata.yaml``, and that every MCAP file in
    it is complete (magic at both ends). Content (CRCs, counts) is checked while reading.
    """
    path = Path(path)
    if not path.exists():
        raise BagError(f'bag {path} does not exist')
    if not path.is_dir():
        raise BagError(f'{path} is a file, not a rosbag2 bag folder (a folder with '
                       'metadata.yaml and its data files)')
    entries = sorted(p.name for p in path.iterdir())
    if not entries:
        raise BagError(f'bag {path} is an empty folder')
    if not (path / 'metadata.yaml').is_file():
        data = [e for e in entries if e.endswith(('.mcap', '.db3'))]
        raise BagError(f'{path} is not a rosbag2 bag: no metadata.yaml'
                       + (f' (data files {", ".join(data)} without it; the recording was not '
                          'closed)' if data else f' (it holds {len(entries)} other entries)'))
    for file in sorted(path.glob('*.mcap')):
        _check_mcap_file(path, file)
    return path


def _open_reader(path: Path | str) -> AnyReader:
    path = check_bag_folder(path)
    reader = AnyReader([path], default_typestore=slip_typestore())
    try:
        reader.open()
    except Exception as exc:
        text = str(exc)
        key = re.search(r'A metadata key is missing KeyError\((.+?)\)', text)
        if key:
            text = f'metadata.yaml is not rosbag2 metadata (it lacks {key.group(1)})'
        elif text.startswith('Could not load YAML'):
            detail = text.split('.yaml:', 1)[-1].split(' in "<unicode string>"')[0]
            text = 'metadata.yaml is not valid YAML: ' + detail.strip(' ;\n')
        if len(text) > 200:
            text = text[:197] + '...'
        raise BagError(f'cannot open bag {path}: {text}') from exc
    return reader


@dataclass(frozen=True)
class TopicInfo:
    """One topic of a bag (``count`` from the data, ``offered_qos`` as recorded)."""

    name: str
    msgtype: str
    count: int
    offered_qos: tuple[Qos, ...] = ()

    @property
    def latched(self) -> bool:
        """Every recorded publisher was transient local (replay it latched)."""
        return bool(self.offered_qos) and all(
            q.durability == QosDurability.TRANSIENT_LOCAL for q in self.offered_qos)


@dataclass(frozen=True)
class BagInfo:
    """Summary of a bag: times in seconds (bag receive stamps), counts from the data."""

    path: Path
    start_s: float
    end_s: float
    message_count: int
    topics: tuple[TopicInfo, ...]
    ros_distro: str = ''

    @property
    def duration_s(self) -> float:
        """Span between the first and the last message [s]."""
        return max(0.0, self.end_s - self.start_s)

    def format(self) -> str:
        """Human-readable table."""
        lines = [f'bag:       {self.path}', f'duration:  {self.duration_s:.3f} s',
                 f'start:     {self.start_s:.3f} s', f'messages:  {self.message_count}',
                 f'distro:    {self.ros_distro or "?"}', 'topics:']
        width = max((len(t.name) for t in self.topics), default=0)
        for t in self.topics:
            lines.append(f'  {t.name:<{width}}  {t.count:>8}  {t.msgtype}')
        return '\n'.join(lines)


class _CountCheck:
    """Counts messages per topic while reading; compares with what metadata.yaml claims."""

    def __init__(self, path: Path, reader: AnyReader, topics: set[str], total: bool) -> None:
        self.path = path
        self.claimed: dict[str, int] = {}
        for conn in reader.connections:
            if conn.topic in topics:
                self.claimed[conn.topic] = self.claimed.get(conn.topic, 0) + conn.msgcount
        self.counted = dict.fromkeys(self.claimed, 0)
        self.claimed_total = reader.message_count if total else None

    def add(self, topic: str) -> None:
        self.counted[topic] = self.counted.get(topic, 0) + 1

    def verify(self) -> None:
        wrong = [f'{t} {self.claimed.get(t, 0)} vs {n}' for t, n in sorted(self.counted.items())
                 if self.claimed.get(t, 0) != n]
        found = sum(self.counted.values())
        if self.claimed_total is not None and self.claimed_total != found:
            wrong.insert(0, f'all topics {self.claimed_total} vs {found}')
        if wrong:
            raise BagError(f'bag {self.path}: metadata.yaml message counts disagree with the data '
                           f'(claimed vs found: {", ".join(wrong[:4])}'
                           + (f', +{len(wrong) - 4} more' if len(wrong) > 4 else '')
                           + '); the metadata was edited or belongs to another recording')


def _iter_reader(path: Path | str, topics: Iterable[str] | None = None,
                 opened: Callable[[AnyReader], None] | None = None
                 ) -> Iterator[tuple[AnyReader, Any, int, bytes]]:
    """Yield ``(reader, connection, stamp_ns, raw)`` in time order; counts are verified at
    the end (so a caller that stops early skips that check). ``opened`` sees the reader first.
    """
    reader = _open_reader(path)
    path = Path(path)
    try:
        if opened is not None:
            opened(reader)
        wanted = None if topics is None else set(topics)
        present = {c.topic for c in reader.connections}
        if wanted is not None:
            missing = wanted - present
            if missing:
                raise BagError(f'bag {path} has no topic(s) {sorted(missing)}')
        conns = [c for c in reader.connections if wanted is None or c.topic in wanted]
        check = _CountCheck(path, reader, wanted if wanted is not None else present,
                            total=wanted is None)
        try:
            for conn, stamp, data in reader.messages(connections=conns):
                check.add(conn.topic)
                yield reader, conn, stamp, data
        except BagError:
            raise
        except Exception as exc:
            raise BagError(f'bag {path} is corrupt: {exc}') from exc
        check.verify()
    finally:
        reader.close()


def bag_info(path: Path | str) -> BagInfo:
    """Summary of a bag from a full pass over its data (CRCs and counts verified).

    Raises:
        BagError: missing, foreign, corrupt, truncated or inconsistent bags.
    """
    counts: dict[str, int] = {}
    types: dict[str, str] = {}
    qos: dict[str, tuple[Qos, ...]] = {}
    distro: list[str] = []
    start, end = None, None

    def opened(reader: AnyReader) -> None:
        for conn in reader.connections:
            types[conn.topic] = conn.msgtype
            qos[conn.topic] = tuple(getattr(conn.ext, 'offered_qos_profiles', ()) or ())
        for bag in reader.readers[:1]:
            assert isinstance(bag, Reader)  # _open_reader opens rosbag2 folders only
            distro.append(str(bag.ros_distro or ''))

    for _, conn, stamp, _ in _iter_reader(path, opened=opened):
        counts[conn.topic] = counts.get(conn.topic, 0) + 1
        start = stamp if start is None else min(start, stamp)
        end = stamp if end is None else max(end, stamp)
    topics = tuple(TopicInfo(name, msgtype, counts.get(name, 0), qos.get(name, ()))
                   for name, msgtype in sorted(types.items()))
    return BagInfo(Path(path), nanoseconds_to_seconds(start or 0),
                   nanoseconds_to_seconds(end or 0), sum(counts.values()), topics,
                   distro[0] if distro else '')


def validate_bag(path: Path | str) -> BagInfo:
    """`bag_info` that also refuses a bag without messages (nothing to export, replay or
    analyse)."""
    info = bag_info(path)
    if info.message_count == 0:
        raise BagError(f'bag {path} holds no messages ({len(info.topics)} topic(s) declared, '
                       'none recorded)')
    return info


def iter_raw(path: Path | str, topics: Iterable[str] | None = None
             ) -> Iterator[tuple[str, str, int, bytes]]:
    """Yield ``(topic, msgtype, stamp_ns, cdr_bytes)`` in time order.

    Raises:
        BagError: on a missing, foreign, corrupt or truncated bag, or counts that disagree
            with ``metadata.yaml`` (also mid-iteration or at the end).
    """
    for _, conn, stamp, data in _iter_reader(path, topics):
        yield conn.topic, conn.msgtype, stamp, bytes(data)


def read_messages(path: Path | str, topics: Iterable[str] | None = None
                  ) -> dict[str, list[tuple[int, Any]]]:
    """All messages of the selected topics, deserialized: ``{topic: [(stamp_ns, msg), ...]}``.

    Messages are rosbags objects with the same field names as the rclpy messages, decoded with
    the definitions stored in the bag.
    """
    topics = list(topics) if topics is not None else None
    out: dict[str, list[tuple[int, Any]]] = {t: [] for t in topics} if topics else {}
    for reader, conn, stamp, data in _iter_reader(path, topics):
        try:
            msg = reader.deserialize(data, conn.msgtype)
        except Exception as exc:
            raise BagError(f'cannot decode a {conn.msgtype} message on {conn.topic}: '
                           f'{exc}') from exc
        out.setdefault(conn.topic, []).append((stamp, msg))
    return out


def stamp_s(msg: Any) -> float:
    """``header.stamp`` of a message in seconds (rosbags and rclpy messages alike)."""
    return stamp_to_seconds(msg.header.stamp)


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
            row: dict[str, Any] = {'bag_time_s': nanoseconds_to_seconds(stamp)}
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
