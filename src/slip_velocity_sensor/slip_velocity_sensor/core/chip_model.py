# SPDX-License-Identifier: Apache-2.0
"""Model of the optical chips' motion counters (hardware_protocols §3.1, §3.2), ROS-free.

Each chip axis reports motion as a signed 8-bit count of resolution steps since the last read.
The firmware reads the chips every ~1.7 ms, so at most ±127 counts (≈ 1.0 mm) per read can be
seen; faster motion is lost. The firmware converts counts with 3200 counts per inch.

`CountQuantizer` turns true displacements into those counts: fractional steps are carried to
the next read (a chip never loses sub-count motion), while counts beyond the saturation limit
are lost (the register clips). It is shared by the firmware emulator and the synthetic
calibration recordings.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

MM_PER_INCH = 25.4


@dataclass(frozen=True)
class ChipModelParams:
    """Counter model of one chip axis (device constants; SI where physical)."""

    counts_per_inch: float = field(default=3200.0, metadata={
        'unit': '1/in', 'range': (100.0, 20000.0),
        'description': 'effective resolution used by the firmware (spec §3.1)'})
    max_counts: int = field(default=127, metadata={
        'unit': 'counts', 'range': (1, 32767), 'description': 'saturation per chip read'})
    poll_period: float = field(default=0.0017, metadata={
        'unit': 's', 'range': (0.0001, 0.1), 'description': 'time between chip reads'})
    count_noise_std: float = field(default=0.0, metadata={
        'unit': 'counts', 'range': (0.0, 100.0),
        'description': 'standard deviation of extra counts per read (0 = ideal chip)'})

    @property
    def metres_per_count(self) -> float:
        """Length of one count [m] (0.0079375 mm at 3200 CPI)."""
        return MM_PER_INCH / self.counts_per_inch / 1000.0


class CountQuantizer:
    """Quantise displacements of several chip axes into saturated integer counts.

    Args:
        n_axes: Number of chip axes modelled together.
        params: Counter model.
        rng: Random generator for count noise (required when ``count_noise_std > 0``).
    """

    def __init__(self, n_axes: int, params: ChipModelParams,
                 rng: np.random.Generator | None = None) -> None:
        if params.count_noise_std > 0.0 and rng is None:
            raise ValueError('count noise needs a seeded rng')
        self.params = params
        self._rng = rng
        self._n = n_axes
        self._scale = 1.0 / params.metres_per_count
        self._carry = [0.0] * n_axes
        self.saturated_reads = 0

    def reset(self) -> None:
        """Forget carried sub-count motion (a chip reset)."""
        self._carry = [0.0] * self._n

    def read_counts(self, displacement: Sequence[float]) -> list[int]:
        """Counts reported for the displacement since the previous read (plain floats).

        The model in scalar form: a handful of axes per read is several times cheaper than
        through numpy (the simulator reads six axes per finger at 120 Hz).

        Args:
            displacement: True displacement of each axis since the last read [m], length n.

        Returns:
            Counts per axis, clipped to ±max_counts.
        """
        scale = self._scale
        steps = [c + d * scale for c, d in zip(self._carry, displacement, strict=True)]
        std = self.params.count_noise_std
        if self._rng is not None and std > 0.0:
            steps = [s + e for s, e in zip(steps, self._rng.normal(0.0, std, self._n).tolist())]
        counts = [math.trunc(s) for s in steps]
        self._carry = [s - c for s, c in zip(steps, counts)]
        limit = self.params.max_counts
        clipped = [min(max(c, -limit), limit) for c in counts]
        if clipped != counts:
            self.saturated_reads += 1
        return clipped

    def read(self, displacement: ArrayLike) -> NDArray[np.int64]:
        """`read_counts` for an array: counts per axis, clipped to ±max_counts, shape (n,)."""
        values = np.asarray(displacement, dtype=np.float64).tolist()
        return np.asarray(self.read_counts(values), dtype=np.int64)


def quantize_series(displacement: ArrayLike, params: ChipModelParams,
                    rng: np.random.Generator | None = None) -> NDArray[np.int64]:
    """Counts of one chip axis for a series of reads (same rules as `CountQuantizer`).

    A scalar loop: for one axis it is much faster than calling `CountQuantizer.read` per poll.

    Args:
        displacement: True displacement between consecutive reads [m], shape (n,).
        params: Counter model.
        rng: Random generator for count noise (required when ``count_noise_std > 0``).

    Returns:
        Counts per read, shape (n,).
    """
    d = np.asarray(displacement, dtype=np.float64) / params.metres_per_count
    if params.count_noise_std > 0.0:
        if rng is None:
            raise ValueError('count noise needs a seeded rng')
        d = d + rng.normal(0.0, params.count_noise_std, d.shape)
    limit = params.max_counts
    out = np.empty(d.shape, dtype=np.int64)
    carry = 0.0
    for i, step in enumerate(d.tolist()):
        total = carry + step
        counts = math.trunc(total)
        carry = total - counts
        out[i] = min(max(counts, -limit), limit)
    return out
