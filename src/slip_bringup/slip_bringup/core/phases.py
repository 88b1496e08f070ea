# SPDX-License-Identifier: Apache-2.0
"""Phases and aborts of a recording, from the slip controller's state changes (ROS-free).

``slip_control/state`` is published latched on every change with the mode and the reason of
the change. A *phase* is a run of one mode; an *end* is a trajectory or hinge that ended, and
it is an *abort* when its message is not ``done`` (the controller's reason reads
``"LINEAR ended: velocity stale"``; the same text is the action result's message, with
``success = false``). Times are header stamps [s].
"""
from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

#: ``SetSlipMode`` constants → names.
MODE_NAMES: dict[int, str] = {0: 'off', 1: 'rotational', 2: 'linear', 3: 'hinge', 4: 'hold'}

_ENDED = re.compile(r'^(LINEAR|ROTATIONAL|HINGE) ended: (.+)$')


@dataclass(frozen=True, slots=True)
class StateChange:
    """One ``slip_control/state`` message: stamp [s], mode constant, reason text."""

    t: float
    mode: int
    reason: str


@dataclass(frozen=True, slots=True)
class Phase:
    """A run of one controller mode, clipped to the recording.

    Attributes:
        mode: Mode name (``MODE_NAMES``).
        t_start: Start [s] (the recording's start when the mode was already on).
        t_end: End [s].
        reason: Reason of the change that started it.
    """

    mode: str
    t_start: float
    t_end: float
    reason: str

    @property
    def duration(self) -> float:
        """``t_end − t_start`` [s]."""
        return self.t_end - self.t_start


@dataclass(frozen=True, slots=True)
class ModeEnd:
    """A LINEAR, ROTATIONAL or HINGE run that ended; ``success`` only for ``done``."""

    mode: str
    t: float
    success: bool
    message: str


def phases(changes: Sequence[StateChange], t_begin: float, t_end: float) -> list[Phase]:
    """Runs of one mode between ``t_begin`` and ``t_end`` [s].

    Consecutive changes with the same mode (a safe-hold toggle, say) extend the run; a change
    stamped before ``t_begin`` (the latched state of a recording started later) starts the
    first run at ``t_begin``.
    """
    ordered = sorted(changes, key=lambda c: c.t)
    runs: list[tuple[int, float, str]] = []
    for c in ordered:
        if not runs or runs[-1][0] != c.mode:
            runs.append((c.mode, c.t, c.reason))
    out: list[Phase] = []
    for i, (mode, start, reason) in enumerate(runs):
        stop = runs[i + 1][1] if i + 1 < len(runs) else t_end
        start, stop = max(start, t_begin), min(stop, t_end)
        if stop > start:
            out.append(Phase(MODE_NAMES.get(mode, f'mode {mode}'), start, stop, reason))
    return out


def mode_ends(changes: Sequence[StateChange]) -> list[ModeEnd]:
    """Every ``<MODE> ended: <message>`` reason, once per end (repeats are dropped)."""
    out: list[ModeEnd] = []
    previous = ''
    for c in sorted(changes, key=lambda c: c.t):
        match = _ENDED.match(c.reason)
        if match and c.reason != previous:
            message = match.group(2).strip()
            out.append(ModeEnd(match.group(1).lower(), c.t, message == 'done', message))
        previous = c.reason
    return out


def phase_at(runs: Sequence[Phase], t: float) -> Phase | None:
    """The phase that contains ``t`` [s], if any."""
    for p in runs:
        if p.t_start <= t <= p.t_end:
            return p
    return None
