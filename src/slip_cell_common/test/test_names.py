"""The one vocabulary of topic, service, action and frame names (issue 14)."""
from __future__ import annotations

import ast
import re
from pathlib import Path

from slip_cell_common.core import names

#: ROS 2 topic/service name tokens: letters, digits, underscores; no leading digit per token.
_RELATIVE = re.compile(r'[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*')


def _constants() -> dict[str, str]:
    return {k: v for k, v in vars(names).items() if k.isupper() and isinstance(v, str)}


def _per_finger() -> list[str]:
    fns = (names.ft_wrench, names.ft_raw, names.ft_bias_srv, names.slip_twist, names.slip_state,
           names.slip_chips, names.slip_set_chip_mode_srv, names.slip_reset_pose_srv)
    return [f(k) for f in fns for k in (1, 2)]


def test_names_are_valid_and_relative_unless_ros_wide() -> None:
    ros_wide = {'DIAGNOSTICS', 'CLOCK', 'TF', 'TF_STATIC'}
    for key, value in _constants().items():
        bare = value[1:] if key in ros_wide else value
        assert (key in ros_wide) == value.startswith('/'), key
        assert _RELATIVE.fullmatch(bare), f'{key} = {value!r}'
    for value in _per_finger():
        assert _RELATIVE.fullmatch(value), value


def test_names_are_unique() -> None:
    values = [*_constants().values(), *_per_finger(), names.slip_base(1), names.slip_base(2)]
    assert len(values) == len(set(values))


def test_per_finger_names_and_frames() -> None:
    assert names.ft_wrench(2) == 'finger_2/ft/wrench'
    assert names.slip_twist(1) == 'finger_1/slip/twist'
    assert names.slip_chips(1).startswith(names.slip_base(1) + '/')
    assert names.ft_sensor_frame(2) == 'ft_sensor_2'
    assert names.vel_sensor_frame(1) == 'vel_sensor_1'
    assert names.finger_joint(1) == 'finger_1_joint'
    assert names.absolute(names.GRIPPER_STATUS) == '/gripper/status'
    assert names.absolute(names.DIAGNOSTICS) == '/diagnostics'


# --- the vocabulary is used: no module spells a name itself ----------------------------------
SRC = Path(__file__).resolve().parents[2]
NAMES_FILE = SRC / 'slip_cell_common' / 'slip_cell_common' / 'core' / 'names.py'
FINGER_NAME_FUNCTIONS = (names.ft_wrench, names.ft_raw, names.ft_bias_srv, names.slip_twist,
                         names.slip_state, names.slip_chips, names.slip_set_chip_mode_srv,
                         names.slip_reset_pose_srv, names.ft_sensor_frame,
                         names.vel_sensor_frame, names.finger_joint)


def _spelled_names() -> tuple[set[str], set[str]]:
    """Exact names (relative and absolute) and f-string templates (``finger_{}/ft/wrench``)."""
    exact = {v for v in _constants().values() if '/' in v or '_' in v}
    templates: set[str] = set()
    for fn in FINGER_NAME_FUNCTIONS:
        exact |= {fn(1), fn(2)}
        templates.add(fn(987654).replace('987654', '{}'))
    exact |= {names.absolute(v) for v in exact if '/' in v}
    templates |= {names.absolute(t) for t in templates if '/' in t}
    return exact, templates


def spelled_out_names(path: Path) -> list[str]:
    """``line: literal`` for each string constant or f-string of ``path`` that is a name."""
    exact, templates = _spelled_names()
    tree = ast.parse(path.read_text(), filename=str(path))
    docstrings = {id(n.body[0].value) for n in ast.walk(tree)
                  if isinstance(n, (ast.Module, ast.ClassDef, ast.FunctionDef,
                                    ast.AsyncFunctionDef))
                  and n.body and isinstance(n.body[0], ast.Expr)}
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            if id(node) not in docstrings and node.value in exact:
                found.append(f'{node.lineno}: {node.value!r}')
        elif isinstance(node, ast.JoinedStr):
            text = ''.join(str(v.value) if isinstance(v, ast.Constant) else '{}'
                           for v in node.values)
            if text in templates or text in exact:
                found.append(f"{node.lineno}: f'{text}'")
    return found


def test_package_modules_take_names_from_the_vocabulary() -> None:
    modules = [p for p in sorted(SRC.glob('*/*/**/*.py'))
               if '/test/' not in p.as_posix() and p != NAMES_FILE]
    assert len(modules) > 50
    spelled = {str(p.relative_to(SRC)): found for p in modules if (found := spelled_out_names(p))}
    assert not spelled, f'use slip_cell_common.core.names instead of literals: {spelled}'


def test_the_check_catches_a_spelled_out_name(tmp_path: Path) -> None:
    probe = tmp_path / 'probe.py'
    probe.write_text('"""Publishes ``gripper/status``."""\n'
                     "a = 'gripper/status'\nb = f'finger_{k}/ft/wrench'\nc = '/sim/state'\n"
                     "d = f'vel_sensor_{k}'\ne = 'status'\n")
    assert sorted(f.split(':')[0] for f in spelled_out_names(probe)) == ['2', '3', '4', '5']
