# SPDX-License-Identifier: Apache-2.0
"""The mypyc-compiled simulation core: chosen only when current, and equal to pure Python.

* ``stale_reason`` on a scratch directory: current, missing, edited, unreadable manifest.
* The built workspace runs the compiled core (when mypy is installed, as requirements.txt
  asks), every hot module from its extension; ``FRICTION_MODELS_PURE_PYTHON=1`` runs all
  of them from source.
* A copy of the built package whose ``plant.py`` was edited after the build falls back to pure
  Python for every hot module, with a warning that names the file.
* Equivalence: the same closed-loop scenario (grasp, lift, gravity slip at a low force,
  exploration on the table with the arm moving and the pads sliding) gives the same sensor
  streams and object trajectory in both implementations.
"""
from __future__ import annotations

import importlib.machinery
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from friction_models.core import native

PACKAGE_DIR = Path(__file__).resolve().parents[1] / 'friction_models'
CORE_DIR = PACKAGE_DIR / 'core'
SUFFIX = importlib.machinery.EXTENSION_SUFFIXES[0]


def _scratch_core(tmp_path: Path) -> Path:
    """Sources, fake extensions and a matching manifest for every compiled module."""
    for m in native.COMPILED_MODULES:
        (tmp_path / f'{m}.py').write_text(f'X = {m!r}\n')
        (tmp_path / f'{m}{SUFFIX}').write_bytes(b'')
    (tmp_path / native.MANIFEST_NAME).write_text(native.manifest_text(tmp_path, 'test'))
    return tmp_path


def test_stale_reason_current_core_is_usable(tmp_path: Path) -> None:
    assert native.stale_reason(_scratch_core(tmp_path)) is None


def test_stale_reason_names_the_edited_source(tmp_path: Path) -> None:
    core = _scratch_core(tmp_path)
    with (core / 'plant.py').open('a') as f:
        f.write('# edited\n')
    reason = native.stale_reason(core)
    assert reason is not None and 'plant.py' in reason and 'reduced.py' not in reason


def test_stale_reason_missing_extension_and_manifest(tmp_path: Path) -> None:
    core = _scratch_core(tmp_path)
    (core / native.MANIFEST_NAME).write_text('{not json')
    assert 'unreadable' in (native.stale_reason(core) or '')
    (core / f'sensors{SUFFIX}').unlink()
    assert native.stale_reason(core) == 'extension missing for sensors'
    for m in native.COMPILED_MODULES:
        (core / f'{m}{SUFFIX}').unlink(missing_ok=True)
    assert native.stale_reason(core) == 'not compiled'


def test_makefile_rebuilds_when_a_compiled_source_changes() -> None:
    makefile = (Path(__file__).resolve().parents[3] / 'Makefile').read_text()
    block = makefile.split('NATIVE_SOURCES :=')[1].split('\n\n')[0].split('\n$')[0]
    for m in (*native.COMPILED_MODULES, 'native'):
        assert f'{m}.py' in block, f'Makefile NATIVE_SOURCES misses {m}.py'


_REPORT = r'''
import importlib, json, warnings
warnings.simplefilter('always')
import friction_models.core as core
from friction_models.core import native
files = {m: importlib.import_module(f'friction_models.core.{m}').__file__
         for m in native.COMPILED_MODULES}
print(json.dumps({'compiled': core.NATIVE_STATUS.compiled, 'reason': core.NATIVE_STATUS.reason,
                  'files': files}))
'''


def _run(code: str, env_extra: dict[str, str], pythonpath: str | None = None
         ) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ)
    env.pop(native.ENV_PURE_PYTHON, None)   # the caller's choice only
    env.update(env_extra)
    if pythonpath is not None:
        env['PYTHONPATH'] = pythonpath + os.pathsep + env.get('PYTHONPATH', '')
    return subprocess.run([sys.executable, '-c', code], env=env, capture_output=True, text=True,
                          timeout=300, check=False)


def _report(env_extra: dict[str, str], pythonpath: str | None = None) -> tuple[dict, str]:
    out = _run(_REPORT, env_extra, pythonpath)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1]), out.stderr


