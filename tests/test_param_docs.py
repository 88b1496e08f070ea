"""The parameter tables of docs/nodes.md are what the code declares (issue 19).

`tools/param_tables.py` generates each table from the nodes' parameter dataclasses; a table in
the document that differs (a parameter added, removed, renamed, or a default, unit, range or
description changed in code) fails here with the first differing line. Every parameter class
a node binds must have a table, so a new node cannot go undocumented.
"""
from __future__ import annotations

import ast
import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[1]
NODES_MD = ROOT / 'docs' / 'nodes.md'


def _tool() -> ModuleType:
    spec = importlib.util.spec_from_file_location('param_tables',
                                                  ROOT / 'tools' / 'param_tables.py')
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault('param_tables', module)
    spec.loader.exec_module(module)
    return module


param_tables = _tool()


def test_nodes_md_tables_equal_the_generated_tables() -> None:
    problems = param_tables.differences(NODES_MD.read_text())
    assert not problems, (
        'docs/nodes.md is out of date; regenerate it with\n'
        '  tools/run_ros.sh .venv/bin/python tools/param_tables.py --write docs/nodes.md\n'
        + '\n'.join(problems))


def _bound_parameter_classes() -> set[str]:
    """Names of the classes nodes pass to ``ParameterBinding(self, <Class>, ...)``."""
    bound: set[str] = set()
    for path in sorted((ROOT / 'src').glob('*/*/**/*.py')):
        if '/test/' in str(path) or path.name == 'param_binding.py':
            continue
        tree = ast.parse(path.read_text(), filename=str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and getattr(node.func, 'id', None) == 'ParameterBinding' \
                    and len(node.args) >= 2 and isinstance(node.args[1], ast.Name):
                bound.add(node.args[1].id)
    return bound


def test_every_bound_parameter_class_has_a_table() -> None:
    bound = _bound_parameter_classes()
    assert {'GripperDriverParams', 'SlipControllerParams', 'SimParams'} <= bound  # scan works
    documented = {ref.partition(':')[2] for t in param_tables.TABLES for ref in t.classes}
    missing = bound - documented
    assert not missing, f'parameter classes bound by nodes but without a table in ' \
                        f'tools/param_tables.py and docs/nodes.md: {sorted(missing)}'


def test_every_table_lists_parameters() -> None:
    for table in param_tables.TABLES:
        rows = list(param_tables.rows(table))
        assert rows, f'{table.name}: no parameters'
        assert all(r.startswith('| `') and r.endswith(' |') for r in rows), table.name


def test_a_changed_default_is_caught() -> None:
    text = NODES_MD.read_text()
    changed = text.replace('| `force_control.kp` | `2.0` |', '| `force_control.kp` | `3.0` |', 1)
    assert changed != text, 'the probe row is not in docs/nodes.md'
    problems = param_tables.differences(changed)
    assert len(problems) == 1 and problems[0].startswith('gripper_driver:'), problems


def test_a_missing_parameter_row_and_a_missing_table_are_caught() -> None:
    text = NODES_MD.read_text()
    rows = [line for line in text.splitlines() if line.startswith('| `hold.margin` |')]
    assert len(rows) == 1
    problems = param_tables.differences(text.replace(rows[0] + '\n', '', 1))
    assert any(p.startswith('slip_controller:') for p in problems), problems
    start = text.index('<!-- param-table: cell_markers -->')
    end = text.index('<!-- /param-table -->', start) + len('<!-- /param-table -->')
    problems = param_tables.differences(text[:start] + text[end:])
    assert any('cell_markers: no' in p for p in problems), problems


def test_rewrite_restores_a_stale_document() -> None:
    stale = NODES_MD.read_text().replace('| `force_control.kp` | `2.0` |',
                                         '| `force_control.kp` | `3.0` |', 1)
    assert param_tables.differences(param_tables.rewrite(stale)) == []


@pytest.mark.parametrize('value, text', [(True, 'true'), (2.0, '2.0'), (1e-05, '1e-05'),
                                         (3, '3'), ('mean', "'mean'"), ((0.5, 1.0), '[0.5, 1.0]')])
def test_values_are_written_as_in_the_yaml_files(value: object, text: str) -> None:
    assert param_tables.format_value(value) == text
