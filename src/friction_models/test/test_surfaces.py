# SPDX-License-Identifier: Apache-2.0
"""Contact surfaces and pressure maps (spec §1, §3, §6.1; check A7)."""
from __future__ import annotations

import numpy as np
import pytest

from friction_models.core.surfaces import (ContactSurface, circle, line, line_grad, soft_finger,
                                           square, standard_surface)

MM = 1e-3


@pytest.mark.parametrize('name, cells, cop_mm', [
    ('square', 441, (0.0, 0.0)),
    ('circle', 317, (0.0, 0.0)),
    ('line', 21, (0.0, 0.0)),
    ('line_grad', 21, (0.0, 3.175)),
    ('LineGradX', 21, (-3.175, 0.0)),
    ('NonConvex1', 18, (0.0, 0.0)),
    ('non_convex_2', 84, (2.619, -0.238)),
])
def test_canonical_surfaces(name: str, cells: int, cop_mm: tuple[float, float]) -> None:
    s = standard_surface(name)
    assert s.n_active == cells
    assert s.pressure.sum() == pytest.approx(1.0, abs=1e-14)
    np.testing.assert_allclose(np.array(s.cop) / MM, cop_mm, atol=1e-3)


@pytest.mark.parametrize('name, r_a_mm', [
    ('square', 7.645), ('circle', 6.380), ('line', 4.989), ('line_grad', 4.040)])
def test_one_point_characteristic_radius(name: str, r_a_mm: float) -> None:
    """A7 (one point per cell column of the spec §6.1 table)."""
    assert standard_surface(name).r_a_cells / MM == pytest.approx(r_a_mm, abs=1e-3)


def test_grid_convention_is_image_order() -> None:
    """Row 0 is the top (+y), column 0 the left (−x); [j, i] indexing."""
    s = square(3, 0.003)
    x, y = s.cell_centres()
    np.testing.assert_allclose(x[0], [-1e-3, 0.0, 1e-3], atol=1e-18)
    np.testing.assert_allclose(y[:, 0], [1e-3, 0.0, -1e-3], atol=1e-18)
    # Largest LineGrad pressure sits at the +y edge (row 0).
    lg = line_grad(21)
    assert lg.pressure[0, 10] == lg.pressure.max() and lg.cop[1] > 0


def test_layout_conversion_at_the_boundary() -> None:
    rng = np.random.default_rng(0)
    p = rng.random((4, 6))
    ji = ContactSurface.from_array(p, 1e-3)
    ij = ContactSurface.from_array(p.T, 1e-3, layout='ij')
    flat = ContactSurface.from_array(p.ravel(), 1e-3, layout='flat', shape=(4, 6))
    for other in (ij, flat):
        np.testing.assert_array_equal(other.pressure, ji.pressure)
        assert other.cop == ji.cop


def test_scaling_by_k() -> None:
    s = line_grad(21, 0.02)
    big = s.scaled(2.5)
    np.testing.assert_allclose(big.cop, 2.5 * np.array(s.cop), rtol=1e-14)
    assert big.r_a_cells == pytest.approx(2.5 * s.r_a_cells, rel=1e-14)
    assert big.second_moment == pytest.approx(6.25 * s.second_moment, rel=1e-14)
    assert big.shape_key() == s.shape_key() and big.same_shape_as(s)


def test_even_line_uses_two_half_columns() -> None:
    s = line(20, 0.02)
    assert s.n_active == 40 and s.cop[0] == pytest.approx(0.0, abs=1e-18)


def test_custom_masks_arrays_and_pressure_units() -> None:
    mask = np.zeros((5, 5), dtype=bool)
    mask[0, 0] = mask[4, 4] = True            # non-convex two-point contact
    s = ContactSurface.from_mask(mask, 1e-3)
    assert s.cop == pytest.approx((0.0, 0.0), abs=1e-18)
    assert s.r_a_cells == pytest.approx(np.hypot(2e-3, 2e-3))
    pa = ContactSurface.from_array(np.full((10, 10), 2e4), 1e-3)   # 20 kPa over 1 cm²
    assert pa.total_normal_force == pytest.approx(2.0)
    with pytest.raises(ValueError):
        ContactSurface.from_array(np.zeros((3, 3)), 1e-3)
    with pytest.raises(ValueError):
        ContactSurface.from_array(-np.ones((3, 3)), 1e-3)
    with pytest.raises(ValueError, match='unknown surface'):
        standard_surface('triangle')


def test_soft_finger_grows_with_load() -> None:
    small, large = soft_finger(0.2), soft_finger(3.0)
    assert small.n_active < large.n_active
    assert small.r_a_cells < large.r_a_cells
    sharp = soft_finger(3.0, k=None)          # exponent k = f_n/0.5 = 6
    assert sharp.pressure.max() / sharp.pressure[sharp.pressure > 0].min() < \
        large.pressure.max() / large.pressure[large.pressure > 0].min()
    assert np.hypot(*large.cop) < 1e-15


def test_circle_equal_area_radius() -> None:
    s = circle(21, 0.02)
    r_eq = np.sqrt(s.n_active / np.pi) * s.cell_size
    assert r_eq / 0.01 == pytest.approx(0.957, abs=2e-3)
