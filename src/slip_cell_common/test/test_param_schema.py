"""Parameter dataclass flattening, validation and rebuild (ROS-free)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import pytest

from slip_cell_common.core.param_schema import (ParameterError, flatten, flattened_group,
                                                   from_flat, replace_flat, specs)


@dataclass(frozen=True)
class Gains:
    kp: float = field(default=2.0, metadata={'unit': '-', 'range': (0.0, 20.0)})
    mode: str = field(default='mean', metadata={'choices': ('mean', 'finger_1')})


@dataclass(frozen=True)
class Cfg:
    port: str = field(default='', metadata={'required': True, 'read_only': True})
    rate: int = field(default=500, metadata={'range': (1, 10000)})
    offsets: tuple[float, ...] = field(default=(0.0, 0.0), metadata={'range': (-1.0, 1.0)})
    gains: Gains = field(default_factory=Gains)

    def validate(self) -> None:
        if self.port == 'forbidden':
            raise ParameterError('port forbidden')


def test_flatten_names_and_defaults() -> None:
    names = [s.name for s in specs(Cfg)]
    assert names == ['port', 'rate', 'offsets', 'gains.kp', 'gains.mode']
    assert flatten(Cfg())['gains.kp'] == 2.0
    assert [s.read_only for s in specs(Cfg)][0] is True


def test_from_flat_builds_nested_and_coerces_int_to_float() -> None:
    cfg = from_flat(Cfg, {'port': 'loop://', 'gains.kp': 3, 'offsets': [0.5, -0.5]})
    assert cfg.gains.kp == 3.0 and isinstance(cfg.gains.kp, float)
    assert cfg.offsets == (0.5, -0.5)


def test_every_problem_is_reported_at_once() -> None:
    with pytest.raises(ParameterError) as err:
        from_flat(Cfg, {'rate': 0, 'gains.kp': math.nan, 'gains.mode': 'median', 'bogus': 1,
                        'offsets': [2.0]})
    text = str(err.value)
    for piece in ('port is required', 'rate = 0 below 1', 'gains.kp = nan is not finite',
                  "not one of ['mean', 'finger_1']", "unknown parameter 'bogus'",
                  'offsets = 2.0 above 1.0'):
        assert piece in text


def test_type_errors_are_rejected() -> None:
    with pytest.raises(ParameterError, match='expected int'):
        from_flat(Cfg, {'port': 'x', 'rate': 2.5})
    with pytest.raises(ParameterError, match='expected bool|expected float'):
        from_flat(Cfg, {'port': 'x', 'gains.kp': True})


def test_custom_validate_runs_and_replace_keeps_other_values() -> None:
    with pytest.raises(ParameterError, match='forbidden'):
        from_flat(Cfg, {'port': 'forbidden'})
    cfg = from_flat(Cfg, {'port': 'loop://'})
    changed = replace_flat(cfg, {'gains.kp': 5.0})
    assert changed.gains.kp == 5.0 and changed.port == 'loop://' and cfg.gains.kp == 2.0


@dataclass(frozen=True)
class TwoGroups:
    squeeze: Gains = field(default_factory=Gains)
    release: Gains = field(default_factory=lambda: Gains(kp=-8.0, mode='finger_1'))


def test_nested_groups_keep_their_factory_defaults() -> None:
    defaults = {s.name: s.default for s in specs(TwoGroups)}
    assert defaults['squeeze.kp'] == 2.0 and defaults['release.kp'] == -8.0
    built = from_flat(TwoGroups, {'squeeze.kp': 3.0})
    assert built.release == Gains(kp=-8.0, mode='finger_1')
    assert built.squeeze.kp == 3.0


# --- flattened groups: a node's class nests a core's class without copying its fields ---------
@dataclass(frozen=True)
class Stream:
    rate: float = field(default=100.0, metadata={'unit': 'Hz', 'range': (1.0, 1000.0)})
    raw: bool = False


@dataclass(frozen=True)
class NodeCfg:
    name: str = 'a'
    stream: Stream = flattened_group(Stream)
    gains: Gains = field(default_factory=Gains)


def test_flattened_group_keeps_the_parent_level_names() -> None:
    assert [s.name for s in specs(NodeCfg)] == ['name', 'rate', 'raw', 'gains.kp', 'gains.mode']
    assert flatten(NodeCfg()) == {'name': 'a', 'rate': 100.0, 'raw': False, 'gains.kp': 2.0,
                                  'gains.mode': 'mean'}
    rate = next(s for s in specs(NodeCfg) if s.name == 'rate')
    assert (rate.low, rate.high, rate.unit) == (1.0, 1000.0, 'Hz')


def test_flattened_group_rebuilds_and_validates_from_flat_names() -> None:
    cfg = from_flat(NodeCfg, {'rate': 50, 'raw': True, 'gains.kp': 4.0})
    assert cfg.stream == Stream(rate=50.0, raw=True) and cfg.gains.kp == 4.0
    assert from_flat(NodeCfg, flatten(cfg)) == cfg
    assert replace_flat(cfg, {'rate': 10.0}).stream.rate == 10.0
    with pytest.raises(ParameterError) as err:
        from_flat(NodeCfg, {'rate': 0.5, 'stream.rate': 10.0})
    assert 'rate = 0.5 below 1.0 Hz' in str(err.value)
    assert "unknown parameter 'stream.rate'" in str(err.value)


def test_flattened_group_default_factory_defaults_are_kept() -> None:
    @dataclass(frozen=True)
    class Fast:
        stream: Stream = flattened_group(lambda: Stream(rate=500.0))

    assert specs(Fast)[0].default == 500.0
    assert from_flat(Fast, {'raw': True}).stream == Stream(rate=500.0, raw=True)


def test_flattened_collisions_are_rejected() -> None:
    @dataclass(frozen=True)
    class Twice:
        rate: float = 1.0
        stream: Stream = flattened_group(Stream)

    @dataclass(frozen=True)
    class Gains2:
        gains: float = 1.0

    @dataclass(frozen=True)
    class LeafAndGroup:
        gains: Gains = field(default_factory=Gains)
        more: Gains2 = flattened_group(Gains2)

    @dataclass(frozen=True)
    class GroupAfterLeaf:
        more: Gains2 = flattened_group(Gains2)
        gains: Gains = field(default_factory=Gains)

    for cls in (Twice, LeafAndGroup, GroupAfterLeaf):
        with pytest.raises(TypeError, match="'(rate|gains|gains.kp)' .* collides"):
            specs(cls)
        with pytest.raises(TypeError, match='collides'):
            from_flat(cls, {})


def test_only_groups_can_be_flattened() -> None:
    @dataclass(frozen=True)
    class Bad:
        rate: float = field(default=1.0, metadata={'flatten': True})

    with pytest.raises(TypeError, match='only a dataclass group'):
        specs(Bad)
