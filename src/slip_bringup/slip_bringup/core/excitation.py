# SPDX-License-Identifier: Apache-2.0
"""Is there an excitation in a recorded force command? (control_and_estimation §6.2)

A frequency response is only meaningful where the commanded force holds the sine it is
measured at. Each candidate segment of the command is fitted by least squares with
``c + a·sin(2πft) + b·cos(2πft)`` on its own stamps (no resampling, so irregular command
rates are fine); the segment counts as excited when the fitted amplitude is close to the
expected one and the sine explains most of the command's variance. A constant command, a step
or a controller's irregular output explains almost nothing and is rejected.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike


@dataclass(frozen=True, slots=True)
class SineFit:
    """Least-squares sine fit of one command segment.

    Attributes:
        frequency_hz: Fitted frequency [Hz] (given, not searched).
        amplitude: Amplitude of the fitted sine [N].
        offset: Mean of the fit [N].
        explained: Fraction of the segment's variance the sine explains [0, 1] (0 for a
            constant segment).
        n: Samples in the segment.
    """

    frequency_hz: float
    amplitude: float
    offset: float
    explained: float
    n: int


def fit_sine(t: ArrayLike, y: ArrayLike, frequency_hz: float) -> SineFit:
    """Fit ``c + a·sin(2πft) + b·cos(2πft)`` to the finite samples of ``(t, y)``.

    Raises:
        ValueError: ``frequency_hz`` is not a finite positive number.
    """
    if not (math.isfinite(frequency_hz) and frequency_hz > 0.0):
        raise ValueError(f'frequency must be finite and > 0, got {frequency_hz!r}')
    ta = np.asarray(t, dtype=np.float64)
    ya = np.asarray(y, dtype=np.float64)
    ok = np.isfinite(ta) & np.isfinite(ya)
    ta, ya = ta[ok], ya[ok]
    if ta.size < 4:
        return SineFit(frequency_hz, 0.0, float(ya.mean()) if ya.size else math.nan, 0.0,
                       int(ta.size))
    phase = 2.0 * math.pi * frequency_hz * (ta - ta[0])
    basis = np.column_stack([np.ones_like(ta), np.sin(phase), np.cos(phase)])
    coef, *_ = np.linalg.lstsq(basis, ya, rcond=None)
    residual = ya - basis @ coef
    total = float(np.sum((ya - ya.mean()) ** 2))
    explained = 0.0 if total <= 1e-12 else max(0.0, 1.0 - float(np.sum(residual ** 2)) / total)
    return SineFit(frequency_hz, float(math.hypot(coef[1], coef[2])), float(coef[0]),
                   explained, int(ta.size))


def is_excited(fit: SineFit, amplitude: float, *, amplitude_tolerance: float = 0.25,
               min_explained: float = 0.9) -> bool:
    """The segment holds the expected sine: amplitude within ``±amplitude_tolerance``
    (relative) of ``amplitude`` [N] and at least ``min_explained`` of the variance."""
    return (fit.n >= 4 and fit.explained >= min_explained
            and abs(fit.amplitude - amplitude) <= amplitude_tolerance * abs(amplitude))
