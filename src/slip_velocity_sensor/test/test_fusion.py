# SPDX-License-Identifier: Apache-2.0
"""Host-side rigid-body fusion: exact recovery, one chip off the object, geometry checks."""
from __future__ import annotations

import math

import numpy as np
import pytest

from slip_velocity_sensor.core.fusion import (DEFAULT_CHIP_ANGLES, FusionParams, RigidBodyFusion,
                                              model_matrix)


def _surface_velocity_at_chips(twist: np.ndarray, radius: float,
                               angles: tuple[float, ...]) -> np.ndarray:
    """Independent kinematics: velocity of the surface point under each chip, in chip axes."""
    vx, vy, w = twist
    out = []
    for phi in angles:
        px, py = radius * math.cos(phi), radius * math.sin(phi)
        ux, uy = vx - w * py, vy + w * px                  # v + ω × p
        tangential = (-math.sin(phi), math.cos(phi))       # chip x: CCW
        radial = (math.cos(phi), math.sin(phi))            # chip y: outward
        out += [ux * tangential[0] + uy * tangential[1], ux * radial[0] + uy * radial[1]]
    return np.array(out)


def test_forward_model_matches_rigid_body_kinematics() -> None:
    rng = np.random.default_rng(0)
    fusion = RigidBodyFusion(FusionParams(radius=0.0243))
    for twist in rng.normal(0.0, [0.05, 0.05, 2.0], (50, 3)):
        expected = _surface_velocity_at_chips(twist, 0.0243, DEFAULT_CHIP_ANGLES)
        assert fusion.forward(twist) == pytest.approx(expected, abs=1e-15)


def test_pseudo_inverse_reduces_to_the_firmware_closed_form_for_120_degree_layout() -> None:
    """For 0/120/240° the normal matrix is diag(3, 3, 3d²) (spec §3.4)."""
    d = 0.0243
    a = model_matrix(d, DEFAULT_CHIP_ANGLES)
    assert a.T @ a == pytest.approx(np.diag([3.0, 3.0, 3.0 * d * d]), abs=1e-12)
    rng = np.random.default_rng(1)
    fusion = RigidBodyFusion(FusionParams(radius=d, outlier_threshold=math.inf))
    for r in rng.normal(0.0, 0.05, (20, 6)):
        phis = DEFAULT_CHIP_ANGLES
        closed = (sum(-math.sin(p) * r[2 * i] + math.cos(p) * r[2 * i + 1]
                      for i, p in enumerate(phis)) / 3.0,
                  sum(math.cos(p) * r[2 * i] + math.sin(p) * r[2 * i + 1]
                      for i, p in enumerate(phis)) / 3.0,
                  (r[0] + r[2] + r[4]) / (3.0 * d))
        got = fusion.fuse(r)
        assert (got.vx, got.vy, got.omega) == pytest.approx(closed, abs=1e-12)


@pytest.mark.parametrize('radius', [0.0203, 0.0243, 0.05])
def test_exact_recovery_of_synthetic_rigid_body_motion(radius: float) -> None:
    rng = np.random.default_rng(2)
    fusion = RigidBodyFusion(FusionParams(radius=radius))
    twists = rng.normal(0.0, [0.03, 0.03, 1.5], (200, 3))
    for twist in twists:
        result = fusion.fuse(fusion.forward(twist))
        assert (result.vx, result.vy, result.omega) == pytest.approx(tuple(twist), abs=1e-12)
        assert result.excluded_chip == -1
        assert result.residual_ratio < 1e-9


