# SPDX-License-Identifier: Apache-2.0
"""Host-side F/T bias (tare): average a window of raw wrenches per sensor (ROS-free).

The one bias procedure of the cell: the drivers' F/T channels (``gripper/bias_ft``,
``finger_k/ft/bias``) and the simulated cell run `BiasAccumulator` with `BiasParams`.
"""
from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field
from enum import IntEnum
from collections.abc import Sequence

from slip_cell_common.core.validation import validate_fields
from slip_gripper_driver.core.ft_scale import Wrench

#: Extra time for a bias window to close after ``bias.duration`` before it fails [s].
BIAS_TIMEOUT_S = 0.5


class BiasState(IntEnum):
    """Host-side bias procedure state."""

    IDLE = 0
    COLLECTING = 1
    DONE = 2
    FAILED = 3


class BiasAccumulator:
    """Host-side tare (hardware_protocols §4.7): average a window of wrenches.

    After `start`, the first ``settle_samples`` samples are skipped, then every sample whose
    stamp lies within ``duration_s`` of the first averaged one is averaged. The window closes
    with the first sample past it; with fewer than ``min_samples`` the bias fails (the previous
    offsets stay). Without samples, `poll` fails it after ``duration_s + timeout_s``.

    A window after a device bias (``start(t, after_device_bias=True)``) opens only with the
    first sample of the box's new stream (``add(..., new_stream=True)``): samples of the old
    stream still carry the old tare. Such a window that fails drops the offsets
    (`tare_lost`): the box subtracts a new tare now, so the old offsets no longer fit.

    Args:
        duration_s: Averaging window [s] (0.1 s).
        min_samples: Fewest samples for a valid bias (50).
        settle_samples: Samples skipped first (2).
        timeout_s: Extra time allowed for samples to arrive [s].
    """

    def __init__(self, duration_s: float = 0.1, min_samples: int = 50, settle_samples: int = 2,
                 timeout_s: float = 0.5) -> None:
        if duration_s <= 0.0 or min_samples < 1 or settle_samples < 0:
            raise ValueError('need duration_s > 0, min_samples >= 1, settle_samples >= 0')
        self.duration_s = duration_s
        self.min_samples = min_samples
        self.settle_samples = settle_samples
        self.timeout_s = timeout_s
        self._lock = threading.Lock()
        self.offsets: Wrench | None = None
        self.state = BiasState.IDLE
        self.message = 'not biased'
        self._start = math.nan
        self._first = math.nan
        self._skipped = 0
        self._count = 0
        self._sum = [0.0] * 6
        self._after_device_bias = False
        self._awaiting_stream = False
        self.tare_lost = False  #: a device-bias window failed: offsets dropped (see above)

    @property
    def biased(self) -> bool:
        """True once valid offsets exist."""
        return self.offsets is not None

    def start(self, t: float, after_device_bias: bool = False) -> None:
        """Begin collecting at ``t`` [s]; ``after_device_bias``: the box was just told to tare
        itself and starts a new stream, with which the window opens."""
        with self._lock:
            self._open(t)
            self.message = 'collecting'
            self._after_device_bias = self._awaiting_stream = after_device_bias
            self.tare_lost = False

    def _open(self, t: float) -> None:
        self.state = BiasState.COLLECTING
        self._start = t
        self._first = math.nan
        self._skipped = 0
        self._count = 0
        self._sum = [0.0] * 6

    def clear(self, message: str = 'not biased') -> None:
        """Drop the offsets (unbiased) and end a collection; ``message`` says why."""
        with self._lock:
            self.offsets = None
            self.state = BiasState.IDLE
            self.message = message
            self._awaiting_stream = False

    def add(self, t: float, wrench: Sequence[float],
            new_stream: bool = False) -> Wrench | None:
        """Feed one raw wrench (N, N·m) stamped ``t`` [s]; returns it bias-removed or None.

        ``new_stream``: the first sample of a stream the box started (numbering from 1).
        """
        with self._lock:
            if self.state == BiasState.COLLECTING:
                if self._awaiting_stream and new_stream:
                    self._awaiting_stream = False
                    self._open(t)  # the tared stream: the window opens here
                if not self._awaiting_stream:
                    self._collect(t, wrench)
            off = self.offsets
        if off is None:
            return None
        return (wrench[0] - off[0], wrench[1] - off[1], wrench[2] - off[2],
                wrench[3] - off[3], wrench[4] - off[4], wrench[5] - off[5])

    def poll(self, t: float) -> BiasState:
        """Fail a collection that received too few samples by time ``t`` [s]."""
        with self._lock:
            if self.state == BiasState.COLLECTING and \
                    t - self._start > self.duration_s + self.timeout_s:
                self._finish()
            return self.state

    def _collect(self, t: float, wrench: Sequence[float]) -> None:
        if not all(math.isfinite(v) for v in wrench):
            return
        if self._skipped < self.settle_samples:
            self._skipped += 1
            return
        if math.isnan(self._first):
            self._first = t
        if t - self._first > self.duration_s:
            self._finish()
            return
        self._count += 1
        for i in range(6):
            self._sum[i] += wrench[i]

    def _finish(self) -> None:
        if self._count >= self.min_samples:
            n = self._count
            s = self._sum
            self.offsets = (s[0] / n, s[1] / n, s[2] / n, s[3] / n, s[4] / n, s[5] / n)
            self.state = BiasState.DONE
            self.message = f'biased with {n} samples'
        else:
            self.state = BiasState.FAILED
            self.message = f'bias failed: {self._count} samples, {self.min_samples} required'
            if self._awaiting_stream:
                self.message = ('device bias failed: the box started no new stream after the '
                                'bias command (0x0042)')
            if self._after_device_bias:
                # The box subtracts a new tare now: offsets taken over the old one are wrong.
                self.offsets = None
                self.tare_lost = True
                self.message += '; the previous bias no longer applies'
        self._awaiting_stream = False


@dataclass(frozen=True)
class BiasParams:
    """F/T bias procedure (parameter group ``bias``)."""

    mode: str = field(default='host', metadata={
        'choices': ('host', 'device'), 'description': 'host-side average or box command 0x0042'})
    duration: float = field(default=0.1, metadata={
        'unit': 's', 'range': (0.01, 10.0), 'description': 'averaging window'})
    min_samples: int = field(default=50, metadata={
        'range': (1, 100000), 'description': 'fewest samples for a valid bias'})
    settle_samples: int = field(default=2, metadata={
        'range': (0, 1000), 'description': 'samples skipped before averaging'})
    on_activate: bool = field(default=False, metadata={
        'description': 'bias automatically on activation'})

    def validate(self) -> None:
        """Raise `ParameterError` listing every invalid field."""
        validate_fields(self)

    def accumulator(self, timeout_s: float = BIAS_TIMEOUT_S) -> BiasAccumulator:
        """A `BiasAccumulator` with these settings."""
        return BiasAccumulator(self.duration, self.min_samples, self.settle_samples, timeout_s)


def bias_outcome(windows: Sequence[tuple[str, BiasAccumulator]]) -> tuple[bool, str]:
    """``(every window succeeded, one message naming each)`` for ``(name, accumulator)``
    pairs whose windows have closed."""
    ok = all(acc.state == BiasState.DONE for _, acc in windows)
    return ok, '; '.join(f'{name}: {acc.message}' for name, acc in windows)
