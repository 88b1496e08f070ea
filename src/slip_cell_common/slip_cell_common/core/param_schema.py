"""Parameter sets as frozen dataclasses: flatten, validate and rebuild (ROS-free).

A node's parameters are one frozen dataclass; groups are nested frozen dataclasses whose
fields are flattened with ``.`` (``force_control.kp``). A group field marked ``flatten`` (see
`flattened_group`) adds its fields to its parent's level instead: a node's class nests a core's
parameter class without copying its fields, and the flat names stay those of the fields
(``expected_rate``, not ``session.expected_rate``). Two fields that flatten to one name, or a
name that is also a group prefix, are rejected when the specs are built. Each field may carry
metadata:

* ``unit``: unit string shown in the parameter description (SI).
* ``description``: one line for users.
* ``range``: ``(low, high)`` inclusive bounds for numbers (applied to every tuple element).
* ``choices``: allowed values for strings.
* ``required``: the default (empty string) is a placeholder that the user must replace.
* ``read_only``: bound at configure; cannot be changed at run time.
* ``flatten``: (group fields only) the group's fields join the parent's level.

`slip_cell_common.param_binding` declares these on an rclpy node.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, TypeVar
from collections.abc import Callable, Iterator, Mapping

T = TypeVar('T')

#: Python types a parameter field may hold (tuples are homogeneous and non-empty).
SCALAR_TYPES = (bool, int, float, str)


@dataclass(frozen=True)
class ParamSpec:
    """One flattened parameter: name, default value and metadata."""

    name: str
    default: Any
    kind: type
    unit: str = ''
    description: str = ''
    low: float | None = None
    high: float | None = None
    choices: tuple[str, ...] = ()
    required: bool = False
    read_only: bool = False
    is_tuple: bool = False


def ranged_field(default: Any, unit: str, low: float, high: float, description: str) -> Any:
    """A dataclass field carrying the ``unit``, ``range`` and ``description`` metadata above.

    Returns ``Any`` (a field spec, not the value) so it can initialise a field of any declared
    type; mypyc-compiled modules check declared types at run time.
    """
    return dataclasses.field(default=default, metadata={
        'unit': unit, 'range': (low, high), 'description': description})


def flattened_group(factory: Callable[[], Any]) -> Any:
    """A group field whose fields join the parent's level (metadata ``flatten``).

    Args:
        factory: Builds the group's default instance (usually the group's class).

    Returns ``Any`` for the same reason as `ranged_field`.
    """
    return dataclasses.field(default_factory=factory, metadata={'flatten': True})


class ParameterError(ValueError):
    """Raised when a parameter set is invalid; the message lists every problem."""


def _field_default(f: dataclasses.Field) -> Any:
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    raise TypeError(f'parameter field {f.name!r} has no default')


def _group_prefix(f: dataclasses.Field, value: Any, prefix: str) -> str | None:
    """Name prefix of a group field's members, or None when ``f`` is not a group."""
    if not dataclasses.is_dataclass(value):
        if f.metadata.get('flatten'):
            raise TypeError(f'parameter {prefix + f.name!r}: only a dataclass group can be '
                            'flattened')
        return None
    return prefix if f.metadata.get('flatten') else prefix + f.name + '.'


def iter_specs(cls: type, prefix: str = '') -> Iterator[ParamSpec]:
    """Yield the flattened parameter specs of a (nested) frozen dataclass type.

    A nested group's defaults are those of the instance its field's default (or
    ``default_factory``) produces, so two groups of one class can default differently.

    Raises:
        TypeError: when a field has no default or an unsupported type, or when two fields
            flatten to one name (``a`` twice, or ``a`` beside ``a.b``).
    """
    seen: set[str] = set()
    groups: set[str] = set()
    for spec in _iter_specs(cls, prefix, None):
        dotted = spec.name.split('.')
        parents = {'.'.join(dotted[:i]) for i in range(1, len(dotted))}
        if spec.name in seen or spec.name in groups or parents & seen:
            raise TypeError(f'parameter {spec.name!r} of {cls.__name__} collides with another '
                            'field (check flattened groups)')
        seen.add(spec.name)
        groups |= parents
        yield spec


def _iter_specs(cls: type, prefix: str, defaults: Any) -> Iterator[ParamSpec]:
    for f in dataclasses.fields(cls):
        default = getattr(defaults, f.name) if defaults is not None else _field_default(f)
        name = prefix + f.name
        group = _group_prefix(f, default, prefix)
        if group is not None:
            yield from _iter_specs(type(default), group, default)
            continue
        meta = f.metadata
        is_tuple = isinstance(default, tuple)
        if is_tuple:
            if not default:
                raise TypeError(f'tuple parameter {name!r} needs a non-empty default')
            kind = type(default[0])
        else:
            kind = type(default)
        if kind not in SCALAR_TYPES:
            raise TypeError(f'parameter {name!r} has unsupported type {kind.__name__}')
        low, high = meta.get('range', (None, None))
        yield ParamSpec(
            name=name, default=default, kind=kind, unit=meta.get('unit', ''),
            description=meta.get('description', ''), low=low, high=high,
            choices=tuple(meta.get('choices', ())), required=bool(meta.get('required', False)),
            read_only=bool(meta.get('read_only', False)), is_tuple=is_tuple)


