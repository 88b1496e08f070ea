# SPDX-License-Identifier: Apache-2.0
"""The status word of an RDT record: diagnostic level and text (ROS-free, §4.5)."""
from __future__ import annotations

from typing import NamedTuple

from slip_cell_common.core.monitors import Level

STATUS_MONITOR_LATCHED = 0x80010000
STATUS_MONITOR_BIT = 0x00010000
STATUS_ERROR_SUMMARY = 0x80000000
_STATUS_BITS: tuple[tuple[int, str], ...] = (
    (0x00020000, 'transducer saturation or A/D error'),
    (0x00100000, 'RDT communication error'),
)


class StatusInfo(NamedTuple):
    """Decoded status word: diagnostic level and text."""

    level: Level
    text: str


def decode_status(status: int) -> StatusInfo:
    """Map a status word to a level (§4.5): 0 OK, 0x80010000 WARN, anything else ERROR."""
    if status == 0:
        return StatusInfo(Level.OK, 'healthy')
    if status == STATUS_MONITOR_LATCHED:
        return StatusInfo(Level.WARN, 'monitor condition latched (0x80010000)')
    parts = [text for bit, text in _STATUS_BITS if status & bit]
    if status & STATUS_ERROR_SUMMARY:
        parts.append('error summary')
    known = STATUS_ERROR_SUMMARY | sum(bit for bit, _ in _STATUS_BITS)
    if status & ~known:
        parts.append('other bits set')
    return StatusInfo(Level.ERROR, f'{", ".join(parts)} (0x{status:08X})')


def is_error_status(status: int) -> bool:
    """True when a record with this status word is not a valid measurement (level ERROR:
    error bits such as 0x80020000; a latched monitor 0x80010000 alone is only a warning)."""
    return status != 0 and decode_status(status).level == Level.ERROR

