# SPDX-License-Identifier: Apache-2.0
"""Reduced planar LuGre model vs the distributed model (spec §6, §10.1; A6, A8-A11, A15)."""
from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from friction_models.core.distributed import DistributedPlanarLuGre
from friction_models.core.limit_surface import LimitSurfaceCache
from friction_models.core.params import PARAMETER_SETS, LuGreParams
from friction_models.core.reduced import ReducedPlanarLuGre, ReducedPlanarLuGreBatch
from friction_models.core.scenarios import twist_profile
from friction_models.core.surfaces import (STANDARD_SURFACES, circle, line_grad, square,
                                           standard_surface)

COULOMB = LuGreParams(mu_s=1.0, sigma2=0.0)
P = PARAMETER_SETS['reduced_vs_distributed']

#: Largest steady-state difference to the bilinear distributed model, in units of μ f_n
#: (force) and μ f_n r_a (torque): the bilinear interpolation error of the n_ls = 20 table.
#: Smooth convex maps need < 1 %; line-like and non-convex maps have sharp limit-surface
#: edges that a 4.5° table resolves only to a few %.
STEADY_TOL = {'square': 0.015, 'circle': 0.015, 'line': 0.05, 'line_grad': 0.05,
              'line_grad_x': 0.05, 'non_convex_1': 0.04, 'non_convex_2': 0.025}


