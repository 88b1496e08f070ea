# SPDX-License-Identifier: Apache-2.0
"""Which implementation of the simulation core runs: mypyc-compiled or pure Python.

The hot modules of the simulated cell (:data:`COMPILED_MODULES`) are plain, typed Python. When
the package is built with mypy installed, ``setup.py`` also compiles them with mypyc into C
extensions that sit next to the sources (``plant.cpython-311-….so`` beside ``plant.py``) and
records the SHA-256 of every compiled source in :data:`MANIFEST_NAME`. Python prefers an
extension over a source file of the same name, so without a check an edited ``plant.py``
would be silently shadowed by the extension built from the old text. :func:`select` runs
first thing in ``friction_models.core`` and decides, for all hot modules together (a compiled
module calls the compiled classes of the others directly, so they must not be mixed):

* compiled, when every extension is present and the manifest matches the sources;
* pure Python, with a :class:`RuntimeWarning` naming the cause, when an extension is missing
  or out of date (``make setup`` or ``colcon build`` rebuilds them);
* pure Python, without a warning, when ``FRICTION_MODELS_PURE_PYTHON=1`` asks for it (the
  reference implementation, used by the equivalence test).

Only the standard library is imported here (``setup.py`` loads this file by path).
"""
from __future__ import annotations

import hashlib
import importlib.abc
import importlib.machinery
import importlib.util
import json
import os
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from collections.abc import Mapping, Sequence

__all__ = [
    'COMPILED_MODULES',
    'ENV_PURE_PYTHON',
    'MANIFEST_NAME',
    'NativeStatus',
    'extension_path',
    'manifest_text',
    'select',
    'source_digests',
    'stale_reason',
]

#: Hot modules compiled by mypyc (names inside ``friction_models.core``).
COMPILED_MODULES: tuple[str, ...] = ('limit_surface', 'reduced', 'pad_contact', 'actuator',
                                      'arm', 'table', 'plant', 'sensors', 'sim_cell')
#: File beside the modules with the SHA-256 of each source the extensions were built from.
MANIFEST_NAME = 'native_sources.json'
#: Environment variable: ``1`` runs the pure-Python modules even when compiled ones exist.
ENV_PURE_PYTHON = 'FRICTION_MODELS_PURE_PYTHON'


@dataclass(frozen=True)
class NativeStatus:
    """Outcome of :func:`select`."""

    compiled: bool   #: True when the mypyc extensions are in use
    reason: str      #: one line for logs and benchmark headers

    def __str__(self) -> str:
        return self.reason


def source_digests(directory: Path, modules: Sequence[str] = COMPILED_MODULES
                   ) -> dict[str, str]:
    """SHA-256 (hex) of ``<module>.py`` in ``directory`` for each module."""
    return {m: hashlib.sha256((directory / f'{m}.py').read_bytes()).hexdigest() for m in modules}


def manifest_text(directory: Path, compiler: str) -> str:
    """JSON manifest written by ``setup.py`` after compiling the sources in ``directory``."""
    return json.dumps({'compiler': compiler, 'sources': source_digests(directory)}, indent=1,
                      sort_keys=True) + '\n'


def extension_path(directory: Path, module: str) -> Path | None:
    """The C extension built for ``module`` in ``directory`` (this interpreter's ABI), or None."""
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        path = directory / f'{module}{suffix}'
        if path.is_file():
            return path
    return None


def stale_reason(directory: Path, modules: Sequence[str] = COMPILED_MODULES) -> str | None:
    """Why the extensions in ``directory`` cannot be used, or None when all are current.

    Returns ``'not compiled'`` when no module has an extension at all.
    """
    missing = [m for m in modules if extension_path(directory, m) is None]
    if len(missing) == len(modules):
        return 'not compiled'
    if missing:
        return f'extension missing for {", ".join(missing)}'
    try:
        recorded = json.loads((directory / MANIFEST_NAME).read_text())['sources']
    except (OSError, ValueError, KeyError, TypeError) as exc:
        return f'manifest {MANIFEST_NAME} unreadable ({exc.__class__.__name__})'
    current = source_digests(directory, modules)
    changed = [m for m in modules if recorded.get(m) != current[m]]
    if changed:
        return 'source changed since the build: ' + ', '.join(f'{m}.py' for m in changed)
    return None


class _SourceFinder(importlib.abc.MetaPathFinder):
    """Import hook that loads the listed modules from their ``.py`` files."""

    def __init__(self, paths: Mapping[str, Path]) -> None:
        self._paths = dict(paths)

    def find_spec(self, fullname: str, path: object = None,
                  target: ModuleType | None = None) -> importlib.machinery.ModuleSpec | None:
        del path, target
        source = self._paths.get(fullname)
        if source is None:
            return None
        return importlib.util.spec_from_file_location(fullname, source)


def select(package: str, directory: Path,
           environ: Mapping[str, str] = os.environ) -> NativeStatus:
    """Choose the implementation of the hot modules of ``package`` (found in ``directory``).

    Must run before any hot module is imported. When pure Python is chosen, installs an
    import hook (for these module names only) so that every later import of them, in any
    order, loads the source file.
    """
    names = {f'{package}.{m}': directory / f'{m}.py' for m in COMPILED_MODULES}
    loaded = [n for n in names if n in sys.modules]
    if loaded:
        raise RuntimeError(f'select() must run before {loaded[0]} is imported')
    if environ.get(ENV_PURE_PYTHON, '') == '1':
        chosen = NativeStatus(False, f'pure Python ({ENV_PURE_PYTHON}=1)')
    else:
        reason = stale_reason(directory)
        if reason is None:
            return NativeStatus(True, 'compiled (mypyc)')
        chosen = NativeStatus(False, f'pure Python ({reason})')
        if reason != 'not compiled':
            warnings.warn(f'friction_models: compiled simulation core not used: {reason}; '
                          'rebuild with `make setup` (or colcon build) to compile it again',
                          RuntimeWarning, stacklevel=3)
    if not any(isinstance(f, _SourceFinder) for f in sys.meta_path):
        sys.meta_path.insert(0, _SourceFinder(names))
    return chosen
