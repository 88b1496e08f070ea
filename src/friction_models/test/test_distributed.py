# SPDX-License-Identifier: Apache-2.0
"""Distributed planar LuGre model (spec §4, §5, §11: A4-A6, A8-A10, A15, A16)."""
from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from friction_models.core.distributed import DistributedPlanarLuGre, steady_state_wrenches
from friction_models.core.integrators import UnstableStepError
from friction_models.core.params import LuGreParams
from friction_models.core.planar import transport_twist, transport_wrench
from friction_models.core.surfaces import (ContactSurface, circle, line, line_grad, square,
                                           standard_surface)

COULOMB = LuGreParams(mu_c=1.0, mu_s=1.0, sigma2=0.0)
P = LuGreParams()


def fine_quadrature(pressure: NDArray[np.float64], h: float, twists: NDArray[np.float64],
                    sub: int) -> NDArray[np.float64]:
    """Independent Coulomb limit-surface integrals (thesis eqs 2.14-2.15), μ = f_n = 1.

    Each cell is split into ``sub × sub`` points carrying its pressure uniformly; the grid
    geometry is rebuilt here from the spec §1 formulas, not taken from the library.
    """
    ny, nx = pressure.shape
    w = np.repeat(np.repeat(pressure / pressure.sum(), sub, 0), sub, 1) / sub ** 2
    xs = (np.arange(nx * sub) + 0.5) * h / sub - nx * h / 2
    ys = ny * h / 2 - (np.arange(ny * sub) + 0.5) * h / sub
    gx, gy = np.meshgrid(xs, ys)
    keep = w > 0
    gx, gy, w = gx[keep], gy[keep], w[keep]
    out = []
    for vx, vy, om in twists:
        ux, uy = vx - om * gy, vy + om * gx
        speed = np.hypot(ux, uy)
        speed[speed == 0.0] = np.inf
        ux, uy = ux / speed, uy / speed
        out.append((-(w @ ux), -(w @ uy), -(w @ (gx * uy - gy * ux))))
    return np.array(out)


