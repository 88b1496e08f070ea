# SPDX-License-Identifier: Apache-2.0
"""Pre-computed limit surface: values, symmetry, lookup, scaling, cache (spec §6.1-§6.5)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from friction_models.core.distributed import steady_state_wrenches
from friction_models.core.limit_surface import (LimitSurface, LimitSurfaceCache, cache_key,
                                                characteristic_radius)
from friction_models.core.params import LuGreParams
from friction_models.core.surfaces import (STANDARD_SURFACES, ContactSurface, line_grad,
                                           square, standard_surface)

MM = 1e-3
COULOMB = LuGreParams(mu_s=1.0, sigma2=0.0)


@pytest.fixture(scope='module')
def tables() -> dict[str, LimitSurface]:
    return {name: LimitSurface.build(standard_surface(name), 20) for name in STANDARD_SURFACES}


@pytest.mark.parametrize('name, r_a_mm, s_v3', [
    ('square', 7.625, 1.144), ('circle', 6.357, 1.134), ('line', 4.950, 1.357),
    ('line_grad', 3.988, 1.458)])
def test_bilinear_radius_and_viscous_scale(name: str, r_a_mm: float, s_v3: float,
                                           tables: dict[str, LimitSurface]) -> None:
    """A7: r_a (bilinear, reference method) and s_v,3 = J_c/r_a² of the spec tables."""
    s = standard_surface(name)
    assert tables[name].r_a / MM == pytest.approx(r_a_mm, abs=1e-3)
    assert characteristic_radius(s) == pytest.approx(tables[name].r_a, rel=1e-14)
    assert s.second_moment / tables[name].r_a ** 2 == pytest.approx(s_v3, abs=1e-3)


@pytest.mark.parametrize('name', STANDARD_SURFACES)
def test_poles(name: str, tables: dict[str, LimitSurface]) -> None:
    """Pure translation: h = −v̂, no torque about the CoP; rotation about the CoP: h_τ = −1."""
    t = tables[name].table
    n = tables[name].n_ls
    theta = np.arange(4 * n + 1) * math.pi / (2 * n)
    np.testing.assert_allclose(t[:, n, 0], -np.cos(theta), atol=1e-12)
    np.testing.assert_allclose(t[:, n, 1], -np.sin(theta), atol=1e-12)
    np.testing.assert_allclose(t[:, n, 2], 0.0, atol=1e-12)
    np.testing.assert_allclose(t[:, 0, 2], -1.0, atol=1e-12)


@pytest.mark.parametrize('name', ['circle', 'line_grad', 'non_convex_2'])
def test_nodes_equal_the_distributed_steady_state(name: str,
                                                  tables: dict[str, LimitSurface]) -> None:
    """Every node equals an independent evaluation of the bilinear steady state (§6.4)."""
    s = standard_surface(name)
    ls = tables[name]
    n, r_a = ls.n_ls, ls.r_a
    cx, cy = s.cop
    rng = np.random.default_rng(0)
    rs, iis = rng.integers(0, 4 * n + 1, 60), rng.integers(0, n, 60)
    theta, psi = rs * math.pi / (2 * n), iis * math.pi / (2 * n)
    om = np.cos(psi)
    vt = r_a * np.sin(psi)
    # CoP twist → pad-centre twist: v_pad = v_cop + ω ẑ × (0 − c)
    pad = np.stack((vt * np.cos(theta) + om * cy, vt * np.sin(theta) - om * cx, om), axis=-1)
    w = steady_state_wrenches(s, COULOMB, pad, bilinear=True)
    tau_cop = w[:, 2] - (cx * w[:, 1] - cy * w[:, 0])
    np.testing.assert_allclose(ls.table[rs, iis, 0], w[:, 0], atol=1e-12)
    np.testing.assert_allclose(ls.table[rs, iis, 1], w[:, 1], atol=1e-12)
    np.testing.assert_allclose(ls.table[rs, iis, 2], tau_cop / r_a, atol=1e-12)


def test_line_grad_rotation_node(tables: dict[str, LimitSurface]) -> None:
    """A6 in the table: rotation about the CoP gives a +x force between 1/11 and 1/9."""
    hx, hy, ht = tables['line_grad'].lookup(0.0, 0.0, 1.0)
    assert 1 / 11 < hx < 1 / 9 and abs(hy) < 1e-12 and ht == pytest.approx(-1.0)


def test_lookup_odd_symmetry_and_node_values(tables: dict[str, LimitSurface]) -> None:
    """A8: LS(−v) = −LS(v); the lookup reproduces node values and interpolates bilinearly."""
    ls = tables['non_convex_2']
    rng = np.random.default_rng(3)
    tw = rng.normal(scale=[0.01, 0.01, 1.0], size=(200, 3))
    a = ls.lookup_batch(tw)
    np.testing.assert_allclose(ls.lookup_batch(-tw), -a, atol=1e-14)
    scalar = np.array([ls.lookup(*t) for t in tw])
    np.testing.assert_allclose(scalar, a, atol=1e-14)
    n, r_a = ls.n_ls, ls.r_a
    r, i = 7, 13
    th, ps = r * math.pi / (2 * n), i * math.pi / (2 * n)
    node = (r_a * math.sin(ps) * math.cos(th), r_a * math.sin(ps) * math.sin(th), math.cos(ps))
    np.testing.assert_allclose(ls.lookup(*node), ls.table[r, i], atol=1e-12)
    th_mid = (r + 0.5) * math.pi / (2 * n)
    mid = (r_a * math.sin(ps) * math.cos(th_mid), r_a * math.sin(ps) * math.sin(th_mid),
           math.cos(ps))
    np.testing.assert_allclose(ls.lookup(*mid), 0.5 * (ls.table[r, i] + ls.table[r + 1, i]),
                               atol=1e-12)
    # Edges: θ just below 2π, pure translation, zero twist.
    np.testing.assert_allclose(ls.lookup(1.0, -1e-300, 0.0), ls.table[0, n], atol=1e-12)
    assert ls.lookup(0.0, 0.0, 0.0) == (0.0, 0.0, 0.0)


def test_radius_scaling_in_the_lookup(tables: dict[str, LimitSurface]) -> None:
    """§6.5: with r_a' = k r_a the lookup of (v, ω) equals the table's lookup of (v, kω)."""
    ls = tables['line_grad']
    k = 2.5
    rng = np.random.default_rng(4)
    for vx, vy, om in rng.normal(scale=[0.01, 0.01, 1.0], size=(20, 3)):
        np.testing.assert_allclose(ls.lookup(vx, vy, om, r_a=k * ls.r_a),
                                   ls.lookup(vx, vy, k * om), atol=1e-14)


def test_size_invariance_of_the_normalised_table() -> None:
    """A9: scaling the patch leaves the table unchanged and scales r_a."""
    s = line_grad(21, 0.02)
    a, b = LimitSurface.build(s, 12), LimitSurface.build(s.scaled(3.0), 12)
    np.testing.assert_allclose(b.table, a.table, atol=1e-12)
    assert b.r_a == pytest.approx(3.0 * a.r_a, rel=1e-13)


def test_progress_reporting() -> None:
    calls: list[tuple[float, float]] = []
    LimitSurface.build(square(21), 8, progress=lambda f, t: calls.append((f, t)),
                       report_after_s=0.0)
    fractions = [c[0] for c in calls]
    assert fractions and fractions[-1] == 1.0 and fractions == sorted(fractions)
    quiet: list[float] = []
    LimitSurface.build(square(9), 8, progress=lambda f, t: quiet.append(f))   # fast: silent
    assert quiet == []


def test_save_load_and_cache(tmp_path: Path) -> None:
    s = line_grad(15, 0.02)
    ls = LimitSurface.build(s, 10)
    path = ls.save(tmp_path / 'table')
    loaded = LimitSurface.load(path, expected_key=ls.key)
    np.testing.assert_array_equal(loaded.table, ls.table)
    assert (loaded.r_a, loaded.n_ls, loaded.key) == (ls.r_a, ls.n_ls, ls.key)
    with pytest.raises(ValueError):
        LimitSurface.load(path, expected_key='0' * 64)

    cache = LimitSurfaceCache(tmp_path / 'cache')
    first = cache.get(s, 10)
    assert cache.get(s, 10) is first and (cache.builds, cache.hits) == (1, 1)
    fresh = LimitSurfaceCache(tmp_path / 'cache')
    again = fresh.get(s, 10)
    assert (fresh.builds, fresh.disk_hits) == (0, 1)
    np.testing.assert_array_equal(again.table, first.table)
    # Keys change with the normalised map, n_ls and the cell size, not with the map's scale.
    other = s.pressure.copy()
    other[3, 7] += 0.01
    assert cache_key(ContactSurface.from_array(other, s.cell_size), 10) != first.key
    assert cache_key(s, 11) != first.key and cache_key(s.scaled(2.0), 10) != first.key
    assert cache_key(ContactSurface.from_array(7.0 * s.pressure, s.cell_size), 10) == first.key
    # A corrupt file is rebuilt, not trusted.
    target = fresh.path_for(first.key)
    assert target is not None
    target.write_bytes(b'not an npz')
    rebuilt = LimitSurfaceCache(tmp_path / 'cache')
    rebuilt.get(s, 10)
    assert rebuilt.builds == 1
