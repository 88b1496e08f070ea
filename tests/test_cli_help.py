"""The user command-line tools: help that explains every option and shows its default, and
one clear error line (exit code 2) for every bad argument.

Each tool runs in-process through its ``main(argv)``. The parsers are taken from the tools
themselves (every tool builds a `slip_cell_common.core.cli_args.Parser`), and each option's
help is rendered by the same formatter ``--help`` uses.
"""
from __future__ import annotations

import argparse
import importlib
from collections.abc import Callable, Iterator
from typing import Any

import pytest

from slip_cell_common.core.cli_args import Parser

TOOLS = {
    'slip_analyze': 'slip_bringup.analyze',
    'slip_evaluate': 'slip_bringup.evaluate_cli',
    'slip_bag': 'slip_bringup.bag_cli',
    'run_graph': 'slip_bringup.run_graph',
    'friction_models_cli': 'friction_models.cli',
    'calibration_fit': 'slip_velocity_sensor.calibration_fit',
    'force_tracking_test': 'slip_gripper_driver.force_tracking_test',
}


def _main(tool: str) -> Callable[[list[str]], Any]:
    return importlib.import_module(TOOLS[tool]).main


class _ParserCapturedError(Exception):
    pass


def _parser_of(tool: str, monkeypatch: pytest.MonkeyPatch) -> Parser:
    """The parser ``tool``'s main builds (stopped before it parses anything)."""
    seen: list[Parser] = []

    def capture(self: Parser, *args: Any, **kwargs: Any) -> Any:
        seen.append(self)
        raise _ParserCapturedError
    monkeypatch.setattr(Parser, 'parse_args', capture)
    with pytest.raises(_ParserCapturedError):
        _main(tool)([])
    monkeypatch.undo()
    return seen[0]


def _parsers(parser: argparse.ArgumentParser) -> Iterator[argparse.ArgumentParser]:
    yield parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                yield from _parsers(sub)


def _rendered(parser: argparse.ArgumentParser, action: argparse.Action) -> str:
    """What ``--help`` prints for ``action`` (its own formatter, one entry)."""
    formatter = parser._get_formatter()
    formatter.add_argument(action)
    return ' '.join(formatter.format_help().split())


def _has_default(action: argparse.Action) -> bool:
    flags = (argparse._StoreTrueAction, argparse._StoreFalseAction, argparse._HelpAction,
             argparse._CountAction, argparse._VersionAction)
    return (bool(action.option_strings) and not isinstance(action, flags)
            and action.default is not None and action.default is not argparse.SUPPRESS)


