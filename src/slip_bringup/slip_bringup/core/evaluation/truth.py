# SPDX-License-Identifier: Apache-2.0
"""Simulator truth sampled during a scenario (the judge of every outcome; SI units)."""
from __future__ import annotations

import math
from collections.abc import Callable

from friction_models.core.harness import Harness
from friction_models.core.sensors import TelemetrySample

from slip_bringup.core.evaluation.poses import rotated

_NAN = math.nan


def centre_point_displacement(x0: float, y0: float, theta0: float, x: float, y: float,
                              theta: float) -> tuple[float, float]:
    """Displacement ``(dx, dy)`` [m, ``gripper_middle`` axes] of the object point that sat at
    the gripper centre at a reference instant.

    The truth tracks one material point, the one at the gripper centre when the grasp closed;
    after earlier slips it lies ``(x0, y0)`` off the centre, and a rotation relative to the pads
    alone would carry it on a circle (an apparent translation of ``2·|(x0, y0)|·sin(Δθ/2)``).
    The object moves rigidly in the pad frame, so the point that was at the centre when the
    tracked point was at ``(x0, y0)`` with relative rotation ``theta0`` [rad] is now at
    ``(x, y) − R(θ − θ0)·(x0, y0)``.
    """
    ox, oy = rotated((x0, y0), theta - theta0)
    return x - ox, y - oy


class TruthProbe:
    """Samples the simulator truth on every ``every``-th telemetry line (lists, SI)."""

    def __init__(self, every: int = 1) -> None:
        self.every = every
        self._n = 0
        self.t: list[float] = []
        self.x: list[float] = []
        self.y: list[float] = []
        self.theta: list[float] = []
        self.normal_force: list[float] = []
        self.object_theta: list[float] = []
        self.object_y: list[float] = []
        self.in_grasp: list[bool] = []
        self.dropped: list[bool] = []

    def on_telemetry(self, harness: Harness, sample: TelemetrySample) -> None:
        """Record one row."""
        self._n += 1
        if self._n % self.every:
            return
        s = harness.cell.state()
        self.t.append(s.stamp)
        self.x.append(s.x)
        self.y.append(s.y)
        self.theta.append(s.theta)
        self.normal_force.append(s.normal_force_1)
        self.object_theta.append(s.object_theta)
        self.object_y.append(s.object_y)
        self.in_grasp.append(s.in_grasp)
        self.dropped.append(s.dropped)

    def indices(self, t0: float, t1: float) -> range:
        """Row indices with ``t0 ≤ t ≤ t1`` (rows are in time order)."""
        lo = next((i for i, t in enumerate(self.t) if t >= t0 - 1e-12), len(self.t))
        hi = lo
        while hi < len(self.t) and self.t[hi] <= t1 + 1e-12:
            hi += 1
        return range(lo, hi)

    def at(self, t: float) -> int:
        """Index of the first row with ``t_row ≥ t`` (the last row if none) [s]."""
        lo, hi = 0, len(self.t)
        while lo < hi:
            mid = (lo + hi) // 2
            if self.t[mid] < t - 1e-12:
                lo = mid + 1
            else:
                hi = mid
        return min(lo, len(self.t) - 1)

    def displacement(self, i: int, x0: float, y0: float, theta0: float) -> tuple[float, float]:
        """`centre_point_displacement` at row ``i`` from the reference ``(x0, y0, theta0)``."""
        return centre_point_displacement(x0, y0, theta0, self.x[i], self.y[i], self.theta[i])

    def peak_displacement(self, t0: float, t1: float, x0: float, y0: float,
                          theta0: float) -> float:
        """Largest displacement [m] in the window of the object point that was at the gripper
        centre at the reference ``(x0, y0, theta0)`` (`centre_point_displacement`)."""
        return max((math.hypot(*self.displacement(i, x0, y0, theta0))
                    for i in self.indices(t0, t1)), default=0.0)

    def peak_rotation(self, t0: float, t1: float, th0: float) -> float:
        """Largest ``|θ − θ0|`` in the window [rad]."""
        return max((abs(self.theta[i] - th0) for i in self.indices(t0, t1)), default=0.0)


def interp_progress(probe: TruthProbe, progress: Callable[[int], float], t: float) -> float:
    """True progress at time ``t`` (nearest probe rows, linear interpolation)."""
    ts = probe.t
    if not ts:
        return _NAN
    lo = 0
    hi = len(ts) - 1
    if t <= ts[0]:
        return progress(0)
    if t >= ts[-1]:
        return progress(hi)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if ts[mid] <= t:
            lo = mid
        else:
            hi = mid
    a = (t - ts[lo]) / (ts[hi] - ts[lo])
    return progress(lo) + a * (progress(hi) - progress(lo))
