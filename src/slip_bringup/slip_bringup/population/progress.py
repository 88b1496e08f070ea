# SPDX-License-Identifier: Apache-2.0
"""A one-line progress bar on a text stream (flushed on every update, so it works in pipes)."""
from __future__ import annotations

import sys
import time
from typing import TextIO


class ProgressBar:
    """``label [#####.....] 12/200  6 %  0:41 elapsed, ~9:30 left``.

    On a terminal the line is redrawn in place; on a pipe or file a line is written at most
    every ``pipe_interval`` seconds and at the end, so logs stay short.
    """

    def __init__(self, label: str, stream: TextIO | None = None, width: int = 30,
                 pipe_interval: float = 5.0) -> None:
        self._label = label
        self._stream = stream if stream is not None else sys.stderr
        self._width = width
        self._tty = bool(getattr(self._stream, 'isatty', lambda: False)())
        self._interval = pipe_interval
        self._start = time.monotonic()   # wall time of a CLI display, not control logic
        self._last_write = -1e9

    def __call__(self, done: int, total: int) -> None:
        now = time.monotonic()
        final = done >= total
        if not self._tty and not final and now - self._last_write < self._interval:
            return
        self._last_write = now
        elapsed = now - self._start
        frac = done / total if total else 1.0
        fill = int(round(frac * self._width))
        left = elapsed / done * (total - done) if done else float('nan')
        eta = f', ~{_clock(left)} left' if done and not final else ''
        line = (f'{self._label} [{"#" * fill}{"." * (self._width - fill)}] {done}/{total} '
                f'{100.0 * frac:3.0f} %  {_clock(elapsed)} elapsed{eta}')
        self._stream.write(('\r' + line + ('\n' if final else '')) if self._tty else line + '\n')
        self._stream.flush()


def _clock(seconds: float) -> str:
    if seconds != seconds:  # NaN
        return '?'
    s = int(round(seconds))
    return f'{s // 60}:{s % 60:02d}'
