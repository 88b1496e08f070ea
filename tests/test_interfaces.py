"""Every slip_msgs type imports, is fully documented, and round-trips through rclpy
serialization."""
from __future__ import annotations

import importlib
import math
import re
from pathlib import Path

import pytest

pytestmark = pytest.mark.ros
serialization = pytest.importorskip('rclpy.serialization')

PKG = Path(__file__).resolve().parents[1] / 'src' / 'slip_msgs'
INTERFACE_FILES = sorted(p for d in ('msg', 'srv', 'action') for p in (PKG / d).glob('*.*'))


def _message_types() -> list[type]:
    types: list[type] = []
    for path in INTERFACE_FILES:
        module = importlib.import_module(f'slip_msgs.{path.parent.name}')
        cls = getattr(module, path.stem)
        if path.parent.name == 'msg':
            types.append(cls)
        elif path.parent.name == 'srv':
            types += [cls.Request, cls.Response]
        else:
            types += [cls.Goal, cls.Result, cls.Feedback]
    return types


def _fill(msg: object, seed: int) -> object:
    """Set every field to a distinctive non-default value (recursing into nested messages)."""
    for name, kind in msg.get_fields_and_field_types().items():
        value = getattr(msg, name)
        if kind == 'double':
            setattr(msg, name, seed + 0.25)
        elif kind in ('uint8', 'uint32', 'int16', 'int8'):
            setattr(msg, name, (seed % 100) + 1)
        elif kind == 'boolean':
            setattr(msg, name, True)
        elif kind == 'string':
            setattr(msg, name, f'value-{seed}')
        elif kind.startswith('double['):
            setattr(msg, name, [seed + 0.5] * len(value))
        elif kind.startswith('int16['):
            setattr(msg, name, [-(seed % 100) - 1] * len(value))
        elif kind.startswith('boolean['):
            setattr(msg, name, [True] * len(value))
        elif kind == 'sequence<geometry_msgs/TransformStamped>':  # TransformArray
            from geometry_msgs.msg import TransformStamped
            item = TransformStamped(child_frame_id=f'child-{seed}')
            item.transform.translation.x = seed + 0.75
            setattr(msg, name, [item, item])
        elif hasattr(value, 'get_fields_and_field_types'):
            _fill(value, seed + 1)
        seed += 1
    return msg


def test_every_interface_file_is_built() -> None:
    assert len(INTERFACE_FILES) == 20
    assert len(_message_types()) == 11 + 2 * 7 + 3 * 2


@pytest.mark.parametrize('msg_type', _message_types(), ids=lambda t: t.__name__)
def test_round_trip(msg_type: type) -> None:
    original = _fill(msg_type(), 3)
    data = serialization.serialize_message(original)
    decoded = serialization.deserialize_message(data, msg_type)
    assert decoded == original
    assert decoded != msg_type() or not msg_type.get_fields_and_field_types()


@pytest.mark.parametrize('path', INTERFACE_FILES, ids=lambda p: p.name)
def test_every_numeric_field_documents_its_unit(path: Path) -> None:
    """Each float field carries a comment; SI units only (no degrees, mm, ms)."""
    for line in path.read_text().splitlines():
        code = line.split('#', 1)[0].strip()
        if not code or '=' in code or code == '---':
            continue
        if code.split()[0].startswith('float64'):
            assert '#' in line or _documented_elsewhere(path, code), f'{path.name}: {line!r}'
        comment = line.split('#', 1)[1] if '#' in line else ''
        assert not re.search(r'\[(deg|mm|ms|mm/s)\]', comment), f'{path.name}: non-SI in {line!r}'


def _documented_elsewhere(path: Path, code: str) -> bool:
    # Goal/feedback fields of actions repeat SetSlipMode fields documented there.
    return path.suffix == '.action' and code.split()[1] in {'duration', 'distance', 'angle'}


def test_mode_constants_match_between_interfaces() -> None:
    from slip_msgs.msg import ContactProperties, MotorCommand
    from slip_msgs.srv import SetSlipMode, StartEstimation
    assert (SetSlipMode.Request.OFF, SetSlipMode.Request.ROTATIONAL, SetSlipMode.Request.LINEAR,
            SetSlipMode.Request.HINGE, SetSlipMode.Request.HOLD) == (0, 1, 2, 3, 4)
    assert StartEstimation.Request.ONLINE == 4
    assert ContactProperties.SOURCE_GROUND_TRUTH == 3
    assert MotorCommand.BYPASS_SAFE_STATE == 7
    assert math.isfinite(SetSlipMode.Request().duration)
