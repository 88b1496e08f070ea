# SPDX-License-Identifier: Apache-2.0
"""Statistics of a population run: rates with confidence intervals, distributions, splits."""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

#: Two-sided 95 % standard-normal quantile.
Z_95 = 1.959963984540054


@dataclass(frozen=True)
class Rate:
    """A success rate ``k/n`` with its Wilson score 95 % interval."""

    successes: int
    trials: int
    low: float
    high: float

    @property
    def value(self) -> float:
        """``k/n`` (NaN when ``n = 0``)."""
        return self.successes / self.trials if self.trials else math.nan


def wilson_interval(successes: int, trials: int, z: float = Z_95) -> Rate:
    """Wilson score interval of a binomial proportion (well-behaved near 0 and 1).

    Raises:
        ValueError: ``successes`` outside ``[0, trials]``.
    """
    if trials < 0 or not 0 <= successes <= max(trials, 0):
        raise ValueError(f'need 0 <= successes <= trials, got {successes}/{trials}')
    if trials == 0:
        return Rate(0, 0, math.nan, math.nan)
    p = successes / trials
    denom = 1.0 + z * z / trials
    centre = (p + z * z / (2.0 * trials)) / denom
    half = z * math.sqrt(p * (1.0 - p) / trials + z * z / (4.0 * trials * trials)) / denom
    return Rate(successes, trials, max(0.0, centre - half), min(1.0, centre + half))


@dataclass(frozen=True)
class Distribution:
    """Summary of a sample of one error quantity (finite values only)."""

    count: int
    median: float
    p90: float
    max: float


def distribution(values: Sequence[float], *, absolute: bool = True) -> Distribution:
    """Median, 90th percentile and maximum of ``|values|`` (or the signed values)."""
    a = np.asarray([v for v in values if v is not None and math.isfinite(v)], dtype=float)
    if absolute:
        a = np.abs(a)
    if a.size == 0:
        return Distribution(0, math.nan, math.nan, math.nan)
    return Distribution(int(a.size), float(np.median(a)), float(np.percentile(a, 90)),
                        float(a.max()))


@dataclass(frozen=True)
class Split:
    """The single threshold on one parameter that best separates failures from successes.

    Attributes:
        parameter: Parameter name.
        threshold: Threshold value (in the parameter's unit).
        failures_above: Failures lie above the threshold (else below).
        failure_rate_inside: Failure rate on the failing side.
        failure_rate_outside: Failure rate on the other side.
        count_inside: Objects on the failing side.
        accuracy: Share of objects the split classifies right.
    """

    parameter: str
    threshold: float
    failures_above: bool
    failure_rate_inside: float
    failure_rate_outside: float
    count_inside: int
    accuracy: float


def best_split(parameters: Mapping[str, Sequence[float]], failed: Sequence[bool]) -> Split | None:
    """The parameter and threshold that best separate ``failed`` from not failed.

    Every midpoint between sorted distinct values of every parameter is tried; the split with
    the highest classification accuracy wins (ties: the larger failure-rate contrast). Returns
    None when there are no failures or no successes.
    """
    f = np.asarray(failed, dtype=bool)
    if f.size == 0 or f.all() or not f.any():
        return None
    best: tuple[float, float, Split] | None = None
    for name, values in parameters.items():
        x = np.asarray(values, dtype=float)
        if x.size != f.size or not np.isfinite(x).all():
            continue
        distinct = np.unique(x)
        for lo, hi in zip(distinct[:-1], distinct[1:]):
            thr = 0.5 * (lo + hi)
            above = x > thr
            for failures_above in (True, False):
                inside = above if failures_above else ~above
                acc = float(np.mean(inside == f))
                rate_in = float(f[inside].mean()) if inside.any() else 0.0
                rate_out = float(f[~inside].mean()) if (~inside).any() else 0.0
                key = (acc, rate_in - rate_out)
                if best is None or key > best[:2]:
                    best = (acc, rate_in - rate_out,
                            Split(name, float(thr), failures_above, rate_in, rate_out,
                                  int(inside.sum()), acc))
    return None if best is None else best[2]
