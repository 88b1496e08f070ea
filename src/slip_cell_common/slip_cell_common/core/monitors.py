"""Rate and age monitors for diagnostics (ROS-free; time passed in explicitly, seconds)."""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from enum import IntEnum


class Level(IntEnum):
    """Diagnostic levels (values of diagnostic_msgs/DiagnosticStatus)."""

    OK = 0
    WARN = 1
    ERROR = 2
    STALE = 3


@dataclass(frozen=True)
class Report:
    """One diagnostic task result: level, one-line message and key/value pairs (units in keys)."""

    level: Level
    message: str
    values: tuple[tuple[str, str], ...] = ()


class FrequencyMonitor:
    """Event rate over a sliding window, compared with an expected rate ± tolerance.

    Args:
        expected_hz: Nominal event rate [Hz].
        tolerance: Allowed relative deviation (0.1 = ±10 %).
        window_s: Averaging window [s].
    """

    def __init__(self, expected_hz: float, tolerance: float = 0.1, window_s: float = 1.0) -> None:
        if expected_hz <= 0.0 or tolerance < 0.0 or window_s <= 0.0:
            raise ValueError('expected_hz and window_s must be > 0, tolerance >= 0')
        self.expected_hz = expected_hz
        self.tolerance = tolerance
        self.window_s = window_s
        self._stamps: deque[float] = deque()

    def tick(self, t: float) -> None:
        """Record one event at time ``t`` [s]."""
        self._stamps.append(t)
        self._trim(t)

    def _trim(self, now: float) -> None:
        while self._stamps and self._stamps[0] < now - self.window_s:
            self._stamps.popleft()

    def rate(self, now: float) -> float:
        """Events per second over the last window ending at ``now`` [Hz]."""
        self._trim(now)
        return len(self._stamps) / self.window_s

    def report(self, now: float) -> Report:
        """OK within tolerance, WARN outside it, ERROR when no event arrived in the window."""
        hz = self.rate(now)
        values = (('rate_hz', f'{hz:.1f}'), ('expected_hz', f'{self.expected_hz:.1f}'))
        if hz == 0.0:
            return Report(Level.ERROR, 'no data', values)
        if abs(hz - self.expected_hz) > self.tolerance * self.expected_hz:
            return Report(Level.WARN, f'rate {hz:.1f} Hz outside {self.expected_hz:.0f} Hz '
                          f'±{100 * self.tolerance:.0f} %', values)
        return Report(Level.OK, 'rate ok', values)


class AgeMonitor:
    """Age of the latest sample against a stale threshold."""

    def __init__(self, stale_after_s: float) -> None:
        if stale_after_s <= 0.0:
            raise ValueError('stale_after_s must be > 0')
        self.stale_after_s = stale_after_s
        self.last: float = math.nan

    def tick(self, stamp: float) -> None:
        """Record the acquisition stamp [s] of the newest sample."""
        self.last = stamp

    def age(self, now: float) -> float:
        """Seconds since the newest sample (inf when none arrived)."""
        return math.inf if math.isnan(self.last) else now - self.last

    def fresh(self, now: float) -> bool:
        """True when the newest sample is younger than the threshold."""
        return self.age(now) <= self.stale_after_s
