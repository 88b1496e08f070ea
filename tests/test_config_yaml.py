"""Each node's YAML lists exactly the parameters it declares, with the declared defaults.

Graphs pass the shared ``slip_gripper_driver/config/cell.yaml`` (``frames.*``) next to a node's
own file, so ``frames.*`` may come from there instead. Launch files compile; every parameter
file a graph names is installed.
"""
from __future__ import annotations

import importlib
import math
import py_compile
from dataclasses import fields
from pathlib import Path
from typing import Any

import pytest
import yaml

from slip_cell_common.core.param_schema import iter_specs

SRC = Path(__file__).resolve().parents[1] / 'src'
CELL_YAML = SRC / 'slip_gripper_driver' / 'config' / 'cell.yaml'

#: (package, yaml file, node key, parameter dataclasses, groups that may come from cell.yaml)
NODES: list[tuple[str, str, str, tuple[str, ...]]] = [
    ('friction_models', 'sim_gripper.yaml', 'sim_gripper',
     ('friction_models.sim_gripper_node:SimNodeParams',
      'friction_models.core.sim_cell:SimParams')),
]
OPTIONAL_NODES: list[tuple[str, str, str, tuple[str, ...]]] = [
    # Registered here as their packages land; each entry is checked when its module imports.
    ('slip_gripper_driver', 'gripper_driver.yaml', 'gripper_driver',
     ('slip_gripper_driver.node_params:GripperDriverParams',)),
    ('slip_gripper_driver', 'netft_driver.yaml', 'netft_driver',
     ('slip_gripper_driver.node_params:NetFTDriverParams',)),
    ('slip_velocity_sensor', 'velocity_sensor_1.yaml', 'velocity_sensor_1',
     ('slip_velocity_sensor.core.params:VelocitySensorParams',)),
    ('slip_velocity_sensor', 'velocity_sensor_2.yaml', 'velocity_sensor_2',
     ('slip_velocity_sensor.core.params:VelocitySensorParams',)),
    ('slip_control', 'contact_estimator.yaml', 'contact_estimator',
     ('slip_control.core.params:ContactEstimatorParams',)),
    ('slip_control', 'slip_controller.yaml', 'slip_controller',
     ('slip_control.core.params:SlipControllerParams',)),
    ('slip_control', 'experiment_runner.yaml', 'experiment_runner',
     ('slip_control.core.params:ExperimentRunnerParams',)),
    ('slip_bringup', 'cell_markers.yaml', 'cell_markers',
     ('slip_bringup.core.cell_markers:CellMarkersParams',)),
]


#: Parameters that legitimately differ from the declared defaults in a per-instance file.
INSTANCE_KEYS: dict[str, tuple[str, ...]] = {
    'velocity_sensor_2': ('finger', 'expected_name', 'frame_id', 'calibration.file'),
}


def _load_class(ref: str) -> type:
    module, _, name = ref.partition(':')
    return getattr(importlib.import_module(module), name)


def _flatten(prefix: str, value: Any, out: dict[str, Any]) -> None:
    if isinstance(value, dict):
        for k, v in value.items():
            _flatten(f'{prefix}{k}.', v, out)
    else:
        out[prefix[:-1]] = value


def _yaml_params(path: Path, key: str) -> dict[str, Any]:
    data = yaml.safe_load(path.read_text())
    assert key in data, f'{path.name}: top-level key must be the node name {key!r}'
    out: dict[str, Any] = {}
    _flatten('', data[key]['ros__parameters'], out)
    return out


def _same(a: Any, b: Any) -> bool:
    if isinstance(b, tuple):
        return isinstance(a, list) and len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(b, float):
        return isinstance(a, float) and (a == b or (math.isnan(a) and math.isnan(b)))
    return type(a) is type(b) and a == b


def _check(package: str, file: str, key: str, classes: tuple[str, ...],
           src: Path = SRC) -> None:
    path = src / package / 'config' / file
    assert path.is_file(), f'{package}/config/{file} is missing'
    declared = {s.name: s for ref in classes for s in iter_specs(_load_class(ref))}
    listed = _yaml_params(path, key)
    shared = _yaml_params(CELL_YAML, '/**')
    frames_from_cell = {n for n in declared if n.startswith('frames.') and n in shared}
    missing = set(declared) - set(listed) - frames_from_cell
    unknown = set(listed) - set(declared)
    assert not missing, f'{file}: parameters not listed: {sorted(missing)}'
    assert not unknown, f'{file}: parameters the node does not declare: {sorted(unknown)}'
    for name, value in listed.items():
        spec = declared[name]
        if spec.required or name in INSTANCE_KEYS.get(key, ()):
            continue  # site or instance values (a port, an address, which finger)
        assert _same(value, spec.default), \
            f'{file}: {name} = {value!r} differs from the declared default {spec.default!r}'


