"""Set-up shows progress: long steps run under tools/heartbeat.sh, colcon prints each package."""
from __future__ import annotations

import os
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HEARTBEAT = ROOT / 'tools' / 'heartbeat.sh'


def _run(*args: str, period: str = '1') -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, HEARTBEAT_S=period)
    return subprocess.run([str(HEARTBEAT), *args], capture_output=True, text=True, env=env,
                          timeout=30, check=False)


def test_heartbeat_reports_a_long_step_and_keeps_its_exit_status() -> None:
    out = _run('long step', 'sh', '-c', 'sleep 2.4; exit 3')
    assert out.returncode == 3
    beats = [line for line in out.stdout.splitlines() if 'long step still running' in line]
    assert len(beats) >= 2, out.stdout


def test_heartbeat_sends_the_command_output_to_a_log(tmp_path: Path) -> None:
    log = tmp_path / 'step.log'
    out = _run('-o', str(log), 'quiet step', 'sh', '-c', 'echo detail; sleep 1.3')
    assert out.returncode == 0
    assert 'detail' not in out.stdout and log.read_text().strip() == 'detail'
    assert 'quiet step still running' in out.stdout


def test_setup_scripts_use_the_heartbeat_and_per_package_lines() -> None:
    colcon = (ROOT / 'tools' / 'colcon_build.sh').read_text()
    assert 'heartbeat.sh' in colcon and 'console_start_end+' in colcon
    assert 'heartbeat.sh' in (ROOT / 'tools' / 'bootstrap_venv.sh').read_text()
