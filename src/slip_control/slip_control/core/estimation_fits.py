# SPDX-License-Identifier: Apache-2.0
"""Fits of the exploration phases (control_and_estimation §3.3, §3.4, §3.7; pure functions).

Per finger, from bias-removed wrenches and slip twists in the raw sensor frames
(``f_n = |Fz|``, ``f_t = ‖(Fx, Fy)‖``, ``τ = Tz``, ``v = ‖(vx, vy)‖``, ``ω``); the gating of the
samples is `slip_control.core.contact_estimator`'s.

LINEAR phase (§3.3) — pairs ``(v, q)`` with ``q = f_t/f_n`` from sliding samples, and the
static samples' ratios. At the end::

    q = μ_c + μ_v·v                 (ordinary least squares; intercept μ_c, slope μ_v)

Only samples at ``v ≥ fit_min_speed`` enter the fit (every sliding sample when too few are
that fast): just above the static threshold the friction still carries part of the static
excess (Stribeck), which biased μ_c up by up to 0.02 at ``μ_s/μ_c ≈ 1.5``.
    μ_s = a_μs·μ_c,   a_μs = max(max(static q)/μ_c, 1)

If the speed span is below ``min_speed_span`` the slope is not identifiable: ``μ_v`` is
reported as 0 (``viscous_valid`` false) and ``μ_c`` is the mean ratio.

ROTATIONAL phase (§3.4, corrected) — per sample ``|ω|``, ``f_n``, ``f_t`` and the torque about
the centre of pressure ``τ_cop = Tz − (c × F)_z`` (``c`` from ``Tx``, ``Ty`` and the pad offset;
``Tz`` when those are missing). The sensor's ``Tz`` is taken about the pad centre: when the
pressure map is not centred (a gradient map) it overstates the torsional friction, which the
limit surface defines about the centre of pressure. Per sample, the viscous torque
``μ_v·u·|ω|`` (``u = viscous_shape·r²``) is removed and the ellipsoidal limit surface
``(f_t/(μ_c f_n))² + (τ/(μ_c r f_n))² = 1`` is solved for ``r``::

    r_i = (|τ_cop,i|/f_n,i − μ_v·u·|ω_i|) / (μ_c·√(1 − (f_t,i/(μ_c f_n,i))²))

and ``r`` is the median of ``r_i`` over the samples that slide fast enough
(``r·|ω| ≥ min_slip_speed``, relaxed to ½, ¼ and none when too few remain: below it the
Stribeck excess inflates the torque) and are near
pure rotation (``f_t ≤ max_load_share·μ_c f_n``); ``u`` depends on ``r`` so the median is
iterated three times. The former OLS ``|τ/f_n| = b + a|ω|``, ``r = b/μ_c`` read +10 % (median)
and +25 % on gradient maps on a population of objects; this reads within a few percent.

Uncertainty (a 95 % interval ``±1.96σ`` that covers the truth): the statistical part uses the
effective sample size ``n·(1 − ρ)/(1 + ρ)`` (``ρ`` the lag-1 autocorrelation of the residuals;
consecutive samples are not independent), and a model-error floor is added in quadrature
(``mu_c_std_floor``; ``r_std_floor·r``) plus, for ``r``, the propagated ``σ_μc``. The floors
are calibrated on a population of simulated objects (docs/evaluation.md).

Validity (§3.7): ``linear_valid`` ⇔ ``n_linear ≥ min_samples_linear``, ``0 < μ_c ≤ mu_c_max``,
fit finite; ``viscous_valid`` ⇔ linear valid and speed span ≥ ``min_speed_span``;
``static_valid`` ⇔ ``n_static ≥ 1`` (else ``μ_s = μ_c``); ``rotational_valid`` ⇔ linear valid,
``n_rotational ≥ min_samples_rotational``, ``r_min ≤ r ≤ r_max``.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike

from slip_control.core.contact import NAN, FingerContact
from slip_control.core.params import ContactEstimatorParams


@dataclass(frozen=True, slots=True)
class LineFit:
    """Result of fitting ``y = intercept + slope·x``.

    Attributes:
        intercept: Fitted intercept.
        slope: Fitted slope (0 when ``slope_fitted`` is false).
        intercept_std: 1-σ standard error of the intercept (NaN with too few samples).
        residual_rms: RMS of the residuals.
        n: Number of samples.
        x_span: ``max(x) − min(x)``.
        slope_fitted: The slope was estimated (else an intercept-only fit).
        autocorrelation: Lag-1 autocorrelation of the residuals (0 when not computable).
    """

    intercept: float
    slope: float
    intercept_std: float
    residual_rms: float
    n: int
    x_span: float
    slope_fitted: bool
    autocorrelation: float = 0.0

    @property
    def variance_inflation(self) -> float:
        """``(1 + ρ)/(1 − ρ)`` for ``ρ > 0`` (1 otherwise): ``n/n_eff`` of correlated samples."""
        rho = min(self.autocorrelation, 0.95)
        return (1.0 + rho) / (1.0 - rho) if rho > 0.0 else 1.0


def fit_line(x: ArrayLike, y: ArrayLike, *, min_span: float) -> LineFit:
    """Ordinary least squares ``y = b + a·x``, or the mean if ``x`` spans less than ``min_span``.

    Args:
        x: Regressor samples, shape (n,).
        y: Response samples, shape (n,).
        min_span: Smallest ``x`` span for which the slope is fitted (same unit as ``x``).

    Returns:
        The fit; NaN fields when ``n`` is too small for them.
    """
    xa = np.asarray(x, dtype=np.float64)
    ya = np.asarray(y, dtype=np.float64)
    n = int(xa.size)
    if n == 0:
        return LineFit(NAN, 0.0, NAN, NAN, 0, 0.0, False)
    span = float(np.ptp(xa))
    x_mean = float(xa.mean())
    y_mean = float(ya.mean())
    dx = xa - x_mean
    sxx = float(dx @ dx)
    if n >= 3 and span >= min_span and span > 0.0 and sxx > 0.0:
        slope = float(dx @ (ya - y_mean)) / sxx
        intercept = y_mean - slope * x_mean
        resid = ya - intercept - slope * xa
        s2 = float(resid @ resid) / (n - 2)
        std = math.sqrt(s2 * (1.0 / n + x_mean * x_mean / sxx))
        return LineFit(intercept, slope, std, math.sqrt(float(resid @ resid) / n), n, span,
                       True, lag1_autocorrelation(resid))
    resid = ya - y_mean
    rss = float(resid @ resid)
    std = math.sqrt(rss / (n - 1) / n) if n >= 2 else NAN
    return LineFit(y_mean, 0.0, std, math.sqrt(rss / n), n, span, False,
                   lag1_autocorrelation(resid))


def lag1_autocorrelation(residuals: ArrayLike) -> float:
    """Lag-1 autocorrelation of a residual series (0 with fewer than 4 samples or no spread)."""
    r = np.asarray(residuals, dtype=np.float64)
    if r.size < 4:
        return 0.0
    r = r - r.mean()
    denom = float(r @ r)
    if denom <= 0.0:
        return 0.0
    return float(r[:-1] @ r[1:]) / denom


def linear_result(fit: LineFit, static_ratios: Sequence[float],
                  params: ContactEstimatorParams) -> FingerContact:
    """Per-finger linear-phase result with flags (§3.3, §3.7); rotational fields NaN.

    Args:
        fit: Fit of ``q`` against ``v`` (`fit_line` with ``min_span = min_speed_span``).
        static_ratios: Friction ratios of the static samples.
        params: Estimator parameters.
    """
    mu_c = fit.intercept
    ok = (fit.n >= params.min_samples_linear and math.isfinite(mu_c)
          and 0.0 < mu_c <= params.mu_c_max and math.isfinite(fit.intercept_std))
    viscous = ok and fit.slope_fitted and fit.x_span >= params.min_speed_span
    mu_v = fit.slope if viscous else 0.0
    n_static = len(static_ratios)
    static = ok and n_static >= 1
    if static:
        a_mu_s = max(max(static_ratios) / mu_c, 1.0)
        mu_s = a_mu_s * mu_c
    else:
        mu_s = mu_c
    mu_c_std = math.hypot(fit.intercept_std * math.sqrt(fit.variance_inflation),
                          params.mu_c_std_floor)
    return FingerContact(mu_c=mu_c, mu_s=mu_s, mu_v=mu_v, mu_c_std=mu_c_std,
                         n_linear=fit.n, n_static=n_static,
                         linear_residual_rms=fit.residual_rms, linear_valid=ok,
                         viscous_valid=viscous, static_valid=static)


@dataclass(frozen=True, slots=True)
class RadiusFit:
    """Result of the torsional-radius fit (§3.4, corrected).

    Attributes:
        r: Torsional radius [m] (NaN when no sample qualified).
        r_std: 1-σ of ``r`` including the model-error floor [m].
        n: Samples used.
        residual_rms: RMS of ``r_i − r`` over the samples used [m].
        slip_speed_gate: The ``r·|ω|`` gate that was applied [m/s].
    """

    r: float
    r_std: float
    n: int
    residual_rms: float
    slip_speed_gate: float


def fit_torsional_radius(omega_abs: ArrayLike, f_n: ArrayLike, f_t: ArrayLike,
                         tau_cop: ArrayLike, mu_c: float, mu_c_std: float, mu_v: float,
                         params: ContactEstimatorParams) -> RadiusFit:
    """``r`` from rotational samples by the ellipsoidal limit surface (see the module doc).

    Args:
        omega_abs: ``|ω|`` per sample [rad/s] (already gated by ``min_abs_omega``).
        f_n: Normal force per sample [N].
        f_t: Tangential force per sample [N].
        tau_cop: Torque about the centre of pressure per sample [N·m].
        mu_c: Coulomb coefficient of the finger (linear phase) [-], > 0.
        mu_c_std: Its 1-σ [-].
        mu_v: Viscous coefficient [1/(m/s)] (negative values are taken as 0).
        params: Estimator parameters.
    """
    w = np.abs(np.asarray(omega_abs, dtype=np.float64))
    fn = np.asarray(f_n, dtype=np.float64)
    ft = np.asarray(f_t, dtype=np.float64)
    tq = np.abs(np.asarray(tau_cop, dtype=np.float64))
    rp = params.rotational
    nan = RadiusFit(NAN, NAN, 0, NAN, NAN)
    if w.size == 0 or not (math.isfinite(mu_c) and mu_c > 0.0):
        return nan
    share = ft / (mu_c * fn)
    near_rotation = share <= rp.max_load_share
    if int(near_rotation.sum()) < params.min_samples_rotational:
        near_rotation = share < 1.0
    slack = np.sqrt(np.maximum(1.0 - np.minimum(share, 1.0) ** 2, 1e-6))
    viscous = max(mu_v, 0.0) * rp.viscous_shape

    def radii(r_guess: float) -> np.ndarray:
        return (tq / fn - viscous * r_guess * r_guess * w) / (mu_c * slack)

    candidates = near_rotation
    r_est = float(np.median(radii(0.0)[candidates])) if candidates.any() else NAN
    if not math.isfinite(r_est):
        return nan
    gate = rp.min_slip_speed
    used = candidates
    for scale in (1.0, 0.5, 0.25, 0.0):
        # The last pass (no gate) keeps a tiny radius measurable so that it is reported, and
        # flagged by the plausibility range, rather than lost.
        gate = rp.min_slip_speed * scale
        used = candidates & (w * r_est >= gate)
        if int(used.sum()) >= params.min_samples_rotational:
            break
    for _ in range(3):
        r_est = float(np.median(radii(r_est)[used]))
    ri = radii(r_est)[used]
    n = int(ri.size)
    resid = ri - r_est
    # Standard error of a median ≈ 1.2533·σ/√n_eff, σ from the MAD (robust to stick-slip bursts).
    sigma = 1.4826 * float(np.median(np.abs(resid)))
    rho = min(max(lag1_autocorrelation(resid), 0.0), 0.95)
    n_eff = max(n * (1.0 - rho) / (1.0 + rho), 1.0)
    stat = 1.2533 * sigma / math.sqrt(n_eff)
    prop = r_est * mu_c_std / mu_c if math.isfinite(mu_c_std) else 0.0
    r_std = math.sqrt(stat ** 2 + (params.r_std_floor * r_est) ** 2 + prop ** 2)
    return RadiusFit(r_est, r_std, n, math.sqrt(float(resid @ resid) / n), gate)


def rotational_result(base: FingerContact, fit: RadiusFit,
                      params: ContactEstimatorParams) -> FingerContact:
    """Add the rotational-phase result to a finger's linear result (§3.4, §3.7).

    ``u = viscous_shape·r²`` (the viscous torsional term of §3.1 for the assumed map shape).

    Args:
        base: The finger's current properties (its ``μ_c`` is what ``fit`` used).
        fit: `fit_torsional_radius` of the finger's samples.
        params: Estimator parameters.
    """
    if not (base.linear_valid and math.isfinite(base.mu_c) and base.mu_c > 0.0) or fit.n == 0:
        return replace(base, r=NAN, u=NAN, r_std=NAN, n_rotational=fit.n,
                       rotational_residual_rms=fit.residual_rms, rotational_valid=False)
    r = fit.r
    u = params.rotational.viscous_shape * r * r
    ok = (fit.n >= params.min_samples_rotational and math.isfinite(r)
          and params.r_min <= r <= params.r_max and math.isfinite(fit.r_std))
    return replace(base, r=r, u=u, r_std=fit.r_std, n_rotational=fit.n,
                   rotational_residual_rms=fit.residual_rms, rotational_valid=ok)
