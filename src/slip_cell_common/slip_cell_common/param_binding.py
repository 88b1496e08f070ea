"""Declare a node's parameter dataclass on an rclpy node, validate on set, swap after set.

Usage in a node::

    self.params = ParameterBinding(self, GripperDriverParams)
    ...
    cfg = self.params.load()          # on configure: validated instance or ParameterError
    self.params.on_change(self._apply) # called with the new instance after a successful set

Every parameter is declared statically typed with a descriptor built from the schema
(`parameter_descriptor`): its type, the description with the unit, ``floating_point_range`` /
``integer_range`` from ``range``, ``read_only``, and the choices, the ``required`` flag and
array element ranges as ``additional_constraints``. ``ros2 param describe`` and rqt show the
limits, and rclpy itself refuses a run-time set of the wrong type (an integer for a double
stays refused; the type never changes) or outside the range. Choices, finiteness and the
cross-field checks of the dataclass's ``validate()`` are checked by the on-set callback, which
refuses with the schema's reason.

Launch-time values (YAML files, ``-p``) are handled so that configure reports every problem at
once instead of the constructor raising inside ``declare_parameter``: an integer given for a
double (``2`` in a YAML file) is taken as that double; any other value rclpy would refuse is
kept aside, the parameter is declared with its default, and `ParameterBinding.load` fails with
the schema's message for every such value. A later successful set replaces the kept value.
"""
from __future__ import annotations

import math
from typing import Any, Generic, TypeVar
from collections.abc import Callable

from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                ParameterType, SetParametersResult)
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.node import Node
from rclpy.parameter import Parameter

from slip_cell_common.core.param_schema import (ParameterError, ParamSpec, flatten,
                                                   from_flat, iter_specs)

P = TypeVar('P')

#: ``(Python type, is_tuple)`` of a spec → ROS parameter type.
_ROS_TYPES: dict[tuple[type, bool], int] = {
    (bool, False): ParameterType.PARAMETER_BOOL,
    (int, False): ParameterType.PARAMETER_INTEGER,
    (float, False): ParameterType.PARAMETER_DOUBLE,
    (str, False): ParameterType.PARAMETER_STRING,
    (bool, True): ParameterType.PARAMETER_BOOL_ARRAY,
    (int, True): ParameterType.PARAMETER_INTEGER_ARRAY,
    (float, True): ParameterType.PARAMETER_DOUBLE_ARRAY,
    (str, True): ParameterType.PARAMETER_STRING_ARRAY,
}
_INT64 = (-2 ** 63, 2 ** 63 - 1)
_DECLARE_ERRORS = (InvalidParameterTypeException, InvalidParameterValueException)


def _has_range(spec: ParamSpec) -> bool:
    return spec.kind in (int, float) and (spec.low is not None or spec.high is not None)


def _constraints(spec: ParamSpec) -> str:
    parts: list[str] = []
    if spec.is_tuple and _has_range(spec):
        unit = f' {spec.unit}' if spec.unit and spec.unit != '-' else ''
        parts.append(f'each element in [{spec.low}, {spec.high}]{unit}')
    if spec.choices:
        parts.append('one of ' + ', '.join(spec.choices))
    if spec.kind is float:
        parts.append('finite')
    if spec.required:
        parts.append('required (no usable default)')
    return '; '.join(parts)


def parameter_descriptor(spec: ParamSpec) -> ParameterDescriptor:
    """The statically typed ROS descriptor of one flattened parameter.

    The description ends with the unit in brackets (none for ``-``); scalar ranges become
    ``floating_point_range`` / ``integer_range`` (step 0: any value in the closed interval).
    """
    description = spec.description or spec.name
    if spec.unit and spec.unit != '-':
        description += f' [{spec.unit}]'
    descriptor = ParameterDescriptor(
        name=spec.name, type=_ROS_TYPES[(spec.kind, spec.is_tuple)], description=description,
        additional_constraints=_constraints(spec), read_only=spec.read_only,
        dynamic_typing=False)
    if _has_range(spec) and not spec.is_tuple:
        if spec.kind is float:
            low = -math.inf if spec.low is None else float(spec.low)
            high = math.inf if spec.high is None else float(spec.high)
            descriptor.floating_point_range = [
                FloatingPointRange(from_value=low, to_value=high, step=0.0)]
        else:
            low_i = _INT64[0] if spec.low is None else int(math.ceil(spec.low))
            high_i = _INT64[1] if spec.high is None else int(math.floor(spec.high))
            descriptor.integer_range = [IntegerRange(from_value=low_i, to_value=high_i, step=0)]
    return descriptor


def _ros_value(value: Any) -> Any:
    return list(value) if isinstance(value, tuple) else value