def test_built_workspace_runs_the_compiled_core() -> None:
    pytest.importorskip('mypyc', reason='mypy not installed: the core is built pure Python')
    report, _ = _report({})
    assert report['compiled'], report['reason']
    assert all(f.endswith(SUFFIX) for f in report['files'].values()), report['files']
    assert set(report['files']) == set(native.COMPILED_MODULES)


def test_pure_python_on_request() -> None:
    report, stderr = _report({native.ENV_PURE_PYTHON: '1'})
    assert not report['compiled']
    assert all(f.endswith('.py') for f in report['files'].values()), report['files']
    assert 'RuntimeWarning' not in stderr


def test_edited_source_falls_back_to_pure_python_with_a_warning(tmp_path: Path) -> None:
    if native.stale_reason(CORE_DIR) is not None:
        pytest.skip(f'no current compiled core to copy ({native.stale_reason(CORE_DIR)})')
    copy = tmp_path / 'friction_models'
    shutil.copytree(PACKAGE_DIR, copy, ignore=shutil.ignore_patterns('__pycache__'))
    with (copy / 'core' / 'plant.py').open('a') as f:
        f.write('\n# edited after the build\n')
    report, stderr = _report({}, pythonpath=str(tmp_path))
    assert Path(report['files']['plant']).parent == copy / 'core'
    assert not report['compiled'] and 'plant.py' in report['reason']
    assert all(f.endswith('.py') for f in report['files'].values()), report['files']
    assert 'RuntimeWarning' in stderr and 'plant.py' in stderr


_SCENARIO = r'''
import json, math, hashlib
import friction_models.core as core
from friction_models.core.harness import Harness
from friction_models.core.presets import reference_presets
from friction_models.core.sim_cell import SimCell, SimParams

class Digest:
    def __init__(self): self.h, self.n = hashlib.sha256(), 0
    def add(self, *values):
        self.n += 1
        self.h.update(repr(values).encode())
    def on_ft(self, h, s): self.add('ft', s.stamp, s.finger, s.raw)
    def on_velocity(self, h, s): self.add('vel', s.stamp, s.finger, s.vx, s.vy, s.omega)
    def on_telemetry(self, h, s): self.add('tel', s.stamp, s.command, s.status)

cell = SimCell(SimParams(seed=7), reference_presets(), 'plastic')
d = Digest()
h = Harness(cell, [d])
h.home(); h.bias()
h.command_force(10.0); h.run_for(1.0)
h.move(lift=0.05, duration=0.5); h.run_for(0.2)
h.command_force(1.5); h.run_for(0.6)                       # gravity slip
h.command_force(10.0); h.run_for(0.3)
h.move(lift=-0.05, duration=0.6); h.run_for(0.3)           # back onto the table
h.command_force(5.0)
h.move(lift=-0.01, duration=0.4)                           # pads slide on the standing object
h.move(rotation=math.radians(10.0), duration=0.4)
h.move(rotation=-math.radians(10.0), duration=0.4)
p = cell.plant
print(json.dumps({'compiled': core.NATIVE_STATUS.compiled, 'events': d.n,
                  'digest': d.h.hexdigest(), 'state': [p.X, p.Y, p.th, p.VX, p.VY, p.W],
                  'slip': list(p.slip_integral)}))
'''


def test_compiled_and_pure_python_give_the_same_simulation() -> None:
    pytest.importorskip('mypyc', reason='mypy not installed: no compiled core to compare')
    runs = {}
    for pure in ('0', '1'):
        out = _run(_SCENARIO, {native.ENV_PURE_PYTHON: pure})
        assert out.returncode == 0, out.stderr
        runs[pure] = json.loads(out.stdout.strip().splitlines()[-1])
    compiled, reference = runs['0'], runs['1']
    assert compiled['compiled'] and not reference['compiled']
    assert compiled['events'] == reference['events'] > 5000
    # The object moved (slip and exploration happened), and both agree on where it went.
    assert abs(reference['slip'][1]) > 1e-3, reference['slip']
    for a, b in zip(compiled['state'] + compiled['slip'], reference['state'] + reference['slip']):
        assert a == pytest.approx(b, rel=1e-9, abs=1e-12)
    assert compiled['digest'] == reference['digest']