@pytest.mark.parametrize('chip', [1, 2, 3])
def test_one_chip_off_the_object_is_excluded_and_the_twist_recovered(chip: int) -> None:
    rng = np.random.default_rng(3 + chip)
    fusion = RigidBodyFusion()
    recovered = 0
    for twist in rng.normal(0.0, [0.03, 0.03, 1.0], (200, 3)):
        readings = fusion.forward(twist)
        speeds = np.hypot(readings[0::2], readings[1::2])
        readings[2 * (chip - 1):2 * chip] = 0.0   # off the surface: reads nothing
        result = fusion.fuse(readings)
        if result.residual_ratio <= fusion.params.outlier_threshold:
            continue  # the chip's own motion was too small to show in the residual
        assert result.excluded_chip == chip
        assert (result.vx, result.vy, result.omega) == pytest.approx(tuple(twist), abs=1e-12)
        assert speeds[chip - 1] > 0.0
        recovered += 1
    assert recovered > 150


def test_without_rejection_a_lifted_chip_biases_the_estimate() -> None:
    """Guards the test above: the rejection is what makes recovery exact."""
    twist = np.array([0.02, -0.01, 0.5])
    plain = RigidBodyFusion(FusionParams(outlier_threshold=math.inf))
    readings = plain.forward(twist)
    readings[0:2] = 0.0
    result = plain.fuse(readings)
    assert result.excluded_chip == -1
    assert np.linalg.norm(np.array(result[:3]) - twist) > 0.1 * np.linalg.norm(twist)


def test_tie_of_the_two_slowest_chips_excludes_nothing() -> None:
    fusion = RigidBodyFusion()
    readings = np.array([0.0, 0.0, 0.0, 0.0, 0.02, 0.01])  # two chips read exactly zero
    result = fusion.fuse(readings)
    assert result.residual_ratio > 0.2
    assert result.excluded_chip == -1


def test_residual_ratio_floor_keeps_rest_noise_from_triggering_rejection() -> None:
    fusion = RigidBodyFusion()
    # One count of noise on one chip at rest (≈ 1 mm/s): ratio bounded by the 1 mm/s floor.
    result = fusion.fuse(np.array([0.00095, 0.0, 0.0, 0.0, 0.0, 0.0]))
    assert result.residual_ratio < 0.5
    big = fusion.fuse(np.array([0.095, 0.0, 0.0, 0.0, 0.0, 0.0]))
    assert big.residual_ratio > result.residual_ratio


def test_batch_fusion_equals_scalar_fusion() -> None:
    rng = np.random.default_rng(5)
    fusion = RigidBodyFusion()
    readings = fusion.forward(rng.normal(0.0, [0.03, 0.03, 1.0], (300, 3)))
    lifted = rng.integers(0, 4, 300)
    for i, chip in enumerate(lifted):
        if chip:
            readings[i, 2 * (chip - 1):2 * chip] = 0.0
    twists, excluded, ratio = fusion.fuse_batch(readings)
    for i in range(len(readings)):
        one = fusion.fuse(readings[i])
        assert tuple(twists[i]) == pytest.approx(one[:3], abs=1e-12)
        assert excluded[i] == one.excluded_chip
        assert ratio[i] == pytest.approx(one.residual_ratio)


def test_geometry_is_built_from_parameters_not_hard_coded() -> None:
    angles = (math.radians(200.0), math.radians(100.0), math.radians(-10.0))
    fusion = RigidBodyFusion(FusionParams(radius=0.03, chip_angles=angles))
    twist = np.array([0.01, 0.02, -0.7])
    readings = _surface_velocity_at_chips(twist, 0.03, angles)
    result = fusion.fuse(readings)
    assert result[:3] == pytest.approx(tuple(twist), abs=1e-12)
    readings[2:4] = 0.0
    lifted = fusion.fuse(readings)
    assert lifted.excluded_chip == 2 and lifted[:3] == pytest.approx(tuple(twist), abs=1e-12)


def test_degenerate_geometry_is_refused() -> None:
    with pytest.raises(ValueError, match='undetermined'):
        RigidBodyFusion(FusionParams(chip_angles=(0.0, 0.0, math.pi)))
    with pytest.raises(ValueError):
        RigidBodyFusion(FusionParams(chip_angles=(0.0, 1.0)))
    with pytest.raises(ValueError):
        RigidBodyFusion().fuse(np.zeros(4))
