#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Check that every reference-document section cited in the code exists in ``docs/``.

The code cites the reference documents as ``<doc> §N.M`` (``hardware_protocols §3.2``,
``control_and_estimation §4``, ``docs/ros_interfaces.md §6.5``, ``house style §7``) and
their requirement ids as ``HW-n`` / ``CE-n``. Each cited section must exist in
``docs/<doc>.md`` as a heading that starts with its number (``### §3.2 Telemetry line``) or as
a list item that starts with it in bold (``* **§13.6** ...``); each requirement id must be a
row of the requirements table (``| HW-6 | ...``).

A bare ``§N.M`` (no document named) is attributed to the first document the same file names
(other than the conventions documents), else to the file's package default (below); inside a
reference document it means that document. Such references are reported apart, because the
attribution is a guess; ``--strict`` makes an unresolved one an error too.
Citations of the papers (``paper §5.1``, ``thesis §2.1``) are not ours and are skipped.

Usage::

    tools/check_doc_refs.py [--strict] [--verbose] [PATH ...]   # default: src tests bench tools
    tools/check_doc_refs.py --strict docs    # the documents' own cross-references

Exit status 0 when every named reference resolves (and, with ``--strict``, every bare one),
1 otherwise. Only the standard library is used.
"""
from __future__ import annotations

import argparse
import re
import sys
from collections import Counter, defaultdict
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / 'docs'
DEFAULT_PATHS = ('src', 'tests', 'bench', 'tools')
TEXT_SUFFIXES = {'.py', '.md', '.yaml', '.yml', '.txt', '.sh', '.cfg', '.toml', '.xml', '.msg',
                 '.srv', '.action', '.json', '.ini', ''}
SKIP_DIRS = {'__pycache__', 'build', 'install', 'log', '.git', '.venv', 'node_modules'}

#: Reference documents: name in citations → file in docs/.
DOCUMENTS = {
    'hardware_protocols': 'hardware_protocols.md',
    'control_and_estimation': 'control_and_estimation.md',
    'friction_models': 'friction_models.md',
    'ros_interfaces': 'ros_interfaces.md',
    'house_style': 'house_style.md',
    'toolchain': 'toolchain.md',
}
#: Requirement-id prefixes and the document holding their table.
REQUIREMENT_DOCS = {'HW': 'hardware_protocols', 'CE': 'control_and_estimation'}
#: Documents that files cite in passing (never taken as the document of a bare ``§``).
PASSING_DOCS = {'house_style', 'toolchain'}
#: Package → document a bare ``§`` in it most likely means (used only without a named one).
PACKAGE_DEFAULTS = {
    'slip_gripper_driver': 'hardware_protocols',
    'slip_velocity_sensor': 'hardware_protocols',
    'friction_models': 'friction_models',
    'slip_control': 'control_and_estimation',
    'slip_bringup': 'control_and_estimation',
    'slip_cell_common': 'ros_interfaces',
    'slip_msgs': 'ros_interfaces',
}

_NUM = r'\d+(?:\.\d+)*'
_DOC_NAME = r'(?P<doc>hardware_protocols|control_and_estimation|friction_models|ros_interfaces|' \
            r'house[_ ]style|toolchain)'
#: ``[docs/]<doc>[.md][`] [spec|spec's] §N.M[–N.M]``, also a Markdown link ``[x.md](x.md) §N``
NAMED_RE = re.compile(
    r'(?:docs/)?' + _DOC_NAME + r'(?:\.md)?[`\'"*)\]]*(?:\s+spec(?:\'s)?)?\s*§\s*(?P<num>' + _NUM +
    r')(?:\s*[–-]\s*§?\s*(?P<end>' + _NUM + r'))?')
#: A ``§`` that continues a list after a named one: ``, §3.6`` / `` and §4.9``.
CONTINUATION_RE = re.compile(
    r'^(?:\s*(?:,|and|or|&|/)\s*)§\s*(?P<num>' + _NUM + r')(?:\s*[–-]\s*§?\s*(?P<end>' + _NUM +
    r'))?')
ANY_SECTION_RE = re.compile(r'§\s*(?P<num>' + _NUM + r')(?:\s*[–-]\s*§?\s*(?P<end>' + _NUM +
                            r'))?')
#: Words before a bare ``§`` that mean an external publication, not our documents.
EXTERNAL_RE = re.compile(
    r'(?:paper|thesis|sections?|arxiv|ieee|rep)(?:\s+"[^"]*")?'
    r'(?:[\s`\'"*]*§\s*\d+(?:\.\d+)*\s*(?:,|and|/|[–-])?)*[\s`\'"*]*$', re.IGNORECASE)
REQUIREMENT_RE = re.compile(r'\b(?P<prefix>HW|CE)-(?P<n>\d+)\b')

HEADING_RE = re.compile(r'^#{1,6}\s+§(?P<num>' + _NUM + r')(?![\d.]*\d)')
LIST_ANCHOR_RE = re.compile(r'^\s*(?:[-*]|\d+\.)\s+\*\*§(?P<num>' + _NUM + r')\*\*')
REQUIREMENT_ROW_RE = re.compile(r'^\|\s*\**(?P<id>(?:HW|CE)-\d+)\**\s*\|')


@dataclass(frozen=True)
class Reference:
    """One cited section."""

    path: Path
    line: int
    doc: str
    number: str
    named: bool          #: the citation names its document
    inferred_from: str   #: '' for named; else how the document was attributed
    candidates: tuple[str, ...] = ()  #: other documents the file names (bare references only)


def _normalise(num: str) -> str:
    return num.rstrip('.')


def _doc_key(raw: str) -> str:
    return raw.replace(' ', '_')


def _expand_range(start: str, end: str | None) -> list[str]:
    """``4.2–4.6`` → 4.2 … 4.6 (same parent); ``6.4–6.6`` likewise; otherwise both ends."""
    start = _normalise(start)
    if not end:
        return [start]
    end = _normalise(end)
    s_parts, e_parts = start.split('.'), end.split('.')
    if len(e_parts) == 1 and len(s_parts) > 1:          # "§4.2–6" → 4.2 … 4.6
        e_parts = s_parts[:-1] + e_parts
    if len(s_parts) == len(e_parts) and s_parts[:-1] == e_parts[:-1]:
        lo, hi = int(s_parts[-1]), int(e_parts[-1])
        if lo <= hi and hi - lo <= 20:
            prefix = '.'.join(s_parts[:-1])
            return [f'{prefix}.{k}' if prefix else str(k) for k in range(lo, hi + 1)]
    return [start, '.'.join(e_parts)]


def document_sections(doc_file: Path) -> set[str]:
    """Section numbers defined in one document (headings and bold list anchors)."""
    if not doc_file.is_file():
        return set()
    found: set[str] = set()
    in_code = False
    for line in doc_file.read_text(encoding='utf-8').splitlines():
        if line.lstrip().startswith('```'):
            in_code = not in_code
            continue
        if in_code:
            continue
        m = HEADING_RE.match(line) or LIST_ANCHOR_RE.match(line)
        if m:
            found.add(_normalise(m.group('num')))
    return found


def document_requirements(doc_file: Path) -> set[str]:
    """Requirement ids (``HW-n``, ``CE-n``) defined as table rows in one document."""
    if not doc_file.is_file():
        return set()
    return {m.group('id') for line in doc_file.read_text(encoding='utf-8').splitlines()
            if (m := REQUIREMENT_ROW_RE.match(line))}


def _package_of(path: Path) -> str | None:
    """Package a file belongs to (``src/<pkg>/...``), or whose name its file name contains."""
    parts = path.relative_to(ROOT).parts if path.is_relative_to(ROOT) else path.parts
    if len(parts) >= 2 and parts[0] == 'src':
        return parts[1]
    return next((pkg for pkg in PACKAGE_DEFAULTS if pkg in path.name), None)


def _iter_files(paths: list[Path]) -> list[Path]:
    files: list[Path] = []
    for base in paths:
        if base.is_file():
            files.append(base)
            continue
        for p in sorted(base.rglob('*')):
            if any(part in SKIP_DIRS for part in p.parts) or not p.is_file():
                continue
            if p.suffix in TEXT_SUFFIXES and p.resolve() != Path(__file__).resolve():
                files.append(p)
    return files


def scan_file(path: Path) -> tuple[list[Reference], list[tuple[Path, int, str]]]:
    """All section references and requirement ids cited in one file."""
    try:
        text = path.read_text(encoding='utf-8')
    except (UnicodeDecodeError, OSError):
        return [], []
    refs: list[Reference] = []
    reqs: list[tuple[Path, int, str]] = []
    # A file's main document is the first one it names (its module docstring, as a rule);
    # the conventions documents are named in passing and never make a file's main document.
    named_docs = tuple(dict.fromkeys(_doc_key(m.group('doc')) for m in NAMED_RE.finditer(text)))
    primary = next((d for d in named_docs if d not in PASSING_DOCS), None)
    if path.parent.resolve() == DOCS.resolve() and path.stem in DOCUMENTS:
        primary = path.stem     # inside a reference document a bare § means the document itself
    package_default = PACKAGE_DEFAULTS.get(_package_of(path) or '')
    for lineno, line in enumerate(text.splitlines(), start=1):
        for m in REQUIREMENT_RE.finditer(line):
            reqs.append((path, lineno, f"{m.group('prefix')}-{m.group('n')}"))
        if '§' not in line:
            continue
        claimed: set[int] = set()       # offsets of '§' already attributed on this line
        for m in NAMED_RE.finditer(line):
            doc = _doc_key(m.group('doc'))
            claimed.add(line.index('§', m.start()))
            for num in _expand_range(m.group('num'), m.group('end')):
                refs.append(Reference(path, lineno, doc, num, True, ''))
            # follow ", §x" / " and §y" chains after a named citation
            pos = m.end()
            while True:
                c = CONTINUATION_RE.match(line[pos:])
                if not c:
                    break
                claimed.add(line.index('§', pos))
                for num in _expand_range(c.group('num'), c.group('end')):
                    refs.append(Reference(path, lineno, doc, num, False, 'same citation'))
                pos += c.end()
        for m in ANY_SECTION_RE.finditer(line):
            if m.start() in claimed:
                continue
            if EXTERNAL_RE.search(line[:m.start()]):
                continue
            if primary:
                doc, how = primary, f'first document the file names ({primary})'
            elif package_default:
                doc, how = package_default, f'package default ({package_default})'
            else:
                doc, how = '', 'no document named in the file'
            others = tuple(d for d in named_docs if d != doc and d not in PASSING_DOCS)
            for num in _expand_range(m.group('num'), m.group('end')):
                refs.append(Reference(path, lineno, doc, num, False, how, others))
    return refs, reqs


def main(argv: list[str] | None = None) -> int:
    """Scan, resolve against docs/ and print a report; return the exit status."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('paths', nargs='*', type=Path,
                    help='files or directories to scan (default: src tests bench tools)')
    ap.add_argument('--strict', action='store_true',
                    help='also fail on bare § references that do not resolve')
    ap.add_argument('--verbose', '-v', action='store_true',
                    help='list every reference, not only the unresolved ones')
    args = ap.parse_args(argv)
    paths = args.paths or [ROOT / p for p in DEFAULT_PATHS]
    missing = [p for p in paths if not p.exists()]
    if missing:
        ap.error('no such path: ' + ', '.join(map(str, missing)))

    sections = {doc: document_sections(DOCS / fname) for doc, fname in DOCUMENTS.items()}
    requirements = {prefix: document_requirements(DOCS / DOCUMENTS[doc])
                    for prefix, doc in REQUIREMENT_DOCS.items()}

    refs: list[Reference] = []
    reqs: list[tuple[Path, int, str]] = []
    for f in _iter_files(paths):
        r, q = scan_file(f)
        refs.extend(r)
        reqs.extend(q)
    # A bare number that the guessed document lacks but exactly one other document named in
    # the same file has is attributed to that one.
    for i, r in enumerate(refs):
        if r.named or r.number in sections.get(r.doc, set()):
            continue
        hits = [d for d in r.candidates if r.number in sections.get(d, set())]
        if len(hits) == 1:
            refs[i] = Reference(r.path, r.line, hits[0], r.number, False,
                                f'only document named in the file that has it ({hits[0]})')

    def resolves(ref: Reference) -> bool:
        return bool(ref.doc) and ref.number in sections.get(ref.doc, set())

    named = [r for r in refs if r.named]
    bare = [r for r in refs if not r.named]
    named_bad = [r for r in named if not resolves(r)]
    bare_bad = [r for r in bare if not resolves(r)]
    req_bad = [(p, n, rid) for p, n, rid in reqs if rid not in requirements[rid.split('-')[0]]]

    def rel(p: Path) -> str:
        return str(p.relative_to(ROOT)) if p.is_relative_to(ROOT) else str(p)

    for doc, fname in DOCUMENTS.items():
        status = f'{len(sections[doc])} sections' if (DOCS / fname).is_file() else 'MISSING'
        print(f'docs/{fname}: {status}')
    if args.verbose:
        for r in refs:
            mark = 'ok ' if resolves(r) else 'BAD'
            how = '' if r.named else f'  [bare: {r.inferred_from}]'
            print(f'{mark} {rel(r.path)}:{r.line}: {r.doc or "?"} §{r.number}{how}')
    if named_bad:
        print('\nUnresolved named references:')
        for r in named_bad:
            print(f'  {rel(r.path)}:{r.line}: {r.doc} §{r.number} '
                  f'(no such section in docs/{DOCUMENTS[r.doc]})')
    if bare_bad:
        print('\nUnresolved bare references (document attributed by guess):')
        for r in bare_bad:
            print(f'  {rel(r.path)}:{r.line}: §{r.number} -> {r.doc or "?"} ({r.inferred_from})')
    if req_bad:
        print('\nUnknown requirement ids:')
        for p, n, rid in req_bad:
            print(f'  {rel(p)}:{n}: {rid}')

    per_doc = Counter(r.doc for r in refs)
    by_kind: dict[str, int] = defaultdict(int)
    for r in bare:
        by_kind[r.inferred_from.split(' (')[0]] += 1
    print(f'\n{len(refs)} section references in {len({r.path for r in refs})} files: '
          f'{len(named)} named ({len(named_bad)} unresolved), '
          f'{len(bare)} bare ({len(bare_bad)} unresolved)')
    print('  per document: ' + ', '.join(f'{d or "?"} {n}' for d, n in per_doc.most_common()))
    print('  bare attributed by: ' + ', '.join(f'{k} {v}' for k, v in sorted(by_kind.items())))
    print(f'{len(reqs)} requirement-id references ({len(req_bad)} unknown)')
    failed = bool(named_bad or req_bad or (args.strict and bare_bad))
    print('FAIL' if failed else 'OK')
    return 1 if failed else 0


if __name__ == '__main__':
    sys.exit(main())
