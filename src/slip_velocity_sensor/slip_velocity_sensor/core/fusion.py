# SPDX-License-Identifier: Apache-2.0
"""Rigid-body fusion of the three optical chips with one-chip-off outlier rejection (ROS-free).

Model (hardware_protocols §3.4). Chip i sits at radius d and angle φ_i in the sensor
frame; its x axis is tangential (counter-clockwise) and its y axis radial (outward). For a
surface moving with twist (vx, vy, ω) relative to the sensor, chip i reads::

    vx_i = −sin(φ_i)·vx + cos(φ_i)·vy + d·ω
    vy_i =  cos(φ_i)·vx + sin(φ_i)·vy

Stacking the chips as r = (vx_1, vy_1, vx_2, vy_2, vx_3, vy_3) gives r = A·(vx, vy, ω) with a
6×3 model matrix A. The fused twist is the least-squares solution A⁺·r; the pseudo-inverses
(all chips, and each chip left out) are computed from A, never hard-coded, so any radius or
chip layout works as long as every pair of chips still determines the twist.

Outlier rejection (one chip off the object, which then reads ≈ 0)::

    e_r = ‖r − A·A⁺·r‖ / (‖r‖ + floor)          floor = 1 mm/s

If e_r > threshold (0.2), the chip with the smallest speed √(vx_i² + vy_i²) is dropped and the
twist is solved from the other two; when the two smallest speeds tie, nothing is dropped.

Units: any consistent set; the host uses SI (m/s, m, rad/s). The forward model is exact and
also drives the firmware emulator and the tests.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

#: Chip angles φ_1, φ_2, φ_3 [rad] of the sensor ring (240°, 120°, 0°).
DEFAULT_CHIP_ANGLES = (math.radians(240.0), math.radians(120.0), 0.0)


@dataclass(frozen=True)
class FusionParams:
    """Geometry and outlier-rejection settings of the host-side fusion (SI)."""

    radius: float = field(default=0.0243, metadata={
        'unit': 'm', 'range': (0.001, 0.5), 'description': 'chip distance from the sensor centre'})
    chip_angles: tuple[float, ...] = field(default=DEFAULT_CHIP_ANGLES, metadata={
        'unit': 'rad', 'range': (-2.0 * math.pi, 2.0 * math.pi),
        'description': 'angle of chips 1, 2, 3 in the sensor frame'})
    outlier_threshold: float = field(default=0.2, metadata={
        'unit': '-', 'range': (0.0, 10.0),
        'description': 'residual ratio above which the slowest chip is dropped'})
    residual_floor: float = field(default=0.001, metadata={
        'unit': 'm/s', 'range': (0.0, 1.0),
        'description': 'added to the reading norm in the residual ratio (1 mm/s)'})
    tie_tolerance: float = field(default=1e-9, metadata={
        'unit': 'm/s', 'range': (0.0, 1.0),
        'description': 'two slowest chip speeds closer than this count as a tie'})

    def validate(self) -> None:
        """Raise ValueError when the geometry is unusable."""
        if len(self.chip_angles) < 3:
            raise ValueError('at least three chips are needed for outlier rejection')
        if not (math.isfinite(self.radius) and self.radius > 0.0):
            raise ValueError(f'radius must be > 0 m, got {self.radius!r}')


class FusionResult(NamedTuple):
    """Fused twist of the surface relative to the sensor (sensor frame).

    Attributes:
        vx: [m/s] (or the speed unit of the readings).
        vy: [m/s].
        omega: [rad/s].
        excluded_chip: Chip number 1..n dropped as off the object, or -1.
        residual_ratio: e_r of the all-chip fit [-] (the quantity the rejection tests).
    """

    vx: float
    vy: float
    omega: float
    excluded_chip: int
    residual_ratio: float


def model_matrix(radius: float, chip_angles: tuple[float, ...]) -> NDArray[np.float64]:
    """Model matrix A, shape (2n, 3), mapping (vx, vy, ω) to stacked chip readings.

    Args:
        radius: Chip distance d from the sensor centre [m].
        chip_angles: Angle φ_i of each chip [rad].
    """
    rows = []
    for phi in chip_angles:
        s, c = math.sin(phi), math.cos(phi)
        rows.append((-s, c, radius))  # tangential (CCW) axis
        rows.append((c, s, 0.0))      # radial (outward) axis
    return np.asarray(rows, dtype=np.float64)


class RigidBodyFusion:
    """Least-squares fusion of chip readings with one-chip-off rejection.

    Args:
        params: Geometry and rejection settings.

    Raises:
        ValueError: When the geometry leaves the twist undetermined with one chip removed.
    """

    def __init__(self, params: FusionParams | None = None) -> None:
        self.params = params if params is not None else FusionParams()
        self.params.validate()
        self.n_chips = len(self.params.chip_angles)
        a = model_matrix(self.params.radius, self.params.chip_angles)
        self._a = a
        self._pinv = np.linalg.pinv(a)
        self._residual_map = np.eye(2 * self.n_chips) - a @ self._pinv
        # For each dropped chip: a (3, 2n) solver whose columns for that chip are zero.
        self._pinv_without = np.zeros((self.n_chips, 3, 2 * self.n_chips))
        for k in range(self.n_chips):
            keep = np.ones(2 * self.n_chips, dtype=bool)
            keep[2 * k:2 * k + 2] = False
            sub = a[keep]
            if np.linalg.matrix_rank(sub) < 3:
                raise ValueError(f'twist is undetermined without chip {k + 1}; check chip_angles')
            self._pinv_without[k][:, keep] = np.linalg.pinv(sub)

    @property
    def matrix(self) -> NDArray[np.float64]:
        """Model matrix A, shape (2n, 3) (a copy)."""
        return self._a.copy()

    def forward(self, twist: ArrayLike) -> NDArray[np.float64]:
        """Chip readings of a rigid-body twist.

        Args:
            twist: (vx, vy, ω) [m/s, m/s, rad/s], shape (3,) or (N, 3).

        Returns:
            Readings (vx_1, vy_1, ..., vx_n, vy_n) in the chip frames [m/s], shape (2n,)
            or (N, 2n).
        """
        return np.asarray(twist, dtype=np.float64) @ self._a.T

    def fuse(self, readings: ArrayLike) -> FusionResult:
        """Fuse one set of chip readings.

        Args:
            readings: (vx_1, vy_1, ..., vx_n, vy_n) [m/s], chip frames, shape (2n,).
        """
        r = np.asarray(readings, dtype=np.float64)
        if r.shape != (2 * self.n_chips,):
            raise ValueError(f'expected {2 * self.n_chips} readings, got shape {r.shape}')
        p = self.params
        norm_r = math.sqrt(float(r @ r))
        res = self._residual_map @ r
        ratio = math.sqrt(float(res @ res)) / (norm_r + p.residual_floor)
        excluded = -1
        if ratio > p.outlier_threshold:
            excluded = self._slowest_chip(r)
        solver = self._pinv if excluded < 0 else self._pinv_without[excluded - 1]
        vx, vy, omega = solver @ r
        return FusionResult(float(vx), float(vy), float(omega), excluded, ratio)

    def fuse_batch(self, readings: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.int64],
                                                       NDArray[np.float64]]:
        """Vectorised `fuse` over many sets of readings.

        Args:
            readings: Shape (N, 2n) [m/s].

        Returns:
            ``(twists (N, 3), excluded_chip (N,), residual_ratio (N,))``.
        """
        r = np.asarray(readings, dtype=np.float64)
        if r.ndim != 2 or r.shape[1] != 2 * self.n_chips:
            raise ValueError(f'expected shape (N, {2 * self.n_chips}), got {r.shape}')
        p = self.params
        res = r @ self._residual_map.T
        ratio = np.linalg.norm(res, axis=1) / (np.linalg.norm(r, axis=1) + p.residual_floor)
        speeds = np.hypot(r[:, 0::2], r[:, 1::2])
        order = np.argsort(speeds, axis=1, kind='stable')
        rows = np.arange(r.shape[0])
        gap = speeds[rows, order[:, 1]] - speeds[rows, order[:, 0]]
        excluded = np.where((ratio > p.outlier_threshold) & (gap > p.tie_tolerance),
                            order[:, 0] + 1, -1)
        twists = r @ self._pinv.T
        for k in range(self.n_chips):
            sel = excluded == k + 1
            if np.any(sel):
                twists[sel] = r[sel] @ self._pinv_without[k].T
        return twists, excluded.astype(np.int64), ratio

    def _slowest_chip(self, r: NDArray[np.float64]) -> int:
        """Chip number of the unique slowest chip, or -1 on a tie."""
        speeds = [math.hypot(r[2 * k], r[2 * k + 1]) for k in range(self.n_chips)]
        order = sorted(range(self.n_chips), key=speeds.__getitem__)
        if speeds[order[1]] - speeds[order[0]] <= self.params.tie_tolerance:
            return -1
        return order[0] + 1