def _as_double(spec: ParamSpec, value: Any) -> Any:
    """A launch-time integer (or integer list) given for a double parameter, as doubles."""
    def is_int(v: Any) -> bool:
        return isinstance(v, int) and not isinstance(v, bool)
    if spec.kind is not float:
        return value
    if spec.is_tuple and isinstance(value, (list, tuple)) and value and all(map(is_int, value)):
        return [float(v) for v in value]
    if not spec.is_tuple and is_int(value):
        return float(value)
    return value


class ParameterBinding(Generic[P]):
    """Binds a frozen parameter dataclass to a node's ROS parameters.

    Args:
        node: The node that owns the parameters.
        cls: Frozen dataclass type (nested dataclasses flatten to ``group.field``; groups marked
            ``flatten`` join their parent's level).
        prefix: Optional name prefix (``'sim.'``) for nodes that host several sets.
    """

    def __init__(self, node: Node, cls: type[P], prefix: str = '') -> None:
        self._node = node
        self._cls = cls
        self._prefix = prefix
        self._specs = {prefix + s.name: s for s in iter_specs(cls)}
        self._listeners: list[Callable[[P], None]] = []
        self._value: P | None = None
        #: Launch-time values rclpy refused at declaration: ``{name: (value, rclpy reason)}``.
        self._refused: dict[str, tuple[Any, str]] = {}
        for name, spec in self._specs.items():
            self._declare(name, spec)
        node.add_on_set_parameters_callback(self._validate_set)
        node.add_post_set_parameters_callback(self._after_set)

    def _declare(self, name: str, spec: ParamSpec) -> None:
        node = self._node
        default = _ros_value(spec.default)
        try:
            node.declare_parameter(name, default, parameter_descriptor(spec))
            return
        except _DECLARE_ERRORS as exc:
            reason = str(exc)
        # The launch-time value does not fit the descriptor: read it untyped, then declare the
        # typed parameter with it as a double (an integer given for a double) or else with the
        # default. rclpy infers the type from the value passed, so no other value is passed.
        given = node.declare_parameter(
            name, default, ParameterDescriptor(dynamic_typing=True)).value
        node.undeclare_parameter(name)
        as_double = _as_double(spec, given)
        if as_double is not given:
            try:
                node.declare_parameter(name, as_double, parameter_descriptor(spec),
                                       ignore_override=True)
                return
            except _DECLARE_ERRORS as exc:
                reason = str(exc)
        node.declare_parameter(name, default, parameter_descriptor(spec), ignore_override=True)
        self._refused[name] = (given, reason)

    @property
    def names(self) -> list[str]:
        """Flattened ROS parameter names, in declaration order."""
        return list(self._specs)

    @property
    def value(self) -> P:
        """The current validated instance (load() must have succeeded once)."""
        if self._value is None:
            raise RuntimeError('parameters not loaded yet: call load() first')
        return self._value

    def _current_flat(self) -> dict[str, Any]:
        flat: dict[str, Any] = {}
        for name in self._specs:
            value = self._node.get_parameter(name).value
            flat[name[len(self._prefix):]] = tuple(value) if isinstance(value, list) else value
        return flat

    def load(self) -> P:
        """Read every parameter, validate, store and return the instance.

        Raises:
            ParameterError: listing every invalid, missing or mistyped parameter, including
                launch-time values that were refused at declaration.
        """
        flat = self._current_flat()
        for name, (given, _) in self._refused.items():
            flat[name[len(self._prefix):]] = tuple(given) if isinstance(given, list) else given
        instance = from_flat(self._cls, flat)
        if self._refused:  # the schema accepted what rclpy refused: report rclpy's reasons
            raise ParameterError('; '.join(reason for _, reason in self._refused.values()))
        self._value = instance
        return instance

    def on_change(self, listener: Callable[[P], None]) -> None:
        """Call ``listener(new_instance)`` after every successful run-time parameter set."""
        self._listeners.append(listener)

    def _validate_set(self, params: list[Parameter]) -> SetParametersResult:
        ours = {p.name: p.value for p in params if p.name in self._specs}
        if not ours:
            return SetParametersResult(successful=True)
        flat = self._current_flat() if self._value is None else flatten(self._value)
        for name, value in ours.items():
            flat[name[len(self._prefix):]] = tuple(value) if isinstance(value, list) else value
        try:
            from_flat(self._cls, flat)
        except (ParameterError, ValueError, TypeError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _after_set(self, params: list[Parameter]) -> None:
        for p in params:
            self._refused.pop(p.name, None)
        if self._value is None or not any(p.name in self._specs for p in params):
            return
        self._value = from_flat(self._cls, self._current_flat())
        for listener in self._listeners:
            listener(self._value)
