"""Every section reference in the code (``control_and_estimation §4.2``, a bare ``§4.2``) names
a section that exists in the repository's own docs/ (issue 19); no path outside the repository."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_every_section_reference_resolves_in_docs() -> None:
    out = subprocess.run([sys.executable, str(ROOT / 'tools' / 'check_doc_refs.py'), '--strict'],
                         capture_output=True, text=True, cwd=ROOT, timeout=120, check=False)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-2000:]
    assert 'OK' in out.stdout


def test_no_reference_leaves_the_repository() -> None:
    bad = []
    for base in ('src', 'tests', 'bench', 'tools', 'docs'):
        for path in (ROOT / base).rglob('*'):
            if path.suffix not in ('.py', '.md', '.yaml', '.sh') or not path.is_file():
                continue
            if path == Path(__file__).resolve():
                continue
            text = path.read_text(errors='replace')
            for needle in ('/work/', 'shared/spec', 'shared/data', '../shared'):
                if needle in text:
                    bad.append(f'{path.relative_to(ROOT)}: {needle}')
    assert not bad, bad
