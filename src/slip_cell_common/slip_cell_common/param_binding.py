"""Declare a node's parameter dataclass on an rclpy node, validate on set, swap after set.

Usage in a node::

    self.params = ParameterBinding(self, GripperDriverParams)
    ...
    cfg = self.params.load()          # on configure: validated instance or ParameterError
    self.params.on_change(self._apply) # called with the new instance after a successful set

Ranges and choices are validated by `slip_cell_common.core.param_schema` (all problems in
one message) rather than by rclpy descriptors, so a bad YAML value makes configure fail with a
clear error instead of raising inside ``declare_parameter``. The range still shows up in the
parameter description for ``ros2 param describe``.
"""
from __future__ import annotations

from typing import Any, Callable, Generic, TypeVar

from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter

from slip_cell_common.core.param_schema import (ParameterError, ParamSpec, flatten,
                                                   from_flat, iter_specs)

P = TypeVar('P')


def _describe(spec: ParamSpec) -> str:
    parts = [spec.description or spec.name]
    if spec.unit and spec.unit != '-':
        parts.append(f'[{spec.unit}]')
    if spec.low is not None or spec.high is not None:
        parts.append(f'range {spec.low}..{spec.high}')
    if spec.choices:
        parts.append('one of ' + ', '.join(spec.choices))
    if spec.required:
        parts.append('(required)')
    return ' '.join(parts)


def _ros_value(value: Any) -> Any:
    return list(value) if isinstance(value, tuple) else value


class ParameterBinding(Generic[P]):
    """Binds a frozen parameter dataclass to a node's ROS parameters.

    Args:
        node: The node that owns the parameters.
        cls: Frozen dataclass type (nested dataclasses flatten to ``group.field``).
        prefix: Optional name prefix (``'sim.'``) for nodes that host several sets.
    """

    def __init__(self, node: Node, cls: type[P], prefix: str = '') -> None:
        self._node = node
        self._cls = cls
        self._prefix = prefix
        self._specs = {prefix + s.name: s for s in iter_specs(cls)}
        self._listeners: list[Callable[[P], None]] = []
        self._value: P | None = None
        for name, spec in self._specs.items():
            node.declare_parameter(name, _ros_value(spec.default), ParameterDescriptor(
                description=_describe(spec), read_only=spec.read_only, dynamic_typing=True))
        node.add_on_set_parameters_callback(self._validate_set)
        node.add_post_set_parameters_callback(self._after_set)

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
            ParameterError: listing every invalid, missing or mistyped parameter.
        """
        self._value = from_flat(self._cls, self._current_flat())
        return self._value

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
        if self._value is None or not any(p.name in self._specs for p in params):
            return
        self._value = from_flat(self._cls, self._current_flat())
        for listener in self._listeners:
            listener(self._value)
