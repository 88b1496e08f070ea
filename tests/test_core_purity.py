"""Core modules import no rclpy and no message packages (house style §1)."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / 'src'
CORE_MODULES = sorted(SRC.glob('*/*/core/**/*.py'))
BANNED = {'rclpy', 'slip_msgs', 'std_msgs', 'geometry_msgs', 'sensor_msgs', 'diagnostic_msgs',
          'std_srvs', 'builtin_interfaces', 'rosgraph_msgs', 'lifecycle_msgs', 'rcl_interfaces',
          'action_msgs'}


def _imported_roots(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    roots = {a.name.split('.')[0] for n in ast.walk(tree) if isinstance(n, ast.Import)
             for a in n.names}
    roots |= {n.module.split('.')[0] for n in ast.walk(tree)
              if isinstance(n, ast.ImportFrom) and n.module and n.level == 0}
    return roots


def test_there_are_core_modules() -> None:
    assert len(CORE_MODULES) >= 5


@pytest.mark.parametrize('path', CORE_MODULES, ids=lambda p: str(p.relative_to(SRC)))
def test_core_is_ros_free(path: Path) -> None:
    bad = _imported_roots(path) & BANNED
    assert not bad, f'{path.relative_to(SRC)} imports {sorted(bad)}'


def test_checker_catches_a_ros_import(tmp_path: Path) -> None:
    probe = tmp_path / 'probe.py'
    probe.write_text('import numpy\nfrom rclpy.node import Node\n')
    assert _imported_roots(probe) & BANNED == {'rclpy'}


# --- layer table (issue 14) --------------------------------------------------------------------

#: Which project packages each package may import. The direction is
#: slip_msgs ← slip_cell_common ← {driver, velocity sensor, control};
#: {driver, velocity sensor} ← friction_models (the simulated cell runs the drivers' host code);
#: friction_models ← slip_control (the model-based slip laws run the friction models online);
#: bring-up (graph runner, demo, bag tools, evaluation) on top of everything.
PROJECT_PACKAGES = {'slip_msgs', 'slip_cell_common', 'slip_gripper_driver',
                    'slip_velocity_sensor', 'slip_control', 'friction_models', 'slip_bringup'}
LAYERS = {
    'slip_cell_common': {'slip_msgs'},
    'slip_gripper_driver': {'slip_msgs', 'slip_cell_common'},
    'slip_velocity_sensor': {'slip_msgs', 'slip_cell_common'},
    'slip_control': {'slip_msgs', 'slip_cell_common', 'friction_models'},
    'friction_models': {'slip_msgs', 'slip_cell_common', 'slip_gripper_driver',
                        'slip_velocity_sensor'},
    'slip_bringup': PROJECT_PACKAGES - {'slip_bringup'},
}


def layer_violations(package: str, module_dir: Path) -> dict[str, set[str]]:
    """Modules of ``package`` that import a project package above or beside its layer."""
    allowed = LAYERS[package] | {package}
    bad: dict[str, set[str]] = {}
    for path in sorted(module_dir.rglob('*.py')):
        wrong = (_imported_roots(path) & PROJECT_PACKAGES) - allowed
        if wrong:
            bad[str(path.relative_to(module_dir.parent))] = wrong
    return bad


def test_layer_table_names_every_python_package() -> None:
    assert set(LAYERS) == {p.parent.name for p in SRC.glob('*/setup.py')}


@pytest.mark.parametrize('package', sorted(LAYERS))
def test_packages_import_only_lower_layers(package: str) -> None:
    bad = layer_violations(package, SRC / package / package)
    assert not bad, f'{package} imports outside its layer: {bad}'


def test_layer_check_catches_an_upward_import(tmp_path: Path) -> None:
    module_dir = tmp_path / 'slip_control'
    module_dir.mkdir()
    (module_dir / 'x.py').write_text('from slip_bringup.core.evaluation import scene\n')
    assert layer_violations('slip_control', module_dir) == {'slip_control/x.py': {'slip_bringup'}}


#: The friction_models modules slip_control may use: the models, never the simulated cell.
CONTROL_MAY_USE_FROM_FRICTION_MODELS = {
    'friction_models.core.limit_surface', 'friction_models.core.params',
    'friction_models.core.reduced', 'friction_models.core.surfaces',
    'friction_models.core.planar', 'friction_models.core.integrators'}


def test_control_uses_the_friction_models_not_the_simulator() -> None:
    used: set[str] = set()
    for path in (SRC / 'slip_control' / 'slip_control').rglob('*.py'):
        tree = ast.parse(path.read_text(), filename=str(path))
        used |= {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)
                 and n.module and n.module.startswith('friction_models')}
        used |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names
                 if a.name.startswith('friction_models')}
    assert used, 'the model-based slip laws use friction_models.core'
    assert used <= CONTROL_MAY_USE_FROM_FRICTION_MODELS, sorted(
        used - CONTROL_MAY_USE_FROM_FRICTION_MODELS)
