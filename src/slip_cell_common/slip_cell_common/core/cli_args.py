# SPDX-License-Identifier: Apache-2.0
"""Command-line conventions shared by the user tools (ROS-free, stdlib only).

* `Parser`: an ``argparse.ArgumentParser`` whose errors are one line on stderr
  (``prog: error: <what is wrong> (see prog --help)``, exit code 2) and whose help shows the
  default of every option that has one (`HelpFormatter`).
* Argument types that reject what a tool cannot use with a message naming the value:
  non-numbers, NaN/inf, and values outside a range (`finite_float`, `positive_float`,
  `non_negative_float`, `float_range`, `int_range`, `positive_int`, `non_negative_int`).
* `plain_doc`: a module docstring without reST markup, for ``description=``.
"""
from __future__ import annotations

import argparse
import math
import re
import sys
import textwrap
from collections.abc import Callable
from typing import Any, NoReturn

__all__ = ['HelpFormatter', 'Parser', 'finite_float', 'float_range', 'int_range',
           'non_negative_float', 'non_negative_int', 'plain_doc', 'positive_float',
           'positive_int']


_STATES_DEFAULT = re.compile(r'\(default\b|\bdefault:|%\(default\)')


class HelpFormatter(argparse.HelpFormatter):
    """Appends ``(default: X)`` to every option whose help does not state its default
    already, and lays out descriptions and epilogs as text with paragraphs.

    Flags (``store_true``/``store_false``), ``None`` defaults and suppressed defaults are left
    alone; an empty string shows as ``''``. In descriptions, paragraphs (separated by blank
    lines) and ``*`` bullets are refilled to the terminal width; indented lines (examples)
    and lines ending with ``:`` followed by an indented block are kept as written.
    """

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        out: list[str] = []
        for block in re.split(r'\n\s*\n', text.strip('\n')):
            lines = block.splitlines()
            items: list[list[str]] = []
            for line in lines:
                if line.startswith((' ', '\t')) and not (items and items[-1][0].startswith('* ')
                                                          and line.startswith('  ')
                                                          and not line.startswith('    ')):
                    items.append([line])          # an indented line: kept as written
                elif line.startswith('* ') or not items or items[-1][0].startswith((' ', '\t')):
                    items.append([line])
                else:
                    items[-1].append(line)
            for item in items:
                if item[0].startswith((' ', '\t')):
                    out.append(indent + item[0])
                    continue
                bullet = item[0].startswith('* ')
                words = ' '.join(part.strip() for part in item)
                out.append(textwrap.fill(words, width, initial_indent=indent,
                                         subsequent_indent=indent + ('  ' if bullet else '')))
            out.append('')
        return '\n'.join(out).rstrip('\n')

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ''
        if (_STATES_DEFAULT.search(text) or action.default is None
                or action.default is argparse.SUPPRESS or not action.option_strings
                or isinstance(action, (argparse._StoreTrueAction, argparse._StoreFalseAction,
                                       argparse._HelpAction, argparse._VersionAction,
                                       argparse._CountAction))):
            return text
        shown = "''" if action.default == '' else '%(default)s'
        return f'{text} (default: {shown})' if text else f'(default: {shown})'


class Parser(argparse.ArgumentParser):
    """``ArgumentParser`` with one-line errors and `HelpFormatter` (subparsers inherit both)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault('formatter_class', HelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> NoReturn:
        """Print ``prog: error: message (see prog --help)`` as one line and exit with 2."""
        text = ' '.join(str(message).split())
        self.exit(2, f'{self.prog}: error: {text} (see {self.prog} --help)\n')

    def exit(self, status: int = 0, message: str | None = None) -> NoReturn:
        """Exit with ``status`` after writing ``message`` (flushed) to stderr."""
        if message:
            sys.stderr.write(message)
            sys.stderr.flush()
        raise SystemExit(status)


def _number(text: str, kind: Callable[[str], Any] = float) -> Any:
    try:
        return kind(text)
    except (TypeError, ValueError):
        what = 'an integer' if kind is int else 'a number'
        raise argparse.ArgumentTypeError(f'expected {what}, got {text!r}') from None


def _finite(text: str) -> float:
    value = _number(text)
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f'must be a finite number, got {text!r}')
    return float(value)


def finite_float(text: str) -> float:
    """A finite float (no NaN or inf)."""
    return _finite(text)


def positive_float(text: str) -> float:
    """A finite float > 0."""
    value = _finite(text)
    if not value > 0.0:
        raise argparse.ArgumentTypeError(f'must be > 0, got {text!r}')
    return value


def non_negative_float(text: str) -> float:
    """A finite float >= 0."""
    value = _finite(text)
    if value < 0.0:
        raise argparse.ArgumentTypeError(f'must be >= 0, got {text!r}')
    return value


def float_range(low: float, high: float) -> Callable[[str], float]:
    """Type of a finite float in ``[low, high]``."""
    def parse(text: str) -> float:
        value = _finite(text)
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f'must be in [{low:g}, {high:g}], got {text!r}')
        return value
    parse.__name__ = f'float in [{low:g}, {high:g}]'
    return parse


def int_range(low: int, high: int) -> Callable[[str], int]:
    """Type of an integer in ``[low, high]``."""
    def parse(text: str) -> int:
        value = int(_number(text, int))
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f'must be an integer in [{low}, {high}], '
                                             f'got {text!r}')
        return value
    parse.__name__ = f'integer in [{low}, {high}]'
    return parse


def positive_int(text: str) -> int:
    """An integer >= 1."""
    value = int(_number(text, int))
    if value < 1:
        raise argparse.ArgumentTypeError(f'must be an integer >= 1, got {text!r}')
    return value


def non_negative_int(text: str) -> int:
    """An integer >= 0."""
    value = int(_number(text, int))
    if value < 0:
        raise argparse.ArgumentTypeError(f'must be an integer >= 0, got {text!r}')
    return value


_LITERAL = re.compile(r'``([^`]+)``')
_ROLE = re.compile(r':[a-z]+:`~?([^`]+)`')
_INTERPRETED = re.compile(r'`([^`]+)`')


def plain_doc(doc: str | None) -> str:
    """``doc`` without reST markup: ````x```` and ```x``` become ``x``, a trailing ``::``
    becomes ``:``; indentation and line breaks are kept (show it with `HelpFormatter`)."""
    text = (doc or '').strip('\n')
    text = _ROLE.sub(r'\1', text)
    text = _LITERAL.sub(r'\1', text)
    text = _INTERPRETED.sub(r'\1', text)
    text = re.sub(r'(?m)(\S)\s*::$', r'\1:', text)
    text = re.sub(r'(?m)^\s*::$\n?', '', text)
    return text.strip()