def twist_sweep(surface: ContactSurface) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Pad-centre twists of a sweep, and a mask of the 'far' (smooth) cases.

    Rotations (both senses) about CoRs on rings around the CoP, inside and outside the patch,
    plus translations in eight directions.
    """
    cx, cy = surface.cop
    twists, far = [], []
    for radius in (0.0, 0.37e-3, 2.1e-3, 5.3e-3, 9.1e-3, 14e-3, 40e-3, 300e-3):
        for ang in np.linspace(0.0, 2 * np.pi, 7, endpoint=False) + 0.3:
            px, py = cx + radius * np.cos(ang), cy + radius * np.sin(ang)
            for om in (1.3, -0.4):
                twists.append((om * py, -om * px, om))      # rotation about (px, py)
                far.append(radius >= 40e-3)
    for ang in np.linspace(0.0, 2 * np.pi, 8, endpoint=False):
        twists.append((0.01 * np.cos(ang), 0.01 * np.sin(ang), 0.0))
        far.append(True)
    return np.array(twists), np.array(far)


@pytest.mark.parametrize('name', ['square', 'circle', 'line', 'line_grad'])
def test_steady_state_equals_fine_quadrature(name: str) -> None:
    """A4/A5 and thesis eqs 2.14-2.15 over a sweep of directions and centres of rotation.

    One point per cell is the midpoint rule of the same integrals: the error is bounded by
    about half the load of the cell holding the CoR plus a smooth O(h²) part, and is tiny
    when the CoR is far away. Bilinear smoothing moves the CoR to cell corners (≤ h/√2 away),
    which costs up to ~0.5 % of the torque near the CoP (r_a 7.625 vs 7.652 mm, spec §6.1).
    """
    s = standard_surface(name)
    r_a = s.r_a_cells
    twists, far = twist_sweep(s)
    ref = fine_quadrature(s.pressure, s.cell_size, twists, sub=10)
    for bilinear in (False, True):
        tol = 0.6 * s.weights.max() + (4e-3 if bilinear else 2e-3)
        got = steady_state_wrenches(s, COULOMB, twists, bilinear=bilinear)
        err_f = np.abs(got[:, :2] - ref[:, :2]).max(axis=1)
        err_t = np.abs(got[:, 2] - ref[:, 2]) / r_a
        assert err_f.max() < tol and err_t.max() < tol, (bilinear, err_f.max(), err_t.max())
        assert err_f[far].max() < 2e-3 and err_t[far].max() < 2e-3
        if not bilinear:
            # Mean error well below the worst case: the midpoint rule has no systematic bias.
            assert err_f.mean() < 0.3 * tol and err_t.mean() < 0.3 * tol


def test_uniform_disc_pure_rotation_torque() -> None:
    """A5: τ = μ f_n 2R/3 for a uniform disc (fine grid; disc radius R·(n−1)/n)."""
    n, size = 401, 0.02
    s = circle(n, size)
    radius = 0.5 * size * (n - 1) / n
    params = LuGreParams(mu_c=0.7, mu_s=0.7, sigma2=0.0)
    fx, fy, tau = steady_state_wrenches(s, params, (0.0, 0.0, 2.0), f_n=3.0)
    assert tau == pytest.approx(-0.7 * 3.0 * 2 * radius / 3, rel=2e-3)
    assert abs(fx) < 1e-9 and abs(fy) < 1e-9


def test_line_grad_rotation_about_cop_gives_net_force() -> None:
    """A6: 1/11 exactly for 21 cells (one point), → 1/9 on a fine line, bilinear in between."""
    mu_fn = 0.8 * 2.0
    params = LuGreParams(mu_c=0.8, mu_s=0.8, sigma2=0.0)

    def rotation_force(s: ContactSurface, bilinear: bool) -> NDArray[np.float64]:
        cx, cy = s.cop
        w = steady_state_wrenches(s, params, (1.0 * cy, -1.0 * cx, 1.0), f_n=2.0,
                                  bilinear=bilinear)
        return w[:2]

    f21 = rotation_force(line_grad(21), False)
    assert f21[0] == pytest.approx(mu_fn / 11, rel=1e-12)          # +x for ω > 0
    assert abs(f21[1]) < 1e-12
    f_fine = rotation_force(line_grad(801), False)
    assert f_fine[0] == pytest.approx(mu_fn / 9, rel=5e-3)
    f_bil = rotation_force(line_grad(21), True)
    assert mu_fn / 11 < f_bil[0] < mu_fn / 9


@pytest.mark.parametrize('ep', [False, True])
def test_dynamics_converge_to_steady_state(ep: bool) -> None:
    s = circle(15, 0.02)
    model = DistributedPlanarLuGre(s, P, elasto_plastic=ep)
    for twist in ((0.01, -0.004, 0.0), (0.003, 0.002, 0.7), (0.0, 0.0, -1.1)):
        model.reset()
        for _ in range(1500):
            w = model.step(twist, 1e-3)
        ref = model.steady_state(twist)
        np.testing.assert_allclose(w.at_pad(), ref.at_pad(), atol=2e-3 * np.abs(ref).max())


def test_odd_symmetry_steady_and_dynamic() -> None:
    """A8: the model is odd in the twist (state starting from zero)."""
    s = line_grad(21)
    rng = np.random.default_rng(0)
    tw = rng.normal(scale=[0.01, 0.01, 1.0], size=(50, 3))
    for bilinear in (False, True):
        np.testing.assert_allclose(steady_state_wrenches(s, P, -tw, bilinear=bilinear),
                                   -steady_state_wrenches(s, P, tw, bilinear=bilinear),
                                   rtol=1e-12, atol=1e-15)
    a, b = DistributedPlanarLuGre(s, P), DistributedPlanarLuGre(s, P)
    for t in tw[:20]:
        wa, wb = a.step(t, 2e-4), b.step(-t, 2e-4)
        np.testing.assert_allclose(wa, [-c for c in wb], rtol=1e-12, atol=1e-15)


def test_normal_force_scaling_and_state() -> None:
    """A10: forces linear in f_n; set_normal_force leaves the bristles untouched."""
    s = square(9, 0.01)
    model = DistributedPlanarLuGre(s, P, f_n=1.0)
    for _ in range(20):
        model.step((0.002, 0.001, 0.3), 1e-4)
    z = model.state
    model.set_normal_force(4.0)
    np.testing.assert_array_equal(model.state, z)
    twin = DistributedPlanarLuGre(s, P, f_n=1.0)
    twin.set_state(z)
    w4 = model.step((0.001, 0.0, 0.1), 1e-4)
    w1 = twin.step((0.001, 0.0, 0.1), 1e-4)
    np.testing.assert_allclose(w4, 4.0 * np.array(w1), rtol=1e-13)
    np.testing.assert_allclose(steady_state_wrenches(s, P, (0.01, 0, 1.0), f_n=3.0),
                               3.0 * steady_state_wrenches(s, P, (0.01, 0, 1.0)), rtol=1e-14)


def test_size_scaling() -> None:
    """A9: scaling the patch by k keeps forces and scales torques by k.

    The twist is scaled consistently (ω/k keeps the CoR at the same relative position).
    """
    s = line_grad(21, 0.02)
    k = 3.0
    big = s.scaled(k)
    tw = np.array([0.01, -0.02, 2.0])
    a = steady_state_wrenches(s, COULOMB, tw)
    b = steady_state_wrenches(big, COULOMB, tw * [1.0, 1.0, 1.0 / k])
    np.testing.assert_allclose(b[:2], a[:2], rtol=1e-12)
    assert b[2] == pytest.approx(k * a[2], rel=1e-12)


def test_frames_round_trip() -> None:
    """A15: pad/CoP twist and wrench transport are exact inverses and agree with the model."""
    s = line_grad(21)
    c = s.cop
    rng = np.random.default_rng(1)
    for vx, vy, om in rng.normal(scale=[0.01, 0.01, 1.0], size=(10, 3)):
        back = transport_twist(*transport_twist(vx, vy, om, (0, 0), c), c, (0, 0))
        np.testing.assert_allclose(back, (vx, vy, om), rtol=1e-15, atol=1e-18)
        a = DistributedPlanarLuGre(s, P)
        b = DistributedPlanarLuGre(s, P)
        cop_twist = transport_twist(vx, vy, om, (0, 0), c)
        wa = a.step((vx, vy, om), 1e-4, frame='pad')
        wb = b.step(cop_twist, 1e-4, frame='cop')
        np.testing.assert_allclose(wa, wb, rtol=1e-12, atol=1e-16)
        fx, fy, tau_cop = transport_wrench(wa.fx, wa.fy, wa.tau, (0, 0), c)
        assert tau_cop == pytest.approx(wa.tau_cop, rel=1e-12, abs=1e-18)
        assert transport_wrench(fx, fy, tau_cop, c, (0, 0))[2] == pytest.approx(wa.tau)


def test_regularisation_of_zero_speed_cells() -> None:
    """A16: a CoR on a cell centre (exactly, or at round-off distance) adds no force."""
    s = square(21, 0.02)
    for offset in (0.0, 1e-19, -3e-17):
        w = steady_state_wrenches(s, COULOMB, (offset, 0.0, 1.0))
        assert np.hypot(w[0], w[1]) < 1e-9             # not 1/441 N
    ln = line(21, 0.02)
    y5 = (10 - 5) * ln.cell_size                        # centre of row 5
    exact = steady_state_wrenches(ln, COULOMB, (y5, 0.0, 1.0))
    nudged = steady_state_wrenches(ln, COULOMB, (y5 + 1e-18, 0.0, 1.0))
    np.testing.assert_allclose(nudged, exact, atol=1e-9)   # not 1/21 N apart
    assert abs(exact[0] - (5 - 15) / 21) < 1e-9           # 5 cells above (+x), 15 below


def test_sticking_and_presliding() -> None:
    """A2/A3 for the planar model."""
    s = square(11, 0.01)
    model = DistributedPlanarLuGre(s, P, f_n=2.0, force_from='post_update')
    x = 1e-8
    for _ in range(10):
        w = model.step((x / 10 / 1e-5, 0.0, 0.0), 1e-5)
    damping = (P.sigma1 + P.sigma2) * (x / 10 / 1e-5) * 2.0
    assert w.fx + damping == pytest.approx(-P.sigma0 * x * 2.0, rel=1e-9)   # EP: exact
    frozen = [model.step((0.0, 0.0, 0.0), dt) for dt in (1e-4, 1.0)]
    assert frozen[0] == frozen[1]
    assert frozen[0].fx == pytest.approx(-P.sigma0 * x * 2.0, rel=1e-9)


def test_set_pressure_keeps_common_cells() -> None:
    big = circle(11, 0.01)
    mask = big.pressure > 0
    mask[:, :5] = False
    half = ContactSurface.from_mask(mask, big.cell_size)
    model = DistributedPlanarLuGre(big, P)
    for _ in range(30):
        model.step((0.001, 0.0, 0.0), 1e-4)
    z = model.state
    model.set_pressure(half)
    z2 = model.state
    np.testing.assert_array_equal(z2[mask], z[mask])
    assert not np.any(z2[~mask])
    model.set_pressure(big)                   # cells re-entering start undeformed
    assert not np.any(model.state[:, :5])
    model.set_pressure(3.0 * mask)            # a raw [j, i] array on the same cells
    assert model.surface.n_active == half.n_active and model.surface.cop == half.cop


def test_explicit_euler_agrees_with_exponential_for_small_dt() -> None:
    s = square(7, 0.01)
    p = LuGreParams(sigma0=1e5, sigma1=20.0)
    diffs = []
    for dt in (2e-6, 1e-6):
        a = DistributedPlanarLuGre(s, p, integrator='exponential')
        b = DistributedPlanarLuGre(s, p, integrator='explicit_euler')
        steps = round(2e-3 / dt)
        for _ in range(steps):
            wa = a.step((0.02, 0.01, 1.0), dt)
            wb = b.step((0.02, 0.01, 1.0), dt)
        diffs.append(np.abs(np.subtract(wa, wb)).max())
    assert diffs[0] < 1e-2 and diffs[0] / diffs[1] == pytest.approx(2.0, rel=0.2)


def test_explicit_euler_guard_and_limiter() -> None:
    s = square(5, 0.01)
    with pytest.raises(UnstableStepError):
        DistributedPlanarLuGre(s, P, integrator='explicit_euler',
                               elasto_plastic=False).step((0.1, 0, 0), 1e-3)
    lim = DistributedPlanarLuGre(s, P, integrator='explicit_euler', rate_limiter=True)
    for _ in range(20):
        w = lim.step((0.1, 0.0, 0.0), 1e-3)
    assert np.isfinite(w).all() and abs(w.fx) < 2 * P.mu_s
    with pytest.raises(ValueError):
        DistributedPlanarLuGre(s, P, rate_limiter=True)


def test_derivative_and_wrench_at_match_the_euler_step() -> None:
    s = line_grad(9, 0.01)
    model = DistributedPlanarLuGre(s, P, integrator='explicit_euler')
    rng = np.random.default_rng(2)
    z = rng.normal(scale=3e-7, size=(9, 9, 2)) * (s.pressure > 0)[..., None]
    model.set_state(z)
    twist = (0.001, -0.002, 0.3)
    rate = model.derivative(z, twist)
    w_inst = model.wrench_at(z, twist)
    w = model.step(twist, 1e-9)
    np.testing.assert_allclose(model.state, z + 1e-9 * rate, rtol=1e-12, atol=1e-22)
    np.testing.assert_allclose(w, w_inst, rtol=1e-12)
