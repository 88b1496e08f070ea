"""After ``source install/setup.bash`` in a fresh shell, the user tools are commands on PATH.

slip_bringup installs small wrappers into ``<prefix>/bin`` (colcon prepends that directory to
PATH); each runs the installed console script found on AMENT_PREFIX_PATH, as ``ros2 run``
would. The shell starts from ``env -i`` (nothing inherited but HOME, a minimal PATH and the
private ROS domain), like tests/test_fresh_shell.py.
"""
from __future__ import annotations

import os
import shlex
import subprocess
from pathlib import Path

import pytest

pytestmark = pytest.mark.ros

ROOT = Path(__file__).resolve().parents[1]
WRAPPERS = ROOT / 'src' / 'slip_bringup' / 'bin'
TOOLS = ('slip_cli', 'slip_bag', 'run_graph', 'slip_analyze', 'slip_evaluate', 'slip_demo',
         'foxglove_live', 'friction_models_cli', 'gripper_firmware_emulator', 'netft_emulator',
         'velocity_sensor_emulator', 'force_tracking_test', 'calibration_recorder',
         'calibration_fit')


def _fresh_shell(script: str, tmp_path: Path) -> subprocess.CompletedProcess[str]:
    env = {'HOME': os.environ.get('HOME', '/root'), 'PATH': '/usr/bin:/bin',
           'ROS_DOMAIN_ID': os.environ['ROS_DOMAIN_ID'],
           'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST',
           'ROS_LOG_DIR': os.environ.get('ROS_LOG_DIR', str(tmp_path))}
    setup = shlex.quote(str(ROOT / 'install' / 'setup.bash'))
    return subprocess.run(['env', '-i', *[f'{k}={v}' for k, v in env.items()], 'bash', '-c',
                           f'source {setup} && {script}'], capture_output=True, text=True,
                          timeout=120, cwd=tmp_path)


def test_every_wrapper_names_an_installed_console_script() -> None:
    assert sorted(p.name for p in WRAPPERS.iterdir()) == sorted(TOOLS)
    for tool in TOOLS:
        text = (WRAPPERS / tool).read_text()
        pkg = text.split('\npkg=', 1)[1].split('\n', 1)[0]
        assert f'\nexe={tool}\n' in text
        assert os.access(ROOT / 'install' / pkg / 'lib' / pkg / tool, os.X_OK), (pkg, tool)


def test_tools_are_on_path_in_a_fresh_shell(tmp_path: Path) -> None:
    found = _fresh_shell('for t in ' + ' '.join(TOOLS) + '; do command -v "$t" || '
                         'echo "MISSING $t"; done', tmp_path)
    assert found.returncode == 0, found.stderr
    assert 'MISSING' not in found.stdout, found.stdout
    paths = found.stdout.split()
    assert all(Path(p).parent == ROOT / 'install' / 'slip_bringup' / 'bin' for p in paths), paths

    cli = _fresh_shell('slip_cli --help', tmp_path)
    assert cli.returncode == 0, cli.stderr
    assert cli.stdout.startswith('usage: slip_cli') and 'topic' in cli.stdout
    live = _fresh_shell('foxglove_live --help', tmp_path)
    assert live.returncode == 0 and 'ws://127.0.0.1:8765' in live.stdout, live.stderr
    # Arguments and exit codes pass through the wrapper.
    bag = _fresh_shell('slip_bag info no_such_bag', tmp_path)
    assert bag.returncode == 2
    assert bag.stderr.strip() == 'slip_bag: error: bag no_such_bag does not exist'
