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