@pytest.mark.parametrize('tool', sorted(TOOLS))
def test_help_explains_every_option_and_shows_its_default(
        tool: str, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    root = _parser_of(tool, monkeypatch)
    assert isinstance(root, Parser) and root.prog == tool
    checked = 0
    for parser in _parsers(root):
        text = parser.format_help()
        assert '``' not in text and '::' not in text, f'{parser.prog}: reST markup in --help'
        description = (parser.description or '').strip()
        assert description and description[0] not in '`*#:.-', parser.prog
        for action in parser._actions:
            if isinstance(action, argparse._HelpAction):
                continue
            name = '/'.join(action.option_strings) or action.dest
            assert (action.help or '').strip(), f'{parser.prog} {name} has no help'
            assert not action.help.lstrip().startswith(('`', '*', '#', ':')), name
            if isinstance(action, argparse._SubParsersAction):
                for choice in action._choices_actions:
                    assert (choice.help or '').strip(), f'{parser.prog} {choice.dest}'
            rendered = _rendered(parser, action)
            if _has_default(action):
                assert 'default' in rendered, f'{parser.prog} {name}: no default in {rendered!r}'
                checked += 1
    assert checked >= 1 or tool in ('slip_analyze',)
    # --help itself prints and exits 0.
    with pytest.raises(SystemExit) as exc:
        _main(tool)(['--help'])
    assert exc.value.code == 0 and capsys.readouterr().out.startswith(f'usage: {tool}')


def test_physics_dt_help_agrees_with_the_simulator_default(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """``slip_evaluate --physics-dt`` says it matches the node: it must (SimParams and the
    node's YAML)."""
    from pathlib import Path

    import yaml

    from friction_models.core.sim_cell import SimParams
    parser = _parser_of('slip_evaluate', monkeypatch)
    action = next(a for a in parser._actions if '--physics-dt' in a.option_strings)
    config = Path(__file__).resolve().parents[1] / 'src/friction_models/config/sim_gripper.yaml'
    node = yaml.safe_load(config.read_text())['sim_gripper']['ros__parameters']['physics_dt']
    assert action.default == SimParams().physics_dt == node
    assert 'as the sim_gripper node' in _rendered(parser, action)


BAD: list[tuple[str, list[str], str]] = [
    ('friction_models_cli', ['stick-slip', '--dt', '-1'], "--dt: must be > 0, got '-1'"),
    ('friction_models_cli', ['stick-slip', '--dt', 'nan'], 'must be a finite number'),
    ('friction_models_cli', ['stick-slip', '--mass', 'heavy'], "expected a number, got 'heavy'"),
    ('friction_models_cli', ['stick-slip', '--duration', '0'], '--duration: must be > 0'),
    ('friction_models_cli', ['stick-slip', '--dt', '0.5', '--duration', '0.1'],
     'longer than --duration'),
    ('friction_models_cli', ['stick-slip', '--dt', '1e-12'], 'steps'),
    ('friction_models_cli', ['stick-slip', '--mu-s', '0.5', '--mu-c', '1.0'], 'mu_s'),
    ('friction_models_cli', ['stick-slip', '--sigma1', '-2'], '--sigma1: must be >= 0'),
    ('friction_models_cli', ['limit-surface', '--n-ls', '0'], '--n-ls: must be an integer in'),
    ('friction_models_cli', ['surfaces', '--n', '2'], '--n: must be an integer in [3, 201]'),
    ('friction_models_cli', ['compare', '--dt', 'inf'], 'must be a finite number'),
    ('friction_models_cli', ['compare', '--dt', '1'], 'must be in [1e-06, 0.05]'),
    ('friction_models_cli', ['compare', '--surface', 'hexagon'], 'invalid choice'),
    ('friction_models_cli', [], 'required: COMMAND'),
    ('slip_analyze', [], 'required: bag'),
    ('slip_analyze', ['bags/linear_slip', '--bogus'], 'unrecognized arguments: --bogus'),
    ('slip_bag', ['replay', 'bags/linear_slip', '--rate', '-1'], '--rate: must be >= 0'),
    ('slip_bag', ['replay', 'bags/linear_slip', '--start-delay', 'nan'], 'finite'),
    ('slip_bag', ['export', 'bags/linear_slip'], 'required: --out'),
    ('slip_bag', ['play', 'bags/linear_slip'], "invalid choice: 'play'"),
    ('run_graph', ['--duration', '-1'], '--duration: must be >= 0'),
    ('run_graph', ['--stop-timeout', '0'], '--stop-timeout: must be > 0'),
    ('run_graph', ['--sim', '--hardware'], 'not allowed with argument --sim'),
    ('calibration_fit', ['fit', 'recordings', '--out-dir', 'out', '--distance', '0'],
     '--distance: must be > 0'),
    ('calibration_fit', ['fit', 'recordings', '--out-dir', 'out', '--a-factor', 'nan'],
     'finite'),
    ('calibration_fit', ['synth', 'out', '--seed', '-1'], '--seed: must be an integer >= 0'),
    ('calibration_fit', ['fit', 'recordings'], 'required: --out-dir'),
    ('force_tracking_test', ['run', '--duration', '-1'], '--duration: must be >= 0'),
    ('force_tracking_test', ['run', '--wait', '0'], '--wait: must be > 0'),
    ('force_tracking_test', ['analyze', 'bag', '--t0', 'inf'], 'finite'),
    ('slip_evaluate', ['--physics-dt', '-1'], "--physics-dt: must be > 0, got '-1'"),
    ('slip_evaluate', ['--physics-dt', 'nan'], 'finite'),
    ('slip_evaluate', ['--seed', '-3'], '--seed: must be an integer >= 0'),
    ('slip_evaluate', ['--population', '0'], '--population: must be an integer >= 1'),
    ('slip_evaluate', ['--population', '2', '--workers', '-1'], '--workers'),
    ('slip_evaluate', ['--velocity-model', 'perfect'], 'invalid choice'),
    ('slip_evaluate', ['--preset', ','], '--preset needs at least one name'),
    ('slip_evaluate', ['--object', '11-42'], 'SEED:INDEX'),
]


@pytest.mark.parametrize(('tool', 'argv', 'expected'), BAD,
                         ids=[f'{t}:{" ".join(a) or "(none)"}' for t, a, _ in BAD])
def test_bad_argument_gives_one_error_line_and_exit_code_2(
        tool: str, argv: list[str], expected: str, capsys: pytest.CaptureFixture[str]) -> None:
    try:
        code = _main(tool)(argv)
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2, (code, err)
    assert len(lines) == 1, f'{tool} {argv}: {len(lines)} lines:\n{err}'
    assert lines[0].startswith(f'{tool}') and ': error: ' in lines[0], lines[0]
    assert expected in lines[0], lines[0]
    assert 'Traceback' not in err and 'numpy' not in err.lower() and not out.strip()
