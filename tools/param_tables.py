#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Print the parameter tables of every node as Markdown, from the parameter dataclasses.

The tables in ``docs/nodes.md`` are this script's output, between marker comments::

    <!-- param-table: gripper_driver -->
    | Parameter | Default | Unit | Allowed | Description |
    ...
    <!-- /param-table -->

``tests/test_param_docs.py`` fails when a table in ``docs/nodes.md`` differs from what this
script prints, so a parameter added, removed or changed in code must reach the document.

Usage (inside the workspace environment, e.g. through ``tools/run_ros.sh``)::

    tools/param_tables.py                         # every table, with its markers
    tools/param_tables.py --node slip_controller  # one table
    tools/param_tables.py --check docs/nodes.md   # exit 1 and name the tables that differ
    tools/param_tables.py --write docs/nodes.md   # rewrite the tables in place
"""
from __future__ import annotations

import argparse
import importlib
import math
import re
import sys
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

#: Marker comments around a generated table in a Markdown file.
BEGIN = '<!-- param-table: {name} -->'
END = '<!-- /param-table -->'
_REGION = re.compile(r'<!-- param-table: (?P<name>[\w.]+) -->\n(?P<body>.*?)<!-- /param-table -->',
                     re.S)


@dataclass(frozen=True)
class TableSpec:
    """One generated table: a name and the parameter classes (``module:Class``) it lists.

    ``prefix`` is prepended to every parameter name of the classes (a class bound under a
    prefix, like the shared ``frames.*``); ``exclude`` drops names starting with any of its
    entries (groups documented in another table).
    """

    name: str
    classes: tuple[str, ...]
    prefix: str = ''
    exclude: tuple[str, ...] = ()


#: Every table of docs/nodes.md, in document order. `tests/test_param_docs.py` checks that each
#: parameter class a node binds (``ParameterBinding(self, Class)``) appears here.
TABLES: tuple[TableSpec, ...] = (
    TableSpec('frames', ('slip_cell_common.core.frames:FrameParams',), prefix='frames.'),
    TableSpec('gripper_driver', ('slip_gripper_driver.node_params:GripperDriverParams',)),
    TableSpec('netft_driver', ('slip_gripper_driver.node_params:NetFTDriverParams',)),
    TableSpec('velocity_sensor', ('slip_velocity_sensor.core.params:VelocitySensorParams',)),
    TableSpec('sim_gripper', ('friction_models.sim_gripper_node:SimNodeParams',)),
    TableSpec('sim_gripper.physics', ('friction_models.core.sim_cell:SimParams',),
              exclude=('frames.',)),
    TableSpec('contact_estimator', ('slip_control.core.params:ContactEstimatorParams',)),
    TableSpec('slip_controller', ('slip_control.core.params:SlipControllerParams',),
              exclude=('frames.',)),
    TableSpec('experiment_runner', ('slip_control.core.params:ExperimentRunnerParams',)),
    TableSpec('cell_markers', ('slip_bringup.core.cell_markers:CellMarkersParams',)),
    TableSpec('foxglove_live', ('slip_bringup.foxglove_live:FoxgloveLiveParams',)),
    TableSpec('bag_recorder', ('slip_bringup.bag_nodes:RecorderParams',)),
    TableSpec('bag_replay', ('slip_bringup.bag_nodes:ReplayParams',)),
)

HEADER = ('| Parameter | Default | Unit | Allowed | Description |\n'
          '|---|---|---|---|---|')


def load_class(ref: str) -> type:
    """``module:Class`` → the class."""
    module, _, name = ref.partition(':')
    return getattr(importlib.import_module(module), name)


def _number(v: float | int) -> str:
    if isinstance(v, float):
        if math.isinf(v):
            return '∞' if v > 0 else '−∞'
        text = repr(v)
        return text if ('.' in text or 'e' in text or 'n' in text) else text + '.0'
    return str(v)


def format_value(v: Any) -> str:
    """A default as it is written in the YAML files (``true``, ``2.0``, ``'mean'``, lists)."""
    if isinstance(v, bool):
        return 'true' if v else 'false'
    if isinstance(v, (int, float)):
        return _number(v)
    if isinstance(v, str):
        return repr(v)
    if isinstance(v, tuple):
        return '[' + ', '.join(format_value(x) for x in v) + ']'
    return str(v)


def _allowed(spec: Any) -> str:
    if spec.choices:
        return ', '.join(f'`{c}`' for c in spec.choices)
    if spec.low is not None or spec.high is not None:
        low = '−∞' if spec.low is None else _number(spec.low)
        high = '∞' if spec.high is None else _number(spec.high)
        return f'[{low}, {high}]'
    return ''


def _cell(text: str) -> str:
    """Text safe inside a Markdown table cell."""
    return text.replace('|', '\\|').replace('\n', ' ')


def rows(table: TableSpec) -> Iterable[str]:
    """Markdown rows of one table (no header)."""
    from slip_cell_common.core.param_schema import iter_specs
    for ref in table.classes:
        for spec in iter_specs(load_class(ref)):
            if any(spec.name.startswith(p) for p in table.exclude):
                continue
            notes = []
            if spec.required:
                notes.append('**required**')
            if spec.read_only:
                notes.append('read-only')
            description = spec.description + (f' ({", ".join(notes)})' if notes else '')
            unit = '' if spec.unit in ('', '-') else spec.unit
            yield (f'| `{table.prefix}{spec.name}` | `{format_value(spec.default)}` | '
                   f'{_cell(unit)} | {_cell(_allowed(spec))} | {_cell(description)} |')


def table_markdown(table: TableSpec) -> str:
    """The table of ``table``, header included, ending with a newline."""
    return HEADER + '\n' + '\n'.join(rows(table)) + '\n'


def region(table: TableSpec) -> str:
    """The table wrapped in its marker comments."""
    return BEGIN.format(name=table.name) + '\n' + table_markdown(table) + END


def regions_in(text: str) -> dict[str, str]:
    """``{table name: table text}`` of every marked region of a Markdown text."""
    found: dict[str, str] = {}
    for m in _REGION.finditer(text):
        if m.group('name') in found:
            raise ValueError(f'table {m.group("name")!r} appears twice')
        found[m.group('name')] = m.group('body')
    return found


def differences(text: str, tables: Iterable[TableSpec] = TABLES) -> list[str]:
    """Why the tables of a Markdown text differ from the generated ones (empty: they agree)."""
    tables = list(tables)
    found = regions_in(text)
    problems = []
    for table in tables:
        if table.name not in found:
            problems.append(f'{table.name}: no "{BEGIN.format(name=table.name)}" region')
        elif found[table.name] != table_markdown(table):
            have = found[table.name].splitlines()
            want = table_markdown(table).splitlines()
            first = next((i for i, (a, b) in enumerate(zip(have, want)) if a != b),
                         min(len(have), len(want)))
            problems.append(f'{table.name}: line {first + 1} of the table differs\n'
                            f'  document:  {have[first] if first < len(have) else "(missing)"}\n'
                            f'  generated: {want[first] if first < len(want) else "(missing)"}')
    known = {t.name for t in tables}
    problems += [f'{name}: region without a table definition in tools/param_tables.py'
                 for name in found if name not in known]
    return problems


def rewrite(text: str, tables: Iterable[TableSpec] = TABLES) -> str:
    """``text`` with every marked region replaced by the generated table."""
    by_name = {t.name: t for t in tables}

    def sub(m: re.Match[str]) -> str:
        table = by_name.get(m.group('name'))
        return region(table) if table is not None else m.group(0)
    return _REGION.sub(sub, text)


def main(argv: list[str] | None = None) -> int:
    """Console entry: print, check or rewrite the tables."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--node', choices=[t.name for t in TABLES],
                        help='print only this table (default: every table)')
    group = parser.add_mutually_exclusive_group()
    group.add_argument('--check', metavar='FILE',
                       help='compare the tables in FILE with the generated ones; '
                            'exit 1 if any differ')
    group.add_argument('--write', metavar='FILE', help='rewrite the tables in FILE in place')
    ns = parser.parse_args(argv)
    tables = [t for t in TABLES if ns.node in (None, t.name)]
    if ns.check:
        problems = differences(Path(ns.check).read_text(), tables)
        for problem in problems:
            print(f'{ns.check}: {problem}', file=sys.stderr)
        return 1 if problems else 0
    if ns.write:
        path = Path(ns.write)
        path.write_text(rewrite(path.read_text(), tables))
        return 0
    print('\n\n'.join(region(t) for t in tables))
    return 0


if __name__ == '__main__':
    sys.exit(main())
