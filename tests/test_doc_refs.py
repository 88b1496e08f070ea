"""Every section reference in the code (``control_and_estimation §4.2``, a bare ``§4.2``) names
a section that exists in the repository's own docs/ (issue 19)."""
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

