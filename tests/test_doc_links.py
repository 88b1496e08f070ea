"""Links between the documents resolve: every relative link names an existing file, and every
``#anchor`` into a Markdown file names one of its headings (GitHub's anchor rules).

Covers README.md, docs/**/*.md and every package README, like tests/test_doc_commands.py.
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LINK = re.compile(r'(?<!!)\[[^\]]*\]\((?P<target>[^)\s]+)\)')
FENCE = re.compile(r'^ {0,3}```')
INLINE_CODE = re.compile(r'`[^`]*`')


def documents() -> list[Path]:
    files = [ROOT / 'README.md', *sorted((ROOT / 'docs').rglob('*.md')),
             *sorted(ROOT.glob('src/*/README.md')), ROOT / 'bags' / 'README.md']
    return [f for f in files if f.is_file()]


def prose_lines(path: Path) -> list[tuple[int, str]]:
    """Lines outside fenced code blocks, inline code removed."""
    out, fenced = [], False
    for number, line in enumerate(path.read_text().splitlines(), start=1):
        if FENCE.match(line):
            fenced = not fenced
            continue
        if not fenced:
            out.append((number, INLINE_CODE.sub('', line)))
    return out


def anchor(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = INLINE_CODE.sub(lambda m: m.group(0)[1:-1], heading.strip()).lower()
    text = re.sub(r'[^\w\- ]', '', text)
    return text.replace(' ', '-')


def anchors(path: Path) -> set[str]:
    seen: dict[str, int] = {}
    out: set[str] = set()
    for _, line in ((n, raw) for n, raw in enumerate(path.read_text().splitlines())):
        if not line.startswith('#') or not re.match(r'^#{1,6} ', line):
            continue
        base = anchor(line.lstrip('#'))
        count = seen.get(base, 0)
        out.add(base if count == 0 else f'{base}-{count}')
        seen[base] = count + 1
    return out


def broken_links(path: Path) -> list[str]:
    problems = []
    for number, line in prose_lines(path):
        for m in LINK.finditer(line):
            target = m.group('target')
            if re.match(r'^[a-z]+:', target):
                continue  # http:, https:, mailto:
            file_part, _, fragment = target.partition('#')
            dest = (path.parent / file_part).resolve() if file_part else path
            shown = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path
            where = f'{shown}:{number}: {target}'
            if not dest.exists():
                problems.append(f'{where}: no such file')
            elif fragment and dest.suffix == '.md' and fragment not in anchors(dest):
                problems.append(f'{where}: no heading #{fragment} in {dest.name}')
    return problems


@pytest.mark.parametrize('path', documents(), ids=lambda p: str(p.relative_to(ROOT)))
def test_links_resolve(path: Path) -> None:
    problems = broken_links(path)
    assert not problems, '\n'.join(problems)


def test_anchor_rules() -> None:
    assert anchor(' `serial.port is required`') == 'serialport-is-required'
    assert anchor(' `finger_k/ft/wrench` is silent') == 'finger_kftwrench-is-silent'
    assert anchor(' Plots look jittery or shifted: plot by header stamp') == \
        'plots-look-jittery-or-shifted-plot-by-header-stamp'


def test_a_broken_link_is_found(tmp_path: Path) -> None:
    doc = tmp_path / 'a.md'
    doc.write_text('# Title\n\n[ok](#title) [gone](missing.md) [bad](b.md#no-such) [b](b.md#b)\n'
                   '```\n[in code](ignored.md)\n```\n')
    (tmp_path / 'b.md').write_text('# B\n')
    problems = broken_links(doc)
    assert len(problems) == 2, problems
    assert 'missing.md: no such file' in problems[0]
    assert 'no heading #no-such' in problems[1]