@pytest.mark.parametrize('entry', NODES, ids=lambda e: e[2])
def test_node_yaml_matches_declared_parameters(entry: tuple) -> None:
    _check(*entry)


@pytest.mark.parametrize('entry', OPTIONAL_NODES, ids=lambda e: e[2])
def test_other_node_yaml_matches_declared_parameters(entry: tuple) -> None:
    package, file, key, classes = entry
    try:
        for ref in classes:
            _load_class(ref)
    except (ImportError, AttributeError):
        pytest.skip(f'{classes} not available yet')
    _check(package, file, key, classes)


def test_cell_yaml_frames_match_frame_params() -> None:
    from slip_cell_common.core.frames import FrameParams
    shared = _yaml_params(CELL_YAML, '/**')
    for f in fields(FrameParams):
        assert _same(shared[f'frames.{f.name}'], getattr(FrameParams(), f.name)), f.name


def test_checker_catches_a_wrong_default(tmp_path: Path) -> None:
    bad = tmp_path / 'friction_models' / 'config'
    bad.mkdir(parents=True)
    text = (SRC / 'friction_models' / 'config' / 'sim_gripper.yaml').read_text()
    (bad / 'sim_gripper.yaml').write_text(text.replace('realtime_factor: 1.0',
                                                       'realtime_factor: 2.0'))
    with pytest.raises(AssertionError, match='realtime_factor'):
        _check(*NODES[0], src=tmp_path)


def test_checker_catches_a_core_field_that_never_reaches_the_yaml(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A field added to a core class nested (flattened) in a node class is a node parameter."""
    import dataclasses
    from dataclasses import dataclass, field

    from slip_gripper_driver.core.netft_params import FtStreamParams
    from slip_gripper_driver.node_params import NetFTDriverParams

    @dataclass(frozen=True)
    class Extended(FtStreamParams):
        added_probe_field: float = field(default=1.0, metadata={'range': (0.0, 2.0)})

    stream = next(f for f in dataclasses.fields(NetFTDriverParams) if f.name == 'stream')
    monkeypatch.setattr(stream, 'default_factory', Extended)
    entry = next(e for e in OPTIONAL_NODES if e[2] == 'netft_driver')
    with pytest.raises(AssertionError, match=r"parameters not listed: \['added_probe_field'\]"):
        _check(*entry)


@pytest.mark.parametrize('launch', sorted(SRC.glob('*/launch/*.launch.py')),
                         ids=lambda p: p.name)
def test_launch_files_compile(launch: Path, tmp_path: Path) -> None:
    py_compile.compile(str(launch), cfile=str(tmp_path / 'launch.pyc'), doraise=True)


@pytest.mark.parametrize('graph', sorted((SRC / 'slip_bringup' / 'config').glob('*.graph.yaml')),
                         ids=lambda p: p.name)
def test_graph_files_name_existing_parameter_files(graph: Path) -> None:
    data = yaml.safe_load(graph.read_text())
    for node in data['nodes']:
        for ref in node.get('params', []):
            package, _, rel = ref.partition('/')
            assert (SRC / package / rel).is_file(), f'{graph.name}: {node["name"]} needs {ref}'


@pytest.mark.ros
@pytest.mark.parametrize('entry', NODES + OPTIONAL_NODES, ids=lambda e: e[2])
def test_node_yaml_loads_into_typed_parameters(entry: tuple, ros_context: object) -> None:
    """rclpy reads the file into the statically typed parameters unchanged (``2.0``, not ``2``).

    A value rclpy refuses for the declared type or range would leave the default declared, and
    an integer written for a double would be converted: both show up as a difference here.
    """
    from rclpy.node import Node

    from slip_cell_common.param_binding import ParameterBinding
    package, file, key, classes = entry
    try:
        loaded = [_load_class(ref) for ref in classes]
    except (ImportError, AttributeError):
        pytest.skip(f'{classes} not available yet')
    path = SRC / package / 'config' / file
    node = Node(key, context=ros_context, use_global_arguments=False, cli_args=[
        '--ros-args', '--params-file', str(CELL_YAML), '--params-file', str(path)])
    try:
        for cls in loaded:
            ParameterBinding(node, cls)
        for name, value in _yaml_params(path, key).items():
            declared = node.get_parameter(name).value
            assert _same(value, tuple(declared) if isinstance(declared, list) else declared), \
                f'{file}: {name} = {value!r} was declared as {declared!r}'
    finally:
        node.destroy_node()
