# SPDX-License-Identifier: Apache-2.0
"""Sequence numbers of RDT records: streams, loss, duplicates, reordering, stalls (ROS-free).

Both ``rdt_sequence`` (per record sent) and ``ft_sequence`` (per measurement) are 32-bit and
wrap; `SequenceTracker` compares them modulo 2³². A real box numbers the records of **each
stream** from 1 and starts a new stream on every start request (hardware_protocols §4.3), while
``ft_sequence`` keeps counting across streams until the box restarts.
"""
from __future__ import annotations

from enum import IntEnum

_SEQ_MOD = 1 << 32
_SEQ_HALF = 1 << 31
#: After a start request, a record numbered at most this opens the new stream (the first
#: records of a stream may be lost on the way).
NEW_STREAM_WINDOW = 64


class SeqVerdict(IntEnum):
    """How a record's ``rdt_sequence`` relates to the previous accepted one."""

    FIRST = 0
    NEW = 1  #: newer (possibly after a gap)
    DUPLICATE = 2
    OLD = 3  #: older within the stream: reordered or late; dropped
    RESYNC = 4  #: accepted after many OLD records in a row (numbering jumped back)
    NEW_STREAM = 5  #: first record of a new stream (numbered from 1 again); accepted at once


class SequenceTracker:
    """Wrap-safe tracking of ``rdt_sequence`` and ``ft_sequence`` across streams.

    ``d = (seq − last) mod 2³²``: 0 is a duplicate, ``0 < d < 2³¹`` is newer (``d − 1``
    records lost), otherwise older (out of order, dropped). A record numbered 1 that does not
    continue the stream (the previous record was not 0), or — after `expect_new_stream` — a
    record numbered at most `NEW_STREAM_WINDOW` that is not a short step forward, opens a new
    stream: it is accepted at once and only the records missing before it (``seq − 1``) count
    as lost. After ``resync_after`` consecutive older records of any other kind the tracker
    follows the new numbering (RESYNC). ``ft_sequence`` not advancing between accepted records
    is a stall; going backwards is a device restart (`restarted` is set for that record).

    Args:
        resync_after: Consecutive older records that force a resynchronisation.
    """

    def __init__(self, resync_after: int = 16) -> None:
        self.resync_after = resync_after
        self.reset()

    def reset(self) -> None:
        """Forget the last sequence numbers and zero the counters."""
        self._last: int | None = None
        self._last_ft: int | None = None
        self._old_run = 0
        self._pending_start = False
        self._since_start = 0
        self.restarted = False
        self.accepted = 0
        self.lost = 0
        self.duplicates = 0
        self.out_of_order = 0
        self.resyncs = 0
        self.new_streams = 0
        self.ft_stalls = 0
        self.ft_restarts = 0

    def expect_new_stream(self) -> None:
        """A start request was sent: the box will number its records from 1 again."""
        self._pending_start = True
        self._since_start = 0

    def _opens_stream(self, seq: int, d: int) -> bool:
        if seq == 1 and self._last != 0:
            return True
        if not self._pending_start or seq > NEW_STREAM_WINDOW:
            return False
        return not 0 < d <= NEW_STREAM_WINDOW

    def update(self, rdt_sequence: int, ft_sequence: int) -> SeqVerdict:
        """Classify one record; only FIRST, NEW, NEW_STREAM and RESYNC records should be used.

        Sets `restarted` when this accepted record's ``ft_sequence`` went backwards.
        """
        self.restarted = False
        last = self._last
        if last is None:
            verdict = SeqVerdict.FIRST
            self.lost += max(0, rdt_sequence - 1) if self._pending_start and \
                rdt_sequence <= NEW_STREAM_WINDOW else 0
            self._pending_start = False
        else:
            d = (rdt_sequence - last) % _SEQ_MOD
            if d == 0 and not (self._pending_start and ft_sequence != self._last_ft):
                self.duplicates += 1  # (a new stream may repeat the number, not the ft count)
                return SeqVerdict.DUPLICATE
            if self._opens_stream(rdt_sequence, d):
                self.new_streams += 1
                self.lost += rdt_sequence - 1
                self._pending_start = False
                verdict = SeqVerdict.NEW_STREAM
            elif d < _SEQ_HALF:
                self.lost += d - 1
                verdict = SeqVerdict.NEW
            else:
                self._old_run += 1
                if self._old_run < self.resync_after:
                    self.out_of_order += 1
                    return SeqVerdict.OLD
                self.resyncs += 1
                verdict = SeqVerdict.RESYNC
        if self._pending_start:
            self._since_start += 1
            if self._since_start > NEW_STREAM_WINDOW:  # the box kept its numbering
                self._pending_start = False
        self._old_run = 0
        self._last = rdt_sequence
        if self._last_ft is not None:
            dft = (ft_sequence - self._last_ft) % _SEQ_MOD
            if dft == 0:
                self.ft_stalls += 1
            elif dft >= _SEQ_HALF:
                self.ft_restarts += 1
                self.restarted = True
        self._last_ft = ft_sequence
        self.accepted += 1
        return verdict
