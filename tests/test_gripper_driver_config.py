# SPDX-License-Identifier: Apache-2.0
"""The driver YAML files list exactly their dataclass fields with the right types; the shared
frames come from cell.yaml; launch files compile; the console scripts are installed."""
from __future__ import annotations

import py_compile
from pathlib import Path
from typing import Any

import pytest
import yaml

from slip_cell_common.core.frames import FrameParams
from slip_cell_common.core.param_schema import flatten, from_flat, specs
from slip_gripper_driver.node_params import GripperDriverParams, NetFTDriverParams

PKG = Path(__file__).resolve().parents[1] / 'src' / 'slip_gripper_driver'
SCRIPTS = ('gripper_driver', 'netft_driver', 'gripper_firmware_emulator', 'netft_emulator',
           'force_tracking_test')


def _flat(tree: dict[str, Any], prefix: str = '') -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in tree.items():
        if isinstance(value, dict):
            out.update(_flat(value, f'{prefix}{key}.'))
        else:
            out[prefix + key] = value
    return out


def _load(name: str, node: str) -> dict[str, Any]:
    doc = yaml.safe_load((PKG / 'config' / name).read_text())
    return _flat(doc[node]['ros__parameters'])


@pytest.mark.parametrize('name,node,cls', [
    ('gripper_driver.yaml', 'gripper_driver', GripperDriverParams),
    ('netft_driver.yaml', 'netft_driver', NetFTDriverParams)])
def test_yaml_lists_exactly_the_dataclass_fields_with_their_types(name: str, node: str,
                                                                  cls: type) -> None:
    values = _load(name, node)
    fields = {s.name: s for s in specs(cls)}
    assert set(values) == set(fields)
    for key, spec in fields.items():
        value = values[key]
        assert type(value) is spec.kind, f'{name}: {key} = {value!r} is not {spec.kind.__name__}'
    if cls is NetFTDriverParams:
        from_flat(cls, values)  # the shipped file is valid as is
        assert values['address'] == '192.168.56.6'


def test_gripper_driver_yaml_defaults_match_the_spec() -> None:
    values = _load('gripper_driver.yaml', 'gripper_driver')
    assert values['serial.port'] == ''  # required: configure fails until set
    assert values['ft.finger_1.address'] == '192.168.56.6'
    assert values['ft.finger_2.address'] == '192.168.56.5'
    assert values['ft.port'] == 49152 and values['actuator.safe_voltage'] == 0.0
    defaults = flatten(GripperDriverParams())
    assert values == defaults  # the YAML documents the defaults
    with pytest.raises(ValueError, match='serial.port is required'):
        from_flat(GripperDriverParams, values)


def test_frames_come_from_the_shared_cell_yaml() -> None:
    doc = yaml.safe_load((PKG / 'config' / 'cell.yaml').read_text())
    frames = _flat(doc['/**']['ros__parameters'])
    assert {k.removeprefix('frames.') for k in frames} == {s.name for s in specs(FrameParams)}
    assert not any(k.startswith('frames.') for k in _load('gripper_driver.yaml',
                                                          'gripper_driver'))


def test_launch_files_compile(tmp_path: Path) -> None:
    files = sorted((PKG / 'launch').glob('*.launch.py'))
    assert {f.name for f in files} >= {'gripper_driver.launch.py', 'netft_driver.launch.py'}
    for f in files:
        py_compile.compile(str(f), cfile=str(tmp_path / (f.name + 'c')), doraise=True)


def test_console_scripts_are_installed() -> None:
    from slip_cell_common.testing import workspace_root
    lib = workspace_root() / 'install' / 'slip_gripper_driver' / 'lib' / 'slip_gripper_driver'
    missing = [s for s in SCRIPTS if not (lib / s).is_file()]
    assert not missing, f'not installed (run make setup): {missing}'