def specs(cls: type) -> list[ParamSpec]:
    """List of flattened specs, in declaration order."""
    return list(iter_specs(cls))


def flatten(instance: Any, prefix: str = '') -> dict[str, Any]:
    """Flat ``{name: value}`` of a parameter dataclass instance."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(instance):
        value = getattr(instance, f.name)
        group = _group_prefix(f, value, prefix)
        if group is not None:
            out.update(flatten(value, group))
        else:
            out[prefix + f.name] = value
    return out


def _coerce(spec: ParamSpec, value: Any) -> Any:
    """Coerce a value to the spec's type; ints are accepted for floats, never the reverse."""
    def one(v: Any) -> Any:
        if spec.kind is float and isinstance(v, int) and not isinstance(v, bool):
            return float(v)
        if spec.kind is bool and not isinstance(v, bool):
            raise ParameterError(f'{spec.name}: expected bool, got {v!r}')
        if spec.kind is int and (isinstance(v, bool) or not isinstance(v, int)):
            raise ParameterError(f'{spec.name}: expected int, got {v!r}')
        if spec.kind in (float, str) and not isinstance(v, spec.kind):
            raise ParameterError(f'{spec.name}: expected {spec.kind.__name__}, got {v!r}')
        return v
    if spec.is_tuple:
        if not isinstance(value, (list, tuple)):
            raise ParameterError(f'{spec.name}: expected a list, got {value!r}')
        return tuple(one(v) for v in value)
    return one(value)


def check_value(spec: ParamSpec, value: Any) -> list[str]:
    """Problems with one (already coerced) value; empty when valid."""
    problems: list[str] = []
    values = value if spec.is_tuple else (value,)
    for v in values:
        if spec.kind is float and not math.isfinite(v):
            problems.append(f'{spec.name} = {v!r} is not finite')
        if spec.kind in (int, float) and not isinstance(v, bool):
            if spec.low is not None and v < spec.low:
                problems.append(f'{spec.name} = {v!r} below {spec.low} {spec.unit}'.rstrip())
            if spec.high is not None and v > spec.high:
                problems.append(f'{spec.name} = {v!r} above {spec.high} {spec.unit}'.rstrip())
        if spec.choices and v not in spec.choices:
            problems.append(f'{spec.name} = {v!r} not one of {list(spec.choices)}')
    if spec.required and (value == '' or value == ()):
        problems.append(f'{spec.name} is required but not set')
    return problems


def _build(cls: type, flat: Mapping[str, Any], prefix: str, defaults: Any = None) -> Any:
    kwargs: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        default = getattr(defaults, f.name) if defaults is not None else _field_default(f)
        name = prefix + f.name
        group = _group_prefix(f, default, prefix)
        if group is not None:
            kwargs[f.name] = _build(type(default), flat, group, default)
        elif name in flat:
            kwargs[f.name] = flat[name]
    return dataclasses.replace(defaults, **kwargs) if defaults is not None else cls(**kwargs)


def from_flat(cls: type[T], flat: Mapping[str, Any], *, strict: bool = True) -> T:
    """Build and validate an instance from flat ``{name: value}`` (missing names keep defaults).

    Raises:
        ParameterError: listing every unknown name (when ``strict``), type error and
            out-of-range value, so a user sees all problems at once.
    """
    spec_by_name = {s.name: s for s in iter_specs(cls)}
    problems: list[str] = []
    coerced: dict[str, Any] = {}
    for name, value in flat.items():
        spec = spec_by_name.get(name)
        if spec is None:
            if strict:
                problems.append(f'unknown parameter {name!r}')
            continue
        try:
            coerced[name] = _coerce(spec, value)
        except ParameterError as exc:
            problems.append(str(exc))
    for name, spec in spec_by_name.items():
        value = coerced.get(name, spec.default)
        if name in coerced or spec.required:
            problems.extend(check_value(spec, value))
    if problems:
        raise ParameterError('; '.join(problems))
    instance: T = _build(cls, coerced, '')
    validate = getattr(instance, 'validate', None)
    if callable(validate):
        validate()
    return instance


def replace_flat(instance: T, changes: Mapping[str, Any]) -> T:
    """A validated copy of ``instance`` with some flat parameters changed."""
    flat = flatten(instance)
    flat.update(changes)
    return from_flat(type(instance), flat)
