"""Parameter dataclasses declared on a real rclpy node: overrides, validation on set, swap."""
from __future__ import annotations

from dataclasses import dataclass, field

import pytest

pytestmark = pytest.mark.ros


@dataclass(frozen=True)
class Loop:
    kp: float = field(default=2.0, metadata={'unit': '-', 'range': (0.0, 20.0),
                                             'description': 'proportional gain'})
    measurement: str = field(default='mean', metadata={'choices': ('mean', 'finger_1')})


@dataclass(frozen=True)
class Cfg:
    port: str = field(default='', metadata={'required': True, 'read_only': True})
    loop: Loop = field(default_factory=Loop)


def _node(ctx, overrides):  # noqa: ANN001, ANN202
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    return Node('binding_probe', context=ctx, parameter_overrides=[
        Parameter(k, value=v) for k, v in overrides.items()])


def test_overrides_validation_and_swap(ros_context) -> None:
    from rclpy.parameter import Parameter
    from slip_cell_common.param_binding import ParameterBinding
    node = _node(ros_context, {'port': 'loop://', 'loop.kp': 3})  # int given for a float
    binding = ParameterBinding(node, Cfg)
    seen: list[Cfg] = []
    binding.on_change(seen.append)
    cfg = binding.load()
    assert cfg.port == 'loop://' and cfg.loop.kp == 3.0
    assert set(binding.names) == {'port', 'loop.kp', 'loop.measurement'}
    assert 'range 0.0..20.0' in node.describe_parameter('loop.kp').description

    result = node.set_parameters([Parameter('loop.kp', value=50.0)])[0]
    assert not result.successful and 'above 20.0' in result.reason
    assert binding.value.loop.kp == 3.0 and not seen

    result = node.set_parameters([Parameter('loop.measurement', value='finger_1')])[0]
    assert result.successful
    assert binding.value.loop.measurement == 'finger_1' and seen[-1] is binding.value

    assert not node.set_parameters([Parameter('port', value='x')])[0].successful  # read-only
    node.destroy_node()


def test_missing_required_and_bad_values_fail_load_with_every_problem(ros_context) -> None:
    from slip_cell_common.param_binding import ParameterBinding
    from slip_cell_common.core.param_schema import ParameterError
    node = _node(ros_context, {'loop.kp': -1.0, 'loop.measurement': 'median'})
    binding = ParameterBinding(node, Cfg)
    with pytest.raises(ParameterError) as err:
        binding.load()
    for piece in ('port is required', 'loop.kp = -1.0 below 0.0', "'median' not one of"):
        assert piece in str(err.value)
    node.destroy_node()
