# SPDX-License-Identifier: Apache-2.0
"""The README's usage example runs, is at most 10 lines, and prints what the README says."""
from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import numpy as np

README = Path(__file__).resolve().parents[1] / 'README.md'


def _blocks() -> tuple[str, str]:
    text = README.read_text()
    match = re.search(r'## Usage example\n\n```python\n(.*?)```.*?```\n(.*?)```', text, re.S)
    assert match, 'README lacks the usage example and its printed output'
    return match.group(1), match.group(2)


def _numbers(text: str) -> list[float]:
    return [float(v) for v in re.findall(r'[-+]\d+\.\d+(?:e[-+]\d+)?', text)]


def test_usage_example_runs_and_matches_its_documented_output() -> None:
    code, documented = _blocks()
    assert len(code.strip().splitlines()) <= 10
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, str(README), 'exec'), {'__name__': '__readme__'})
    printed = out.getvalue()
    assert [line.split()[0] for line in printed.splitlines()] == ['reduced', 'distributed']
    np.testing.assert_allclose(_numbers(printed), _numbers(documented), rtol=1e-3, atol=1e-4)
