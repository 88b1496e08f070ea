# SPDX-License-Identifier: Apache-2.0
"""Chip re-sync episodes as the velocity-sensor firmware reports them (ROS-free).

When a chip does not answer its product-ID read, the firmware's sensor task prints ``resynch``
and the three product IDs, then re-syncs the chips; it does this on every pass (about every
6 ms) for as long as a chip stays out. Meanwhile the serial task keeps printing velocity lines
built from whatever motion was accumulated, i.e. zeros while no chip is read. Nothing marks the
end of a re-sync: the notices just stop.

A velocity line covers one serial period, the time since the previous line. The line that
follows a notice covers the re-sync; the next one may still cover the tail of the last re-sync
(the re-sync runs after its notice, for up to one pass); only a line whose whole period started
after a period free of notices measures motion again. `ResyncTracker` therefore keeps a
re-sync open from the first notice until ``clean_lines`` consecutive velocity lines arrived
without a notice between them, and the line that closes it is the first usable one.
"""
from __future__ import annotations

import math


class ResyncTracker:
    """Open/closed state of a chip re-sync, driven by parsed lines in arrival order.

    Args:
        clean_lines: Velocity lines without a notice before them that end a re-sync (>= 1);
            the line that reaches the count is usable. 2 = the first line whose period began
            after a full serial period free of notices.
    """

    def __init__(self, clean_lines: int = 2) -> None:
        if clean_lines < 1:
            raise ValueError('clean_lines must be >= 1')
        self.clean_lines = clean_lines
        self.active = False
        #: Re-sync episodes seen (a run of notices up to its end counts once).
        self.episodes = 0
        #: ``resynch`` notices seen.
        self.notices = 0
        #: Stamp of the first notice of the current (or last) episode [s]; NaN before any.
        self.started = math.nan
        #: Stamp of the newest notice [s]; NaN before any.
        self.last_notice = math.nan
        #: Stamp of the velocity line that ended the last episode [s]; NaN while none ended.
        self.ended = math.nan
        #: Product IDs printed with the newest notice (empty before any).
        self.product_ids: tuple[int, ...] = ()
        self._notice_since_line = False
        self._clean = 0

    def on_notice(self, t: float) -> None:
        """A ``resynch`` notice arrived at ``t`` [s]: a chip is (still) out."""
        if not self.active:
            self.active = True
            self.episodes += 1
            self.started = t
        self.notices += 1
        self.last_notice = t
        self._notice_since_line = True
        self._clean = 0

    def on_product_ids(self, ids: tuple[int, ...]) -> None:
        """The product-ID line printed with a notice."""
        self.product_ids = tuple(ids)

    def on_velocity_line(self, t: float) -> bool:
        """A velocity line arrived at ``t`` [s]; True when it is free of a re-sync.

        False for every line from the first notice up to and excluding the line that ends the
        episode.
        """
        if not self.active:
            return True
        if self._notice_since_line:
            self._notice_since_line = False
            self._clean = 0
            return False
        self._clean += 1
        if self._clean < self.clean_lines:
            return False
        self.active = False
        self.ended = t
        return True

    def duration(self, t: float) -> float:
        """How long the open episode has lasted at ``t`` [s] (0 when none is open)."""
        return t - self.started if self.active else 0.0

    def forget_times(self) -> None:
        """Drop the stamps (the clock jumped); the open/closed state is kept."""
        self.started = self.last_notice = self.ended = math.nan


def describe_product_ids(ids: tuple[int, ...], expected: int) -> str:
    """Which chips failed, in words: ``chip 1 reads 0 (not answering, data line low)``.

    Args:
        ids: Product IDs as printed (chip 1 first).
        expected: The ID of a healthy chip (0x31).
    """
    parts = []
    for chip, pid in enumerate(ids, start=1):
        if pid == expected:
            continue
        if pid == 0:
            why = 'not answering, data line low'
        elif pid == -1:
            why = 'not answering, data line pulled high'
        else:
            why = f'expected {expected}'
        parts.append(f'chip {chip} reads {pid} ({why})')
    return ', '.join(parts) if parts else 'product ids not reported'
