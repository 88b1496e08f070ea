# SPDX-License-Identifier: Apache-2.0
"""Port-to-name matching, the host-wide name claim, and the node parameter set."""
from __future__ import annotations

import ast
import multiprocessing
from pathlib import Path

import pytest

from slip_cell_common.core.param_schema import ParameterError, flatten, from_flat, specs
from slip_velocity_sensor.core.identity import (DuplicateSensorNameError, MissingSensorError,
                                                NameClaim, assign_ports)
from slip_velocity_sensor.core.params import VelocitySensorParams

CORE = Path(__file__).resolve().parents[1] / 'slip_velocity_sensor' / 'core'


def test_assign_ports_maps_names_and_finds_duplicates_and_gaps() -> None:
    assert assign_ports({'/dev/a': 'sensor_2', '/dev/b': 'sensor_1', '/dev/c': None},
                        ('sensor_1', 'sensor_2')) == {'sensor_1': '/dev/b', 'sensor_2': '/dev/a'}
    with pytest.raises(DuplicateSensorNameError) as err:
        assign_ports({'/dev/a': 'sensor_1', '/dev/b': 'sensor_1'})
    assert err.value.ports == ('/dev/a', '/dev/b') and err.value.name == 'sensor_1'
    with pytest.raises(MissingSensorError, match="sensor_2.*'/dev/c'"):
        assign_ports({'/dev/a': 'sensor_1', '/dev/c': None}, ('sensor_1', 'sensor_2'))


def _claim_in_child(lock_dir: str, queue: multiprocessing.Queue) -> None:
    try:
        NameClaim('sensor_1', '/dev/ttyUSB1', lock_dir).acquire()
    except DuplicateSensorNameError as exc:
        queue.put(str(exc))
    else:
        queue.put('claimed')


def test_name_claim_is_exclusive_across_processes(tmp_path: Path) -> None:
    claim = NameClaim('sensor_1', '/dev/ttyUSB0', tmp_path)
    claim.acquire()
    assert claim.held
    ctx = multiprocessing.get_context('spawn')
    queue: multiprocessing.Queue = ctx.Queue()
    child = ctx.Process(target=_claim_in_child, args=(str(tmp_path), queue))
    child.start()
    message = queue.get(timeout=20.0)
    child.join(10.0)
    assert '/dev/ttyUSB0' in message and '/dev/ttyUSB1' in message
    claim.release()
    assert not claim.held
    other = NameClaim('sensor_2', '/dev/ttyUSB1', tmp_path)
    with other:
        assert other.held        # different names never conflict


def test_node_parameters_flatten_with_the_spec_names() -> None:
    names = {s.name for s in specs(VelocitySensorParams)}
    for expected in ('autostart', 'port', 'baudrate', 'finger', 'expected_name', 'frame_id',
                     'handshake.timeout', 'handshake.retries', 'command_spacing', 'radius',
                     'calibration.file', 'calibration.speed_term', 'calibration.chip_1.x.a',
                     'calibration.chip_3.y.b', 'stale_after', 'expected_rate', 'rate_tolerance',
                     'integrate_pose'):
        assert expected in names
    params = from_flat(VelocitySensorParams, {'port': '/dev/pts/3', 'handshake.retries': 5,
                                              'calibration.chip_2.y.a': 0.29})
    assert params.handshake.retries == 5 and params.calibration.chip_2.y.a == 0.29
    assert flatten(params)['calibration.speed_term'] == 'zero'
    session = params.session
    assert session.stale_after == 0.05 and session.expected_rate == 146.0


@pytest.mark.parametrize('flat, message', [
    ({}, 'port is required'),
    ({'port': 'x', 'calibration.speed_term': 'linear'}, 'speed_term'),
    ({'port': 'x', 'command_spacing': 0.001}, 'command_spacing'),
    ({'port': 'x', 'handshake.timeout': float('nan')}, 'not finite'),
    ({'port': 'x', 'expected_name': 'sensor 1'}, 'expected_name'),
])
def test_node_parameter_validation(flat: dict, message: str) -> None:
    with pytest.raises(ParameterError, match=message):
        from_flat(VelocitySensorParams, flat)


def test_only_transport_code_may_touch_pyserial_and_no_core_prints() -> None:
    """House rule: pyserial only in transport modules; no print() in library code."""
    for path in sorted(CORE.glob('*.py')):
        tree = ast.parse(path.read_text())
        imported = {a.name.split('.')[0] for n in ast.walk(tree) if isinstance(n, ast.Import)
                    for a in n.names}
        imported |= {n.module.split('.')[0] for n in ast.walk(tree)
                     if isinstance(n, ast.ImportFrom) and n.module}
        assert 'serial' not in imported, path.name
        assert 'matplotlib' not in imported, path.name
        calls = {n.func.id for n in ast.walk(tree)
                 if isinstance(n, ast.Call) and isinstance(n.func, ast.Name)}
        assert 'print' not in calls, path.name


def test_frame_id_must_match_the_finger_and_calibration_file_placeholders() -> None:
    params = from_flat(VelocitySensorParams, {'port': 'x', 'finger': 2,
                                              'expected_name': 'sensor_2',
                                              'frame_id': 'vel_sensor_2',
                                              'frames.tf_prefix': 'cell_a/'})
    assert params.resolved_frame_id == 'cell_a/vel_sensor_2'
    assert params.calibration_file == 'config/calibration_sensor_2.yaml'
    with pytest.raises(ParameterError, match="frame_id 'vel_sensor_1' names finger 1"):
        from_flat(VelocitySensorParams, {'port': 'x', 'finger': 2})
    custom = from_flat(VelocitySensorParams, {'port': 'x', 'finger': 2, 'frame_id': 'pad_left',
                                              'calibration.file': '/cal/{finger}.yaml'})
    assert custom.resolved_frame_id == 'pad_left' and custom.calibration_file == '/cal/2.yaml'
    with pytest.raises(ParameterError, match='initial_delay'):
        from_flat(VelocitySensorParams, {'port': 'x', 'reconnect.initial_delay': 2.0,
                                         'reconnect.max_delay': 1.0})
