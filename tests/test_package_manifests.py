"""Every package.xml declares exactly what its Python package imports (issue 14).

The imports of each package's installed modules (not its tests) are read with `ast`; each
top-level module maps to one rosdep key. Declared run-time dependencies (``exec_depend`` and
``depend``) must equal that set: an undeclared import breaks an install from the manifest, an
unused declaration drags in what the package never needs.
"""
from __future__ import annotations

import ast
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / 'src'
PYTHON_PACKAGES = sorted(p.parent for p in SRC.glob('*/setup.py'))

#: Top-level Python module -> rosdep key, for modules that are not ROS packages themselves.
ROSDEP_KEYS = {
    'numpy': 'python3-numpy', 'scipy': 'python3-scipy', 'yaml': 'python3-yaml',
    'serial': 'python3-serial', 'rosbags': 'python3-rosbags', 'matplotlib': 'python3-matplotlib',
    'filterpy': 'python3-filterpy', 'dask': 'python3-dask', 'distributed': 'python3-distributed',
    'foxglove': 'python3-foxglove-sdk', 'mypy': 'python3-mypy',
}
OPTIONAL: dict[str, str] = {}


def _is_local(root: str, package_dir: Path) -> bool:
    return (package_dir / root).is_dir() or (package_dir / f'{root}.py').is_file()


def imported_roots(package_dir: Path) -> set[str]:
    """Top-level modules imported by the package's modules (tests and setup.py excluded)."""
    roots: set[str] = set()
    module_dir = package_dir / package_dir.name
    for path in module_dir.rglob('*.py'):
        tree = ast.parse(path.read_text(), filename=str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                roots |= {a.name.split('.')[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                roots.add(node.module.split('.')[0])
    stdlib = set(sys.stdlib_module_names) | {'__future__'}
    return {r for r in roots if r not in stdlib and r != package_dir.name
            and not _is_local(r, module_dir)}


def declared_run_depends(package_dir: Path) -> set[str]:
    """``exec_depend`` and ``depend`` entries of the package's manifest."""
    root = ET.parse(package_dir / 'package.xml').getroot()
    return {e.text.strip() for tag in ('exec_depend', 'depend') for e in root.iter(tag)
            if e.text}


def expected_depends(package_dir: Path) -> set[str]:
    return {ROSDEP_KEYS.get(r, r) for r in imported_roots(package_dir)}


def test_there_are_python_packages() -> None:
    names = {p.name for p in PYTHON_PACKAGES}
    assert {'slip_cell_common', 'slip_gripper_driver', 'slip_velocity_sensor',
            'friction_models', 'slip_control', 'slip_bringup'} <= names


@pytest.mark.parametrize('package_dir', PYTHON_PACKAGES, ids=lambda p: p.name)
def test_manifest_declares_exactly_the_imports(package_dir: Path) -> None:
    declared = declared_run_depends(package_dir)
    expected = expected_depends(package_dir)
    optional = set(OPTIONAL.values())
    missing = expected - declared - optional
    unused = declared - expected
    assert not missing, f'{package_dir.name}/package.xml lacks {sorted(missing)}'
    assert not unused, f'{package_dir.name}/package.xml declares unused {sorted(unused)}'


def test_checker_sees_an_undeclared_import(tmp_path: Path) -> None:
    pkg = tmp_path / 'probe_pkg'
    (pkg / 'probe_pkg').mkdir(parents=True)
    (pkg / 'probe_pkg' / 'a.py').write_text(
        'import numpy\nfrom rclpy.node import Node\nimport os\n')
    (pkg / 'package.xml').write_text(
        '<package format="3"><name>probe_pkg</name><exec_depend>rclpy</exec_depend></package>')
    assert expected_depends(pkg) - declared_run_depends(pkg) == {'python3-numpy'}
