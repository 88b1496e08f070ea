"""Parameter dataclasses declared on a real rclpy node: typed descriptors, overrides, validation
on set, swap, and flattened core groups reaching the node's names."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import pytest

from slip_cell_common.core.param_schema import ParameterError, from_flat, specs

pytestmark = pytest.mark.ros


@dataclass(frozen=True)
class Loop:
    kp: float = field(default=2.0, metadata={'unit': '-', 'range': (0.0, 20.0),
                                             'description': 'proportional gain'})
    measurement: str = field(default='mean', metadata={'choices': ('mean', 'finger_1')})
    period: float = field(default=0.002, metadata={'unit': 's', 'range': (0.0005, 0.1),
                                                   'description': 'loop period'})


@dataclass(frozen=True)
class Cfg:
    port: str = field(default='', metadata={'required': True, 'read_only': True})
    decimation: int = field(default=5, metadata={'range': (1, 500)})
    offsets: tuple[float, ...] = field(default=(0.0, 0.0), metadata={
        'unit': 'm', 'range': (-1.0, 1.0)})
    enabled: bool = True
    loop: Loop = field(default_factory=Loop)

    def validate(self) -> None:
        if self.loop.kp > 10.0 and self.loop.measurement == 'finger_1':
            raise ParameterError('loop.kp above 10 needs loop.measurement mean')


def _node(ctx, overrides, name='binding_probe'):
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    return Node(name, context=ctx, parameter_overrides=[
        Parameter(k, value=v) for k, v in overrides.items()])


def test_descriptors_are_typed_with_ranges_units_and_read_only(ros_context) -> None:
    from rcl_interfaces.msg import ParameterType as T
    from slip_cell_common.param_binding import ParameterBinding
    node = _node(ros_context, {'port': 'loop://'})
    ParameterBinding(node, Cfg)
    kp, period, dec, offsets, port, mode, enabled = node.describe_parameters(
        ['loop.kp', 'loop.period', 'decimation', 'offsets', 'port', 'loop.measurement',
         'enabled'])
    assert [d.type for d in (kp, dec, offsets, port, enabled)] == [
        T.PARAMETER_DOUBLE, T.PARAMETER_INTEGER, T.PARAMETER_DOUBLE_ARRAY, T.PARAMETER_STRING,
        T.PARAMETER_BOOL]
    assert not any(d.dynamic_typing for d in (kp, dec, offsets, port, mode, enabled))
    assert [(r.from_value, r.to_value, r.step) for r in kp.floating_point_range] == [
        (0.0, 20.0, 0.0)]
    assert [(r.from_value, r.to_value) for r in period.floating_point_range] == [(0.0005, 0.1)]
    assert [(r.from_value, r.to_value, r.step) for r in dec.integer_range] == [(1, 500, 0)]
    assert not kp.integer_range and not dec.floating_point_range
    assert kp.description == 'proportional gain'            # unit '-' is not shown
    assert period.description == 'loop period [s]'
    assert 'each element in [-1.0, 1.0] m' in offsets.additional_constraints
    assert 'one of mean, finger_1' in mode.additional_constraints
    assert port.read_only and 'required' in port.additional_constraints
    assert not kp.read_only
    node.destroy_node()


def test_overrides_validation_and_swap(ros_context) -> None:
    from rclpy.parameter import Parameter
    from slip_cell_common.param_binding import ParameterBinding
    node = _node(ros_context, {'port': 'loop://', 'loop.kp': 3})  # int given for a float
    binding = ParameterBinding(node, Cfg)
    seen: list[Cfg] = []
    binding.on_change(seen.append)
    cfg = binding.load()
    assert cfg.port == 'loop://' and cfg.loop.kp == 3.0
    assert node.get_parameter('loop.kp').type_ == Parameter.Type.DOUBLE
    assert set(binding.names) == {'port', 'decimation', 'offsets', 'enabled', 'loop.kp',
                                  'loop.measurement', 'loop.period'}

    result = node.set_parameters([Parameter('loop.kp', value=50.0)])[0]  # descriptor range
    assert not result.successful and 'loop.kp out of range' in result.reason
    result = node.set_parameters([Parameter('decimation', value=0)])[0]
    assert not result.successful and 'decimation out of range' in result.reason
    result = node.set_parameters([Parameter('offsets', value=[0.5, 2.0])])[0]  # schema
    assert not result.successful and 'offsets = 2.0 above 1.0 m' in result.reason
    result = node.set_parameters([Parameter('loop.measurement', value='median')])[0]
    assert not result.successful and "'median' not one of" in result.reason
    assert binding.value.loop.kp == 3.0 and not seen

    result = node.set_parameters([Parameter('loop.measurement', value='finger_1')])[0]
    assert result.successful
    assert binding.value.loop.measurement == 'finger_1' and seen[-1] is binding.value
    result = node.set_parameters([Parameter('loop.kp', value=12.0)])[0]  # validate()
    assert not result.successful and 'needs loop.measurement mean' in result.reason

    assert not node.set_parameters([Parameter('port', value='x')])[0].successful  # read-only
    node.destroy_node()


def test_an_integer_set_on_a_double_is_refused_and_keeps_the_type(ros_context) -> None:
    from rclpy.parameter import Parameter
    from slip_cell_common.param_binding import ParameterBinding
    node = _node(ros_context, {'port': 'loop://'})
    binding = ParameterBinding(node, Cfg)
    binding.load()
    result = node.set_parameters([Parameter('loop.kp', value=4)])[0]
    assert not result.successful and 'Wrong parameter type' in result.reason
    assert not node.set_parameters([Parameter('decimation', value=4.0)])[0].successful
    assert not node.set_parameters([Parameter('enabled', value=1)])[0].successful
    kp = node.get_parameter('loop.kp')
    assert kp.type_ == Parameter.Type.DOUBLE and kp.value == 2.0
    assert node.describe_parameter('loop.kp').type == Parameter.Type.DOUBLE.value
    assert node.set_parameters([Parameter('loop.kp', value=4.0)])[0].successful
    assert binding.value.loop.kp == 4.0
    node.destroy_node()


def test_missing_required_and_bad_values_fail_load_with_every_problem(ros_context) -> None:
    from slip_cell_common.param_binding import ParameterBinding
    node = _node(ros_context, {'loop.kp': -1.0, 'loop.measurement': 'median',
                               'decimation': 'five'})
    binding = ParameterBinding(node, Cfg)
    with pytest.raises(ParameterError) as err:
        binding.load()
    for piece in ('port is required', 'loop.kp = -1.0 below 0.0', "'median' not one of",
                  "decimation: expected int, got 'five'"):
        assert piece in str(err.value)
    # Refused launch-time values leave the defaults declared, with their types.
    assert node.get_parameter('loop.kp').value == 2.0
    assert node.get_parameter('decimation').value == 5
    node.destroy_node()


def test_a_refused_launch_value_is_replaced_by_a_later_set(ros_context) -> None:
    from rclpy.parameter import Parameter
    from slip_cell_common.param_binding import ParameterBinding
    node = _node(ros_context, {'port': 'loop://', 'loop.kp': 30.0})
    binding = ParameterBinding(node, Cfg)
    with pytest.raises(ParameterError, match='loop.kp = 30.0 above 20.0'):
        binding.load()
    assert node.set_parameters([Parameter('loop.kp', value=5.0)])[0].successful
    assert binding.load().loop.kp == 5.0
    node.destroy_node()


# --- a field added to a core class reaches the node (issue 14: no copied fields) --------------
def _with_added_field(node_cls: type, group: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Make ``node_cls``'s (flattened) group ``group`` produce a core class with one more field.

    The node class itself is untouched: only the group field's default factory now builds a
    subclass of the core class, as if a field had been added to the core class.
    """
    node_field = next(f for f in dataclasses.fields(node_cls) if f.name == group)
    core_cls = type(node_field.default_factory())  # type: ignore[misc]
    extended = dataclass(frozen=True)(type(f'Extended{core_cls.__name__}', (core_cls,), {
        '__annotations__': {'added_probe_field': float},
        'added_probe_field': field(default=0.5, metadata={'unit': 's', 'range': (0.0, 1.0)})}))
    monkeypatch.setattr(node_field, 'default_factory', extended)


