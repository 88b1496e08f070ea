# SPDX-License-Identifier: Apache-2.0
"""The core uses only the libraries docs/DEVELOPING.md allows, and never prints."""
from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

CORE = Path(__file__).resolve().parents[1] / 'friction_models' / 'core'
THIRD_PARTY = {'numpy', 'scipy', 'yaml', 'filterpy'}
# Project packages whose cores a core may import.
PROJECT = {'slip_cell_common', 'slip_gripper_driver', 'slip_velocity_sensor', 'friction_models'}


def imported_modules(tree: ast.AST) -> set[str]:
    names = {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    names |= {n.module for n in ast.walk(tree)
              if isinstance(n, ast.ImportFrom) and n.module and n.level == 0}
    return names


def disallowed(modules: set[str]) -> set[str]:
    bad = set()
    for name in modules:
        root = name.split('.')[0]
        if root in sys.stdlib_module_names or root in THIRD_PARTY:
            continue
        if root in PROJECT and name.split('.')[1:2] == ['core']:
            continue
        bad.add(name)
    return bad


@pytest.mark.parametrize('path', sorted(CORE.glob('*.py')), ids=lambda p: p.name)
def test_core_imports_and_no_print(path: Path) -> None:
    tree = ast.parse(path.read_text())
    assert not disallowed(imported_modules(tree)), f'{path.name} imports outside the core rules'
    assert not any(isinstance(n, ast.Call) and getattr(n.func, 'id', '') == 'print'
                   for n in ast.walk(tree)), f'{path.name} prints'


def test_checker_rejects_ros_and_node_modules() -> None:
    tree = ast.parse('import numpy\nimport rclpy\nfrom slip_cell_common import x\n'
                     'from slip_cell_common.core.frames import y\n')
    assert disallowed(imported_modules(tree)) == {'rclpy', 'slip_cell_common'}
