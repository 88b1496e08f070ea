# SPDX-License-Identifier: Apache-2.0
"""Issue 16: ``slip_demo`` never claims success on a failed run.

The slow test runs the real demo (the simulated cell's graph as processes, through real DDS)
with a fault injected through the demo's ``--set`` hook: the slip controller believes contact
is lost below 10 N, so the LINEAR slip ends "contact lost" soon after it starts, the runner
marks the object lost and stops the sequence there (a short run). The demo must exit 1 and
print FAILED rows naming the reasons, the worst diagnostics level and the real-time factor.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.ros


@pytest.mark.parametrize('bad', ['slip_controller', 'slip_controller.x', 'nosuchnode.x=1'])
def test_bad_set_arguments_are_refused_before_anything_starts(bad: str, tmp_path: Path) -> None:
    from slip_bringup.demo import main
    assert main(['--out', str(tmp_path / 'out'), '--set', bad]) == 2


@pytest.mark.slow
def test_demo_exits_nonzero_on_a_failed_segment(ros_env: dict[str, str],
                                                 tmp_path: Path) -> None:
    out = tmp_path / 'demo'
    proc = subprocess.run(
        [sys.executable, '-m', 'slip_bringup.demo', '--out', str(out), '--timeout', '300',
         '--set', 'slip_controller.contact_lost_force=10.0'],
        env=ros_env, capture_output=True, text=True, timeout=600)
    text = proc.stdout + proc.stderr
    assert proc.returncode == 1, text
    rows = {line.split()[0]: line for line in text.splitlines()
            if line.startswith(('  linear ', '  rotational '))}
    linear, rotational = rows.get('linear', ''), rows.get('rotational', '')
    assert 'target   20.0 mm' in linear and 'FAILED: contact lost' in linear, text
    assert 'target  20.0 deg' in rotational, text
    assert 'FAILED: not run (no trajectory recorded)' in rotational, text
    assert "success=False: demo: step 'LINEAR slip' failed: contact lost" in text
    assert 'RESULT: FAILED: linear slip: contact lost' in text
    assert 'Diagnostics: worst level ' in text
    assert 'Real-time factor (sim/state): mean ' in text
    assert (out / 'metrics.json').is_file()