NODE_GROUPS = [
    ('slip_gripper_driver.node_params', 'NetFTDriverParams', 'stream',
     {'address': '127.0.0.1'}),
    ('slip_gripper_driver.core.netft_params', 'FtParams', 'stream', {}),  # gripper_driver's ft.*
    ('slip_velocity_sensor.core.params', 'VelocitySensorParams', 'session',
     {'port': 'loop://'}),
]


@pytest.mark.parametrize('module, name, group, required', NODE_GROUPS,
                         ids=[e[1] for e in NODE_GROUPS])
def test_a_field_added_to_a_core_class_reaches_the_node(ros_context, monkeypatch, module,
                                                        name, group, required) -> None:
    import importlib

    from rclpy.parameter import Parameter
    from slip_cell_common.param_binding import ParameterBinding
    node_cls = getattr(importlib.import_module(module), name)
    before = [s.name for s in specs(node_cls)]
    _with_added_field(node_cls, group, monkeypatch)
    after = [s.name for s in specs(node_cls)]
    assert 'added_probe_field' not in before
    assert sorted(after) == sorted([*before, 'added_probe_field'])  # flat: no group prefix

    node = _node(ros_context, {**required, 'added_probe_field': 0.25}, name=name.lower())
    binding = ParameterBinding(node, node_cls)
    assert 'added_probe_field' in binding.names
    assert node.describe_parameter('added_probe_field').floating_point_range[0].to_value == 1.0
    cfg = binding.load()
    assert getattr(cfg, group).added_probe_field == 0.25
    assert not node.set_parameters([Parameter('added_probe_field', value=2.0)])[0].successful
    rebuilt = from_flat(node_cls, {**required, 'added_probe_field': 0.75})
    assert getattr(rebuilt, group).added_probe_field == 0.75
    node.destroy_node()
