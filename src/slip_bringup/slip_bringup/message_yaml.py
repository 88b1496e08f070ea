"""rclpy messages ↔ plain data / YAML, for ``slip_cli`` (``rosidl_runtime_py`` has no wheel).

`message_to_yaml` prints a message as ``ros2 topic echo`` does; `fill_message` sets a
message's fields from a dict (YAML arguments of ``slip_cli call``), converting integers given
for float fields and recursing into nested messages and sequences of messages.
"""
from __future__ import annotations

import array
import importlib
import math
from typing import Any

import yaml


class MessageFieldError(ValueError):
    """A YAML argument names a field the message lacks or gives a value of the wrong type."""


def import_interface(name: str, kind: str) -> Any:
    """``'pkg/srv/Name'`` or ``'pkg/Name'`` (``kind`` = msg/srv/action) → the rclpy class.

    Typed ``Any``: the generated class is found at run time, so its fields (and a service's
    ``Request``/``Response``) are unknown to the type checker."""
    parts = name.strip('/').split('/')
    if len(parts) == 2:
        parts = [parts[0], kind, parts[1]]
    if len(parts) != 3 or parts[1] != kind:
        raise MessageFieldError(f'{name!r} is not a {kind} type name (pkg/{kind}/Name)')
    try:
        return getattr(importlib.import_module(f'{parts[0]}.{parts[1]}'), parts[2])
    except (ImportError, AttributeError):
        raise MessageFieldError(f'{kind} type {"/".join(parts)} is not installed') from None


def _is_message(value: Any) -> bool:
    return hasattr(value, 'get_fields_and_field_types')


def message_to_data(value: Any) -> Any:
    """Nested dicts/lists of Python scalars (field order kept)."""
    if _is_message(value):
        return {name: message_to_data(getattr(value, name))
                for name in value.get_fields_and_field_types()}
    if isinstance(value, (bytes, bytearray)):
        return list(value)
    if isinstance(value, (list, tuple, array.array)) or hasattr(value, 'tolist'):
        items = value.tolist() if hasattr(value, 'tolist') else list(value)
        return [message_to_data(v) for v in items]
    return value


class _Dumper(yaml.SafeDumper):
    """Block style, field order kept, NaN/inf as YAML's ``.nan``/``.inf``."""


def _represent_float(dumper: yaml.SafeDumper, value: float) -> Any:
    if math.isnan(value):
        return dumper.represent_scalar('tag:yaml.org,2002:float', '.nan')
    return yaml.SafeDumper.represent_float(dumper, value)


_Dumper.add_representer(float, _represent_float)


def message_to_yaml(msg: Any) -> str:
    """YAML text of a message (as ``ros2 topic echo`` prints it, without the ``---``)."""
    return yaml.dump(message_to_data(msg), Dumper=_Dumper, sort_keys=False,
                     default_flow_style=False, allow_unicode=True)


def _element_class(msg: Any, name: str) -> type | None:
    """Message class of the elements of a sequence field (None for primitives)."""
    slot = msg.SLOT_TYPES[list(msg.get_fields_and_field_types()).index(name)]
    value_type = getattr(slot, 'value_type', slot)
    namespaces = getattr(value_type, 'namespaces', None)
    if not namespaces:
        return None
    return getattr(importlib.import_module('.'.join(namespaces)), value_type.name)


def fill_message(msg: Any, data: dict[str, Any] | None, path: str = '') -> Any:
    """Set fields of ``msg`` from ``data``; returns ``msg``.

    Raises:
        MessageFieldError: unknown field or a value the field does not accept.
    """
    if data is None:
        return msg
    if not isinstance(data, dict):
        raise MessageFieldError(f'{path or "the message"} needs a mapping of fields, got '
                                f'{data!r}')
    fields = list(msg.get_fields_and_field_types())
    for name, value in data.items():
        where = f'{path}{name}'
        if name not in fields:
            raise MessageFieldError(f'{type(msg).__name__} has no field {where!r} (fields: '
                                    f'{", ".join(fields) or "none"})')
        current = getattr(msg, name)
        try:
            if _is_message(current):
                fill_message(current, value, where + '.')
                continue
            if isinstance(value, list):
                element = _element_class(msg, name)
                if element is not None:
                    value = [fill_message(element(), v, f'{where}[{i}].')
                             for i, v in enumerate(value)]
                elif len(value) and isinstance(value[0], int) and not isinstance(value[0], bool) \
                        and _float_sequence(current):
                    value = [float(v) for v in value]
            elif isinstance(current, float) and isinstance(value, int) \
                    and not isinstance(value, bool):
                value = float(value)
            setattr(msg, name, value)
        except MessageFieldError:
            raise
        except (AssertionError, TypeError, ValueError) as exc:
            raise MessageFieldError(f'field {where!r} does not accept {value!r}'
                                    + (f': {exc}' if str(exc) else '')) from None
    return msg


def _float_sequence(current: Any) -> bool:
    if isinstance(current, array.array):
        return current.typecode in 'fd'
    dtype = getattr(current, 'dtype', None)
    return dtype is not None and dtype.kind == 'f'
