"""Message definitions as rosbag2 stores them: the installed ``.msg`` text, comments kept.

rosbag2 (``LocalMessageDefinitionSource``) writes each topic's schema as the root type's
``.msg`` file verbatim, followed by every type it depends on, each introduced by a line of 80
``=`` and ``MSG: <pkg>/<Type>`` (the type as the field names it, package-qualified). The
``.msg`` files come from the ament index (``share/<pkg>/msg/<Type>.msg``), which exists for the
ROS wheels, a system install and this workspace alike. MCAP readers (``mcap_ros2``, Foxglove,
rosbags) parse this ``ros2msg`` text; the comments carry the units of our fields.

Types are also registered in a rosbags `Typestore` from the same files, so any installed
interface package can be written and read, not only the ones rosbags ships.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from rosbags.typesys import get_types_from_msg
from rosbags.typesys.store import Typestore

SEPARATOR = '=' * 80 + '\n'

#: Same expressions as rosbag2_cpp's local message definition source.
_TYPE_NAME = re.compile(r'^([a-zA-Z0-9_]+)(?:/[a-zA-Z0-9_]+)*/(?:msg/)?([a-zA-Z0-9_]+)$')
_FIELD_TYPE = re.compile(r'(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+')
_PRIMITIVES = frozenset({'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16',
                         'uint16', 'int32', 'uint32', 'int64', 'uint64', 'string'})
_MAX_DEPTH = 50


class DefinitionNotFound(LookupError):
    """No installed ``.msg`` file for a message type (the message names the type)."""


@dataclass(frozen=True)
class MessageDefinition:
    """A topic schema as rosbag2 stores it.

    Attributes:
        msgtype: ``pkg/msg/Type``.
        encoding: ``ros2msg`` (the only one produced here).
        text: Root ``.msg`` text, then every dependency after its delimiter.
    """

    msgtype: str
    encoding: str
    text: str


def split_type(msgtype: str) -> tuple[str, str]:
    """``'pkg/msg/Type'`` or ``'pkg/Type'`` → ``('pkg', 'Type')``."""
    match = _TYPE_NAME.match(msgtype)
    if match is None:
        raise DefinitionNotFound(f'type name {msgtype!r} is not of the form pkg/msg/Type')
    return match.group(1), match.group(2)


def msg_directory(package: str) -> Path:
    """``msg/`` directory of an installed interface package (ament index).

    Falls back to the workspace sources (``src/<pkg>``, ``src/upstream_interfaces/<pkg>``) when
    the workspace is not sourced, so tools still read our own types.
    """
    from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
    try:
        return Path(get_package_share_directory(package)) / 'msg'
    except (PackageNotFoundError, LookupError, ValueError):
        src = Path(__file__).resolve().parents[2]
        for candidate in (src / package, src / 'upstream_interfaces' / package):
            if (candidate / 'msg').is_dir():
                return candidate / 'msg'
    raise DefinitionNotFound(f'interface package {package} is not installed '
                             '(source install/setup.bash)')


def msg_file(msgtype: str) -> Path:
    """Installed ``.msg`` file of a type (ament index: ``share/<pkg>/msg/<Type>.msg``)."""
    package, name = split_type(msgtype)
    path = msg_directory(package) / f'{name}.msg'
    if not path.is_file():
        raise DefinitionNotFound(f'{package} has no msg/{name}.msg')
    return path


def dependencies(text: str, package: str) -> list[str]:
    """Non-primitive field types of a ``.msg`` text, package-qualified, sorted (as rosbag2)."""
    deps = set()
    for match in _FIELD_TYPE.finditer(text):
        name = match.group(1)
        if name in _PRIMITIVES:
            continue
        deps.add(name if '/' in name else f'{package}/{name}')
    return sorted(deps)


def full_definition(msgtype: str) -> MessageDefinition:
    """The ``ros2msg`` schema of ``msgtype`` with every dependency, comments kept.

    Raises:
        DefinitionNotFound: a ``.msg`` file of the type or of a dependency is not installed.
    """
    seen: set[str] = set()

    def append(name: str, depth: int) -> str:
        if depth <= 0:
            raise DefinitionNotFound(f'definition of {msgtype} nests too deeply')
        package, _ = split_type(name)
        text = msg_file(name).read_text()
        for dep in dependencies(text, package):
            if dep not in seen:
                seen.add(dep)
                text += '\n' + SEPARATOR + f'MSG: {dep}\n' + append(dep, depth - 1)
        return text

    return MessageDefinition(msgtype, 'ros2msg', append(msgtype, _MAX_DEPTH))


def _normalized(name: str) -> str:
    package, type_name = split_type(name)
    return f'{package}/msg/{type_name}'


def register_type(store: Typestore, msgtype: str) -> None:
    """Register ``msgtype`` and its dependencies in ``store`` from the installed ``.msg`` files.

    Types the store already knows are left as they are.

    Raises:
        DefinitionNotFound: a needed ``.msg`` file is not installed.
    """
    pending = [_normalized(msgtype)]
    types: dict[str, object] = {}
    while pending:
        name = pending.pop()
        if name in store.fielddefs or name in types:
            continue
        package, _ = split_type(name)
        text = msg_file(name).read_text()
        types.update(get_types_from_msg(text, name))
        pending.extend(_normalized(d) for d in dependencies(text, package))
    if types:
        store.register(types)  # type: ignore[arg-type]