def unit_twists(r_a: float, count: int, seed: int) -> NDArray[np.float64]:
    """CoP twists whose generalised velocity (vx, vy, r_a ω) is uniform on a sphere."""
    u = np.random.default_rng(seed).normal(size=(count, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    return 0.01 * u / np.array([1.0, 1.0, r_a])


@pytest.mark.parametrize('name', STANDARD_SURFACES)
def test_steady_state_matches_distributed(name: str) -> None:
    """A11: equal at both poles, close at mixed motions; the ellipsoid is much worse."""
    s = standard_surface(name)
    dist = DistributedPlanarLuGre(s, COULOMB)
    red = ReducedPlanarLuGre(s, COULOMB)
    ell = ReducedPlanarLuGre(s, COULOMB, limit_surface=False)
    r_a = red.r_a
    scale = np.array([1.0, 1.0, 1.0 / r_a])
    err_ls, err_el = [], []
    for tw in unit_twists(r_a, 150, seed=1):
        ref = np.array(dist.steady_state(tw, frame='cop', bilinear=True).at_cop())
        err_ls.append(np.abs(np.array(red.steady_state(tw, frame='cop').at_cop()) - ref) * scale)
        err_el.append(np.abs(np.array(ell.steady_state(tw, frame='cop').at_cop()) - ref) * scale)
    assert np.max(err_ls) < STEADY_TOL[name]
    assert np.max(err_el) > 4 * np.max(err_ls)
    # Poles: pure rotations about the CoP, translations along table directions (k·4.5°).
    ang = np.deg2rad(4.5 * 13)
    for tw in ((0.0, 0.0, 0.8), (0.0, 0.0, -2.0), (0.01, 0.0, 0.0),
               (0.01 * np.cos(ang), 0.01 * np.sin(ang), 0.0)):
        ref = np.array(dist.steady_state(tw, frame='cop', bilinear=True).at_cop())
        np.testing.assert_allclose(red.steady_state(tw, frame='cop').at_cop(), ref, atol=1e-12)
    # Between table directions a translation is off by at most the chord 1 − cos(π/(4 n_ls)).
    ref = np.array(dist.steady_state((-0.003, 0.004, 0.0), frame='cop').at_cop())
    got = np.array(red.steady_state((-0.003, 0.004, 0.0), frame='cop').at_cop())
    assert np.abs(got - ref).max() < 1 - np.cos(np.pi / 80)


def test_steady_state_error_is_table_resolution() -> None:
    """The mixed-motion difference is interpolation error: it shrinks with n_ls."""
    s = line_grad(21)
    dist = DistributedPlanarLuGre(s, COULOMB)
    errors = []
    for n_ls in (20, 40):
        red = ReducedPlanarLuGre(s, COULOMB, n_ls=n_ls)
        scale = np.array([1.0, 1.0, 1.0 / red.r_a])
        err = [np.abs(np.subtract(red.steady_state(tw, frame='cop').at_cop(),
                                  dist.steady_state(tw, frame='cop', bilinear=True).at_cop()))
               * scale for tw in unit_twists(red.r_a, 300, seed=2)]
        errors.append(np.sqrt(np.mean(np.square(err))))
    assert errors[1] < 0.6 * errors[0]


def test_line_grad_rotation_net_force_needs_the_limit_surface() -> None:
    """A6: LineGrad rotating about its CoP: net +x force with the table, none with the ellipsoid.

    A centred ellipsoid cannot represent a force from a pure rotation about the CoP.
    """
    s = line_grad(21)
    rot = (0.0, 0.0, 1.0)
    w_ls = ReducedPlanarLuGre(s, COULOMB, f_n=2.0).steady_state(rot, frame='cop')
    w_el = ReducedPlanarLuGre(s, COULOMB, limit_surface=False, f_n=2.0).steady_state(
        rot, frame='cop')
    w_d = DistributedPlanarLuGre(s, COULOMB, f_n=2.0).steady_state(rot, frame='cop',
                                                                   bilinear=True)
    assert w_ls.fx == pytest.approx(w_d.fx, abs=1e-12) and 2 / 11 < w_ls.fx < 2 / 9
    assert w_el.fx == 0.0 and w_el.fy == 0.0


def run_profile(model: object, dt: float) -> NDArray[np.float64]:
    steps = round(5.0 / dt)
    twists = twist_profile(np.arange(steps) * dt)
    out = np.empty((steps, 3))
    for k in range(steps):
        w = model.step(twists[k], dt, frame='cop')  # type: ignore[attr-defined]
        out[k] = (w.fx, w.fy, w.tau_cop)
    return out


def nrmse(test: NDArray[np.float64], base: NDArray[np.float64]) -> tuple[float, float]:
    """Paper §6.4 metrics: RMSE(‖ΔF_t‖)/max‖F_t‖ and RMSE(Δτ)/max|τ|."""
    df = np.hypot(*(test[:, :2] - base[:, :2]).T)
    return (float(np.sqrt(np.mean(df ** 2)) / np.hypot(*base[:, :2].T).max()),
            float(np.sqrt(np.mean((test[:, 2] - base[:, 2]) ** 2)) / np.abs(base[:, 2]).max()))


#: NRMSE bounds (force, torque) of the reduced model with the table on the 5 s profile.
SERIES_TOL = {'square': (0.005, 0.01), 'circle': (0.005, 0.01), 'line': (0.03, 0.03),
              'line_grad': (0.03, 0.035), 'line_grad_x': (0.03, 0.04),
              'non_convex_1': (0.02, 0.02), 'non_convex_2': (0.01, 0.01)}


@pytest.mark.parametrize('name', STANDARD_SURFACES)
def test_time_series_against_distributed(name: str) -> None:
    """Spec §10.1: 5 s varying twist, σ0 = 1e6, EP on, dt = 0.5 ms.

    The exponential update is converged there: halving dt changes the NRMSE by < 1e-4.
    """
    s = standard_surface(name)
    dt = 5e-4
    base = run_profile(DistributedPlanarLuGre(s, P), dt)
    e_ls = nrmse(run_profile(ReducedPlanarLuGre(s, P), dt), base)
    e_el = nrmse(run_profile(ReducedPlanarLuGre(s, P, limit_surface=False), dt), base)
    print(f'\n{name}: NRMSE reduced+LS force {e_ls[0]:.4f} torque {e_ls[1]:.4f}; '
          f'ellipsoid force {e_el[0]:.4f} torque {e_el[1]:.4f}')
    assert e_ls[0] < SERIES_TOL[name][0] and e_ls[1] < SERIES_TOL[name][1]
    assert e_el[0] > 2 * e_ls[0] and e_el[1] > 2 * e_ls[1]


@pytest.mark.parametrize('ep', [False, True])
def test_dynamics_converge_to_steady_state(ep: bool) -> None:
    model = ReducedPlanarLuGre(line_grad(21), P, elasto_plastic=ep, f_n=1.5)
    for twist in ((0.01, -0.004, 0.0), (0.003, 0.002, 0.7), (0.0, 0.0, -1.1)):
        for _ in range(300):
            w = model.step(twist, 1e-3)
        np.testing.assert_allclose(w, model.steady_state(twist), rtol=1e-9, atol=1e-14)


def test_viscous_torque_uses_the_second_moment_about_the_cop() -> None:
    """§6.3 / §13.8: the viscous wrench equals the distributed model's (about the CoP)."""
    s = line_grad(21)
    visc = LuGreParams(mu_s=1.0, sigma2=0.7)
    tw = (0.004, -0.002, 0.9)
    red = ReducedPlanarLuGre(s, visc)
    red0 = ReducedPlanarLuGre(s, COULOMB)
    dist = DistributedPlanarLuGre(s, visc)
    dist0 = DistributedPlanarLuGre(s, COULOMB)
    red_v = np.subtract(red.steady_state(tw), red0.steady_state(tw))
    dist_v = np.subtract(dist.steady_state(tw), dist0.steady_state(tw))
    np.testing.assert_allclose(red_v, dist_v, rtol=1e-12, atol=1e-16)
    assert red.viscous_scale[2] == pytest.approx(1.458, abs=1e-3)


def test_odd_symmetry_frames_and_normal_force() -> None:
    """A8, A10, A15 for the reduced model."""
    s = line_grad(21)
    a, b, c = (ReducedPlanarLuGre(s, P) for _ in range(3))
    rng = np.random.default_rng(5)
    cx, cy = s.cop
    for vx, vy, om in rng.normal(scale=[0.005, 0.005, 0.5], size=(40, 3)):
        wa = a.step((vx, vy, om), 2e-4)
        wb = b.step((-vx, -vy, -om), 2e-4)
        wc = c.step((vx - om * cy, vy + om * cx, om), 2e-4, frame='cop')
        np.testing.assert_allclose(wa, [-v for v in wb], rtol=1e-12, atol=1e-16)
        np.testing.assert_allclose(wa, wc, rtol=1e-10, atol=1e-15)
        assert wa.tau == pytest.approx(wa.tau_cop + cx * wa.fy - cy * wa.fx, rel=1e-12)
    z = a.state
    a.set_normal_force(3.0)
    np.testing.assert_array_equal(a.state, z)
    d = ReducedPlanarLuGre(s, P)
    d.set_state(z)
    np.testing.assert_allclose(a.step((0.001, 0, 0.1), 1e-4),
                               3.0 * np.array(d.step((0.001, 0, 0.1), 1e-4)), rtol=1e-12)


def test_zero_twist_freezes_the_state() -> None:
    model = ReducedPlanarLuGre(circle(), P, f_n=2.0)
    model.set_state((3e-7, -1e-7, 2e-9))
    w = model.step((0.0, 0.0, 0.0), 0.5)
    np.testing.assert_array_equal(model.state, (3e-7, -1e-7, 2e-9))
    np.testing.assert_allclose(w.at_cop(), -P.sigma0 * 2.0 * np.array([3e-7, -1e-7, 2e-9]))


def test_size_change_rescales_without_rebuilding() -> None:
    """§6.5/A9: same shape, new size → r_a, CoP, J scale; table object reused."""
    s = line_grad(21, 0.02)
    model = ReducedPlanarLuGre(s, COULOMB)
    table = model.limit_surface
    tw = (0.003, 0.001, 0.6)
    before = model.steady_state(tw, frame='cop')
    model.set_pressure(s.scaled(2.0))
    assert model.limit_surface is table and model.r_a == pytest.approx(2 * table.r_a)
    after = model.steady_state((tw[0], tw[1], tw[2] / 2.0), frame='cop')
    np.testing.assert_allclose((after.fx, after.fy), (before.fx, before.fy), rtol=1e-12)
    assert after.tau_cop == pytest.approx(2.0 * before.tau_cop, rel=1e-12)


def test_given_table_must_match_the_pressure_shape() -> None:
    table = ReducedPlanarLuGre(square(15), COULOMB).limit_surface
    assert table is not None
    big = ReducedPlanarLuGre(square(15, 0.04), COULOMB, limit_surface=table)
    assert big.r_a == pytest.approx(2.0 * table.r_a) and big.limit_surface is table
    with pytest.raises(ValueError, match='pressure shape'):
        ReducedPlanarLuGre(circle(15), COULOMB, limit_surface=table)


def test_shape_change_uses_the_cache() -> None:
    cache = LimitSurfaceCache()
    model = ReducedPlanarLuGre(square(15), COULOMB, cache=cache)
    model.set_pressure(circle(15))
    model.set_pressure(square(15))
    assert cache.builds == 2 and cache.hits == 1
    model.set_pressure(5.0 * circle(15).pressure)     # a raw array on the same cells
    assert cache.builds == 2 and cache.hits == 2
    assert model.r_a == pytest.approx(ReducedPlanarLuGre(circle(15), COULOMB).r_a)


@pytest.mark.parametrize('threshold', [0, 16])
@pytest.mark.parametrize('options', [
    {}, {'elasto_plastic': False}, {'limit_surface': False},
    {'integrator': 'explicit_euler', 'rate_limiter': True}, {'force_from': 'post_update'}])
def test_batch_equals_single_contacts(threshold: int, options: dict[str, object]) -> None:
    """Batched stepping (vectorised and small-N paths) reproduces N single models."""
    surfaces = [circle(21), line_grad(21), circle(21), square(11, 0.01)]
    batch = ReducedPlanarLuGreBatch(surfaces, P, scalar_threshold=threshold,
                                    f_n=[1.0, 2.0, 0.5, 3.0], **options)  # type: ignore[arg-type]
    singles = [ReducedPlanarLuGre(s, P, f_n=f, **options)  # type: ignore[arg-type]
               for s, f in zip(surfaces, (1.0, 2.0, 0.5, 3.0), strict=True)]
    rng = np.random.default_rng(6)
    for k in range(60):
        tw = rng.normal(scale=[0.004, 0.004, 0.4], size=(4, 3)) * (k % 7 != 3)
        wb = batch.step(tw, 1e-4)
        ws = np.array([m.step(t, 1e-4) for m, t in zip(singles, tw, strict=True)])
        np.testing.assert_allclose(np.stack(wb, axis=-1), ws, rtol=1e-9, atol=1e-14)
    np.testing.assert_allclose(batch.state, [m.state for m in singles], rtol=1e-9, atol=1e-20)


def test_simulator_api_two_pads() -> None:
    """The documented simulator API; a 2-pad batch equals two single models.

    Construction from (surface, params, limit_surface, elasto_plastic); pad twist and f_n in,
    wrench at the pad centre out.
    """
    pad = circle(21, 0.02)
    single = ReducedPlanarLuGre(pad, P, limit_surface=True, elasto_plastic=True)
    w = single.step((0.01, 0.0, 0.5), 1e-3, f_n=2.0)
    assert w.fx < 0 and w.tau < 0 and len(w.at_pad()) == 3
    pads = ReducedPlanarLuGreBatch([pad, pad], P)
    wb = pads.step(np.array([[0.01, 0.0, 0.5], [0.01, 0.0, -0.5]]), 1e-3, f_n=[2.0, 2.0])
    assert wb.fx[0] == pytest.approx(w.fx) and wb.tau[0] == pytest.approx(w.tau)
    assert wb.tau[1] == pytest.approx(-w.tau) and wb.at_pad().shape == (2, 3)


@pytest.mark.parametrize('model', ['reduced', 'distributed'])
@pytest.mark.parametrize('options', [
    {}, {'elasto_plastic': False}, {'integrator': 'explicit_euler', 'rate_limiter': True},
    {'force_from': 'post_update'}])
def test_advance_equals_step(model: str, options: dict[str, object]) -> None:
    """The coupling's float entry point gives exactly `step`'s numbers and state."""
    surface = line_grad(11, 0.01)
    cls = ReducedPlanarLuGre if model == 'reduced' else DistributedPlanarLuGre
    a = cls(surface, P, **options)  # type: ignore[arg-type]
    b = cls(surface, P, **options)  # type: ignore[arg-type]
    rng = np.random.default_rng(9)
    for k in range(80):
        vx, vy, om = (rng.normal(scale=[0.004, 0.004, 0.4]) * (k % 5 != 2)).tolist()
        f_n = 1.0 + 0.01 * k
        wa = a.step((vx, vy, om), 1e-4, f_n)
        assert tuple(b.advance(vx, vy, om, 1e-4, f_n)) == tuple(wa)
    np.testing.assert_array_equal(a.state, b.state)
