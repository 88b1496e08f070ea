# SPDX-License-Identifier: Apache-2.0
"""Contact-property estimator core (control_and_estimation §3; CE-3, CE-4).

Per finger, from bias-removed wrenches and slip twists in the raw sensor frames
(``f_n = |Fz|``, ``f_t = ‖(Fx, Fy)‖``, ``τ = Tz``, ``v = ‖(vx, vy)‖``, ``ω``):

LINEAR phase (§3.3) — samples with ``f_n ≥ min_normal_force`` and ``|ω| ≤ max_abs_omega``;
``q = f_t/f_n``; ``v < static_speed`` → static sample, else a pair ``(v, q)``. At the end::

    q = μ_c + μ_v·v                 (ordinary least squares; intercept μ_c, slope μ_v)
    μ_s = a_μs·μ_c,   a_μs = max(max(static q)/μ_c, 1)

If the speed span is below ``min_speed_span`` the slope is not identifiable: ``μ_v`` is
reported as 0 (``viscous_valid`` false) and ``μ_c`` is the mean ratio.

ROTATIONAL phase (§3.4) — samples with ``f_n ≥ min_normal_force``, ``|ω| ≥ min_abs_omega``,
``v ≤ max_speed``; ``y = |τ/f_n|`` [m]. At the end::

    y = b + a·|ω|    (OLS),   r = b/μ_c,   u = a/μ_v (μ_v ≠ 0) else r²,   |u| > k·r² → u = r²

Uncertainty: 1-σ standard error of the OLS intercept,
``σ_b² = s²·(1/n + x̄²/S_xx)`` with ``s² = RSS/(n − 2)`` (``s²/n`` with ``n − 1`` dof for the
intercept-only fit); ``σ_μc = σ_b`` of the linear fit and, by first-order propagation of
``r = b/μ_c``, ``σ_r = sqrt((σ_b/μ_c)² + (b·σ_μc/μ_c²)²)``.

Validity (§3.7): ``linear_valid`` ⇔ ``n_linear ≥ min_samples_linear``, ``0 < μ_c ≤ mu_c_max``,
fit finite; ``viscous_valid`` ⇔ linear valid and speed span ≥ ``min_speed_span``;
``static_valid`` ⇔ ``n_static ≥ 1`` (else ``μ_s = μ_c``); ``rotational_valid`` ⇔ linear valid,
``n_rotational ≥ min_samples_rotational``, ``r_min ≤ r ≤ r_max``.

No silent defaults (CE-4): a phase in which no finger produced a valid result leaves the
published property set (values *and* source) unchanged and reports why (e.g. "no contact");
a partly valid result is published with its flags. The raw attempt is always reported.

ONLINE phase (§3.6, corrected) — recursive least squares with forgetting factor ``λ`` per
finger, run on every synchronised sample while the slip controllers slide the object:

* ``μ_c, μ_v`` from samples with ``v ≥ online.min_speed``, ``|ω| ≤ online.max_abs_omega``::

      h_t = v/‖(r·ω, v)‖,   f_t ≈ [h_t·f_n, v·f_n]·[μ_c, μ_v]ᵀ   (the f_n factor restored)

* ``r`` from samples with ``|ω| ≥ rotational.min_abs_omega`` using the pad's limit surface,
  a superellipse with exponent ``n = online.limit_surface_exponent``: while slipping,
  ``(f_c/(μ_c f_n))ⁿ + (τ_c/(μ_c r f_n))ⁿ = 1`` with the Coulomb parts ``f_c = f_t − μ_v·v·f_n``
  and ``τ_c = |τ| − μ_v·u·|ω|·f_n``, i.e.::

      τ_c ≈ r·μ_c f_n·(1 − ρⁿ)^(1/n),   ρ = f_c/(μ_c f_n) ≤ online.max_load_ratio

  which stays unbiased when the pads also carry a tangential load (gravity) during rotation.
  ``n = 2`` is the ellipsoid of the controllers; the exact limit surface of a uniformly pressed
  disc (the simulated pads, `friction_models.core.limit_surface`) lies inside it — at ρ = 0.54
  the torque is 0.92, at ρ = 0.89 only 0.79 of the ellipsoid's — and ``n = 1.7`` matches it to
  3.5 % in torque for ρ ≤ 0.95. ``r`` is only updated while ``μ_c`` is known to
  ``online.r_needs_mu_c_rel_std`` (relative 1-σ): with ρ = 0.3–0.9 a 1 % error of ``μ_c``
  moves ``r`` by 2–4 %.

Each update is a Kalman step with measurement noise ``force_noise`` / ``torque_noise``. The
``(μ_c, μ_v)`` pair uses directional forgetting (only the excited direction is forgotten, so
the poorly excited ``μ_c``/``μ_v`` split cannot drift and nothing winds up); its prior is the
starting ``μ_c`` with 1-σ ``max(σ_start, initial_std_mu_c)`` and the starting ``μ_v`` (0 unless
``viscous_valid``) with 1-σ ``initial_std_mu_v``. ``r`` is scalar and forgotten only when
updated, its variance bounded by the prior. The velocity at a wrench's stamp is reconstructed
from the three velocity intervals around it, and a wrench is used only when the two intervals
next to its stamp both show slip (stick–slip, unsynchronised sensors, see
`OnlineFingerEstimator.update`); online samples need ``f_n ≥ online.min_normal_force`` (light
objects slide in the air below the exploration's 1 N gate). Results are published at most
every ``publish_period`` once ``min_updates`` updates have been made, with
``online_updated = true`` and 1-σ values from the filter.

Timing: a step is triggered by a finger-1 twist; the finger-2 twist must be within
``sync_tolerance`` and both wrenches within ``ft_stale_after`` of its stamp, otherwise the
sample is skipped and counted as stale (§3.2). Phase windows are judged on stamps; `poll`
ends a phase whose window has passed even if no sample arrives.
"""
from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from enum import IntEnum
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import ArrayLike

from slip_control.core.contact import NAN, ContactProperties, ContactSource, FingerContact
from slip_control.core.params import ContactEstimatorParams
from slip_control.core.signals import SensorSnapshot, TwistSample, WrenchSample


class EstimationPhase(IntEnum):
    """Estimator phases (mirror ``slip_msgs/StartEstimation``)."""

    IDLE = 0
    LINEAR = 1
    ROTATIONAL = 2
    LIMIT_SURFACE = 3
    ONLINE = 4


# ---------------------------------------------------------------------------------------------
# Fits (pure functions)
# ---------------------------------------------------------------------------------------------

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
    """

    intercept: float
    slope: float
    intercept_std: float
    residual_rms: float
    n: int
    x_span: float
    slope_fitted: bool


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
                       True)
    resid = ya - y_mean
    rss = float(resid @ resid)
    std = math.sqrt(rss / (n - 1) / n) if n >= 2 else NAN
    return LineFit(y_mean, 0.0, std, math.sqrt(rss / n), n, span, False)


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
    return FingerContact(mu_c=mu_c, mu_s=mu_s, mu_v=mu_v, mu_c_std=fit.intercept_std,
                         n_linear=fit.n, n_static=n_static,
                         linear_residual_rms=fit.residual_rms, linear_valid=ok,
                         viscous_valid=viscous, static_valid=static)


def rotational_result(base: FingerContact, fit: LineFit,
                      params: ContactEstimatorParams) -> FingerContact:
    """Add the rotational-phase result to a finger's linear result (§3.4, §3.7).

    Args:
        base: The finger's current properties (its ``μ_c``, ``μ_v`` are used).
        fit: Fit of ``|τ/f_n|`` [m] against ``|ω|`` [rad/s].
        params: Estimator parameters.
    """
    mu_c = base.mu_c
    if not (base.linear_valid and math.isfinite(mu_c) and mu_c > 0.0) or fit.n == 0:
        return replace(base, r=NAN, u=NAN, r_std=NAN, n_rotational=fit.n,
                       rotational_residual_rms=fit.residual_rms, rotational_valid=False)
    b = fit.intercept
    r = b / mu_c
    mu_c_std = base.mu_c_std if math.isfinite(base.mu_c_std) else 0.0
    r_std = math.sqrt((fit.intercept_std / mu_c) ** 2 + (b * mu_c_std / mu_c ** 2) ** 2)
    r2 = r * r
    if base.viscous_valid and fit.slope_fitted and base.mu_v != 0.0:
        u = fit.slope / base.mu_v
    else:
        u = r2
    if abs(u) > params.u_clamp_factor * r2:
        u = r2
    ok = (fit.n >= params.min_samples_rotational and math.isfinite(r)
          and params.r_min <= r <= params.r_max and math.isfinite(r_std))
    return replace(base, r=r, u=u, r_std=r_std, n_rotational=fit.n,
                   rotational_residual_rms=fit.residual_rms, rotational_valid=ok)


# ---------------------------------------------------------------------------------------------
# Online estimator (per finger)
# ---------------------------------------------------------------------------------------------

def _at_wrench(before: float, at: float, after: float, x: float) -> float:
    """Value at ``x`` of the mean-preserving quadratic through three interval means.

    The cells are ``[−1, 0]``, ``[0, 1]``, ``[1, 2]`` (equal widths) with means ``before``,
    ``at``, ``after`` (any one velocity component, m/s or rad/s); ``x`` ∈ (0, 1] is the position
    in the middle cell, the result is in the unit of the means. A velocity
    sample is the mean over its interval, so under stick–slip (bursts of two or three
    intervals) the containing interval's mean misses the velocity at a wrench at its end by
    10–13 mm/s rms in the simulated cell; this reconstruction by 2–5 mm/s.
    """
    s = x - 0.5
    return (at + 0.5 * (after - before) * s
            + 0.5 * (before + after - 2.0 * at) * (s * s - 1.0 / 12.0))


class OnlineFingerEstimator:
    """Recursive estimate of ``(μ_c, μ_v)`` and ``r`` for one finger (§3.6, corrected).

    Args:
        base: Starting properties (needs ``linear_valid``; ``r`` is updated only when
            ``rotational_valid``).
        params: Estimator parameters.
    """

    def __init__(self, base: FingerContact, params: ContactEstimatorParams) -> None:
        o = params.online
        self._p = params
        self._base = base
        self._lam = o.forgetting
        self._var_f = o.force_noise ** 2
        self._var_t = o.torque_noise ** 2
        # θ = (μ_c, μ_v) and its symmetric 2×2 information matrix (i00, i01, i11), kept as
        # floats: numpy's per-call overhead dominates at this size.
        self._mu_c = base.mu_c
        self._mu_v = base.mu_v if base.viscous_valid else 0.0
        s_mu = max(base.mu_c_std if math.isfinite(base.mu_c_std) else 0.0, o.initial_std_mu_c)
        self._i00, self._i01, self._i11 = 1.0 / s_mu ** 2, 0.0, 1.0 / o.initial_std_mu_v ** 2
        self._r_known = base.rotational_valid and math.isfinite(base.r)
        self._r = base.r if self._r_known else NAN
        s_r = max(base.r_std if math.isfinite(base.r_std) else 0.0, o.initial_std_r)
        self._Pr0 = s_r ** 2
        self._Pr = self._Pr0
        self._u = base.u if math.isfinite(base.u) else 0.0
        self._twists: list[TwistSample] = []      # last distinct twists, ascending stamps
        self._wrenches: list[WrenchSample] = []   # wrenches waiting for their intervals
        self.n_linear_updates = 0
        self.n_rotational_updates = 0

    @property
    def mu_c(self) -> float:
        """Current ``μ_c`` [-]."""
        return self._mu_c

    @property
    def mu_v(self) -> float:
        """Current ``μ_v`` [1/(m/s)]."""
        return self._mu_v

    @property
    def r(self) -> float:
        """Current ``r`` [m] (NaN if not known)."""
        return self._r

    def update(self, w: WrenchSample, tw: TwistSample) -> tuple[bool, bool]:
        """Take this finger's latest wrench and twist; update with every aligned wrench.

        A twist is the mean velocity over the interval that ends at its stamp; a wrench is
        instantaneous, and the two fingers' sensors are not synchronised (finger 1's wrench
        falls on an interval boundary, finger 2's at ≈ 63 % of an interval). Under stick–slip
        the object can stop inside an interval, so a wrench is used only when the interval
        that contains its stamp and the neighbour on its side both show slip; the velocity
        at the wrench is the mean-preserving quadratic through the three intervals around it
        (`_at_wrench`). A wrench therefore waits for the next twist (≈ 8 ms) and static loads
        (``f_t/f_n < μ_c``) stay out of the fit.

        Args:
            w: Latest wrench of this finger (raw frame).
            tw: Latest twist of this finger (raw frame).

        Returns:
            ``(mu_updated, r_updated)``: whether any update of each kind was made.
        """
        tws, wrs = self._twists, self._wrenches
        if not tws or tw.stamp > tws[-1].stamp:
            tws.append(tw)
            if len(tws) > 4:
                del tws[0]
        if not wrs or w.stamp > wrs[-1].stamp:
            wrs.append(w)
        mu_done = r_done = False
        while wrs and tws:
            w0 = wrs[0]
            if w0.stamp <= tws[0].stamp:           # before the known intervals: unusable
                del wrs[0]
                continue
            k = next((i for i in range(1, len(tws)) if tws[i].stamp >= w0.stamp), None)
            if k is None or k + 1 >= len(tws):     # wait for the interval after it
                break
            del wrs[0]
            a, b = self._use(w0, tws[k - 1], tws[k], tws[k + 1])
            mu_done |= a
            r_done |= b
        return mu_done, r_done

    def _use(self, w: WrenchSample, before: TwistSample, at: TwistSample,
             after: TwistSample) -> tuple[bool, bool]:
        """Gate and use one wrench with the three velocity intervals around it.

        The twist at the wrench's stamp is reconstructed from the three interval means
        (`_at_wrench`); a wrench is used only when the two intervals next to its stamp (the
        one containing it and the neighbour on its side) both show slip, so the object cannot
        have stopped between them.
        """
        p, o = self._p, self._p.online
        f_n = abs(w.fz)
        if f_n < o.min_normal_force:
            return False, False
        width = at.stamp - before.stamp
        if not (width > 0.0 and abs(after.stamp - at.stamp - width) <= 0.5 * width):
            return False, False        # a twist is missing: the reconstruction needs 3 equal cells
        x = (w.stamp - before.stamp) / width
        near = (before, at) if x < 0.5 else (at, after)
        vx = _at_wrench(before.vx, at.vx, after.vx, x)
        vy = _at_wrench(before.vy, at.vy, after.vy, x)
        aw = abs(_at_wrench(before.omega, at.omega, after.omega, x))
        v = math.hypot(vx, vy)
        f_t = math.hypot(w.fx, w.fy)
        mu_done = r_done = False
        if (v >= o.min_speed and min(math.hypot(t.vx, t.vy) for t in near) >= o.min_speed
                and max(abs(t.omega) for t in (before, at, after)) <= o.max_abs_omega):
            rw = self._r * aw if self._r_known else 0.0
            h_t = v / math.hypot(rw, v)
            self._update_mu(h_t * f_n, v * f_n, f_t)
            self.n_linear_updates += 1
            mu_done = True
        if (self._r_known and min(abs(t.omega) for t in near) >= p.rotational.min_abs_omega
                and aw >= p.rotational.min_abs_omega
                and self._mu_c_known()):
            cap = self.mu_c * f_n
            load = max(f_t - self.mu_v * v * f_n, 0.0) / cap if cap > 0.0 else math.inf
            # Close to the translational limit the torsional capacity is ill-conditioned.
            if load <= o.max_load_ratio:
                n = o.limit_surface_exponent
                psi = cap * (1.0 - load ** n) ** (1.0 / n)
                y = abs(w.tz) - self.mu_v * self._u * aw * f_n
                k = self._Pr * psi / (self._var_t + psi * psi * self._Pr)
                self._r += k * (y - self._r * psi)
                self._Pr = min((1.0 - k * psi) * self._Pr / self._lam, self._Pr0)
                self.n_rotational_updates += 1
                r_done = True
        return mu_done, r_done

    def _update_mu(self, a: float, b: float, y: float) -> None:
        """One step for ``y = a·μ_c + b·μ_v + noise`` with directional forgetting.

        Information form, ``I = P⁻¹``, ``φ = (a, b)``, ``σ = force_noise``::

            I ← I − (1 − λ)·(Iφ)(Iφ)ᵀ/(φᵀIφ)     forget only along the excited direction
            I ← I + φφᵀ/σ²                        add the new sample
            θ ← θ + I⁻¹φ·(y − φᵀθ)/σ²

        Uniform forgetting would also erase what the accelerating and decelerating parts of a
        trapezoid taught about the ``μ_c``/``μ_v`` split; in the cruise phase only
        ``μ_c + v·μ_v`` is excited and the pair would then drift along that ridge.
        Directional forgetting (Kulhavý and Kárný, 1984) keeps ``I`` positive definite and
        bounded, so there is no wind-up either.
        """
        i00, i01, i11 = self._i00, self._i01, self._i11
        h0 = i00 * a + i01 * b
        h1 = i01 * a + i11 * b
        q = a * h0 + b * h1
        if q > 0.0:
            k = (1.0 - self._lam) / q
            i00 -= k * h0 * h0
            i01 -= k * h0 * h1
            i11 -= k * h1 * h1
        w = 1.0 / self._var_f
        i00 += w * a * a
        i01 += w * a * b
        i11 += w * b * b
        det = i00 * i11 - i01 * i01
        p00, p01, p11 = i11 / det, -i01 / det, i00 / det
        e = y - (a * self._mu_c + b * self._mu_v)
        self._mu_c += w * (p00 * a + p01 * b) * e
        self._mu_v += w * (p01 * a + p11 * b) * e
        self._i00, self._i01, self._i11 = i00, i01, i11

    def _mu_c_known(self) -> bool:
        """``μ_c`` is precise enough to update ``r`` with (``r_needs_mu_c_rel_std``).

        The 1-σ is the filter's once it has made ``min_updates`` updates, else the starting
        set's (the filter starts from ``max(σ_start, initial_std_mu_c)`` on purpose, so that a
        poor start can move; that floor says nothing about how good the start is).
        """
        o = self._p.online
        std = self.mu_c_std
        if self.n_linear_updates < o.min_updates and math.isfinite(self._base.mu_c_std):
            std = min(std, self._base.mu_c_std)
        return std <= o.r_needs_mu_c_rel_std * self._mu_c

    @property
    def mu_c_std(self) -> float:
        """1-σ of ``μ_c`` from the information matrix [-]."""
        det = self._i00 * self._i11 - self._i01 * self._i01
        return math.sqrt(self._i11 / det)

    def result(self) -> FingerContact:
        """Current properties of this finger, flags re-checked against the limits."""
        p, b = self._p, self._base
        fc = b
        if self.n_linear_updates >= p.online.min_updates:
            mu_c = self.mu_c
            ratio = b.mu_s / b.mu_c if b.static_valid and b.mu_c > 0.0 else 1.0
            lin_ok = b.linear_valid and math.isfinite(mu_c) and 0.0 < mu_c <= p.mu_c_max
            fc = replace(fc, mu_c=mu_c, mu_s=ratio * mu_c,
                         mu_v=self.mu_v if b.viscous_valid else b.mu_v,
                         mu_c_std=self.mu_c_std, linear_valid=lin_ok)
        if self._r_known and self.n_rotational_updates >= p.online.min_updates:
            r = self._r
            rot_ok = (b.rotational_valid and fc.linear_valid and math.isfinite(r)
                      and p.r_min <= r <= p.r_max)
            fc = replace(fc, r=r, r_std=math.sqrt(self._Pr), rotational_valid=rot_ok)
        return fc


# ---------------------------------------------------------------------------------------------
# Estimator (phases, gating, reports)
# ---------------------------------------------------------------------------------------------

class _Collector:
    """Gated samples of one finger in one phase."""

    __slots__ = (
        'gated',
        'lin_q',
        'lin_v',
        'no_contact',
        'rot_w',
        'rot_y',
        'seen',
        'static_q',
    )

    def __init__(self) -> None:
        self.lin_v: list[float] = []
        self.lin_q: list[float] = []
        self.static_q: list[float] = []
        self.rot_w: list[float] = []
        self.rot_y: list[float] = []
        self.seen = 0
        self.no_contact = 0
        self.gated = 0


@dataclass(frozen=True, slots=True)
class EstimatorReport:
    """What a finished phase (or an online update) produced.

    Attributes:
        phase: The phase that produced it.
        success: Every finger got a valid result for this phase.
        message: Human-readable summary (names the failure, e.g. "no contact").
        properties: The current property set after this report.
        changed: ``properties`` was replaced: publish it (latched).
        attempt: Per-finger results of this phase, with flags (also when not published).
        stale_skipped: Samples skipped as unsynchronised or stale during the phase.
    """

    phase: EstimationPhase
    success: bool
    message: str
    properties: ContactProperties
    changed: bool
    attempt: tuple[FingerContact, FingerContact]
    stale_skipped: int


@dataclass(frozen=True, slots=True)
class StartOutcome:
    """Answer to a ``StartEstimation`` request.

    Attributes:
        accepted: The phase started (or, for IDLE, the estimator is idle now).
        message: Why not, or what started.
        report: Report of a running phase that this request finished first, if any.
    """

    accepted: bool
    message: str
    report: EstimatorReport | None = None


@dataclass(frozen=True, slots=True)
class EstimatorDiagnostics:
    """Snapshot for the ``estimate`` diagnostics task.

    Attributes:
        phase: Current phase.
        source: Source of the current properties.
        valid: Current properties valid.
        stale_skipped_total: Unsynchronised/stale samples skipped since construction.
        samples: Gated samples of the running phase per finger ``(lin, static, rot)``.
        last_message: Message of the last report or start.
    """

    phase: EstimationPhase
    source: ContactSource
    valid: bool
    stale_skipped_total: int
    samples: tuple[tuple[int, int, int], tuple[int, int, int]]
    last_message: str


def start_precheck(inputs: SensorSnapshot, t: float,
                   params: ContactEstimatorParams) -> tuple[bool, str]:
    """Whether a LINEAR or ROTATIONAL phase started at ``t`` can collect anything (CE-4).

    Refuses (so the caller answers ``accepted = false`` with the reason instead of letting the
    phase run into a silent empty fit) when a stream never delivered, is older than
    ``start_max_age``, is non-finite, or when either pad has ``f_n < min_normal_force``
    ("no contact").

    Args:
        inputs: Latest samples of both fingers.
        t: Request time [s] (same clock as the stamps).
        params: Estimator parameters.

    Returns:
        ``(ok, message)``.
    """
    streams = (('finger 1 wrench', inputs.wrench_1), ('finger 2 wrench', inputs.wrench_2),
               ('finger 1 velocity', inputs.twist_1), ('finger 2 velocity', inputs.twist_2))
    missing = [name for name, s in streams if s is None]
    if missing:
        return False, 'no samples received yet from: ' + ', '.join(missing)
    old = [f'{name} ({t - s.stamp:.3f} s old)' for name, s in streams
           if s is not None and t - s.stamp > params.start_max_age]
    if old:
        return False, (f'stale sensor data (start_max_age = {params.start_max_age} s): '
                       + ', '.join(old))
    w1, w2, v1, v2 = inputs.wrench_1, inputs.wrench_2, inputs.twist_1, inputs.twist_2
    assert w1 is not None and w2 is not None and v1 is not None and v2 is not None
    checks = (('finger 1 wrench', w1.finite()), ('finger 2 wrench', w2.finite()),
              ('finger 1 velocity', v1.usable()), ('finger 2 velocity', v2.usable()))
    bad = [name for name, ok in checks if not ok]
    if bad:
        return False, 'invalid (non-finite or flagged) samples from: ' + ', '.join(bad)
    f1, f2 = w1.normal_force, w2.normal_force
    if min(f1, f2) < params.min_normal_force:
        return False, (f'no contact: f_n = {f1:.3f} N (finger 1), {f2:.3f} N (finger 2); both '
                       f'pads need f_n >= min_normal_force = {params.min_normal_force} N')
    return True, ''


class ContactEstimator:
    """Contact-property estimator: phases, gating, fits, online update, presets (§3).

    Args:
        params: Estimator parameters.
        initial: Initial property set (default: the DEFAULT placeholder, never valid).
    """

    def __init__(self, params: ContactEstimatorParams,
                 initial: ContactProperties | None = None) -> None:
        self._p = params
        self._props = initial if initial is not None else ContactProperties.default()
        self._phase = EstimationPhase.IDLE
        self._t_begin = 0.0
        self._t_end = math.inf
        self._col = (_Collector(), _Collector())
        self._phase_stale = 0
        self._stale_total = 0
        self._online: tuple[OnlineFingerEstimator, OnlineFingerEstimator] | None = None
        self._online_last_pub = -math.inf
        self._online_dirty = False
        self._last_message = 'idle'

    # -- service-level API ------------------------------------------------------------------

    @property
    def params(self) -> ContactEstimatorParams:
        """Parameter snapshot."""
        return self._p

    @property
    def properties(self) -> ContactProperties:
        """Current property set (what ``contact/properties`` carries)."""
        return self._props

    @property
    def phase(self) -> EstimationPhase:
        """Current phase."""
        return self._phase

    def update_params(self, params: ContactEstimatorParams) -> bool:
        """Swap in a new parameter snapshot if idle; ``False`` = retry after the phase ends.

        A running phase (including ONLINE) keeps the snapshot it started with, so its gates
        and fit limits never change half-way.
        """
        if self._phase != EstimationPhase.IDLE:
            return False
        self._p = params
        return True

    def get_properties(self) -> tuple[ContactProperties, bool, str]:
        """``GetContactProperties``: ``(properties, valid, message)``."""
        return self._props, self._props.valid, self._last_message

    def set_properties(self, props: ContactProperties, message: str = '') -> None:
        """Replace the current set (preset, ground truth); discards any running phase."""
        self._reset_phase()
        self._props = props
        self._last_message = message or f'properties set: {props.describe()}'

    def load_preset(self, path: str | Path, name: str) -> tuple[bool, str]:
        """Load preset ``name`` from a CSV or YAML file (see `load_presets`) as the current set.

        Returns:
            ``(ok, message)``; the current set is unchanged on failure.
        """
        try:
            presets = load_presets(path, self._p)
        except (OSError, ValueError, KeyError, yaml.YAMLError) as exc:
            return False, f'cannot load presets from {str(path)!r}: {exc}'
        if name not in presets:
            return False, (f'preset {name!r} not in {str(path)!r} '
                           f'(have: {", ".join(sorted(presets))})')
        self.set_properties(presets[name], f'preset {name!r} loaded from {str(path)!r}')
        return True, self._last_message

    def start(self, phase: int, duration: float, t: float) -> StartOutcome:
        """``StartEstimation``: start a phase at time ``t`` [s] for ``duration`` [s].

        A running LINEAR or ROTATIONAL phase is finished first (fitted with the samples it
        has; the report is returned), so a ROTATIONAL request arriving as the LINEAR window
        closes sees the linear result. IDLE discards a running phase and stops ONLINE.

        Args:
            phase: `EstimationPhase` value.
            duration: Collection time [s], finite and > 0 (ignored for IDLE and ONLINE).
            t: Start time [s] on the stamps' clock.
        """
        try:
            ph = EstimationPhase(phase)
        except ValueError:
            return self._started(False, f'unknown phase {phase!r} (0 IDLE, 1 LINEAR, '
                                        '2 ROTATIONAL, 3 LIMIT_SURFACE, 4 ONLINE)')
        if ph == EstimationPhase.LIMIT_SURFACE:
            return self._started(False, 'LIMIT_SURFACE estimation is not implemented')
        if ph == EstimationPhase.IDLE:
            was = self._phase
            self._reset_phase()
            return self._started(True, f'idle (stopped {was.name})')
        if ph in (EstimationPhase.LINEAR, EstimationPhase.ROTATIONAL) and not (
                isinstance(duration, (int, float)) and math.isfinite(duration)
                and duration > 0.0):
            return self._started(False, f'duration = {duration!r} s must be finite and > 0')
        if ph == EstimationPhase.ONLINE and not self._p.online.enabled:
            return self._started(False, 'ONLINE estimation is disabled (online.enabled = false)')
        report = None
        if self._phase in (EstimationPhase.LINEAR, EstimationPhase.ROTATIONAL):
            report = self._finish()
        if ph == EstimationPhase.ROTATIONAL:
            pr = self._props
            if not (pr.source == ContactSource.ESTIMATED and pr.linear_valid):
                return self._started(False, 'ROTATIONAL needs a valid LINEAR result for both '
                                            f'fingers first (current: {pr.describe()})', report)
        if ph == EstimationPhase.ONLINE:
            pr = self._props
            if not pr.linear_valid:
                return self._started(False, 'ONLINE needs valid mu_c for both fingers '
                                            f'(current: {pr.describe()})', report)
            self._reset_phase()
            self._online = (OnlineFingerEstimator(pr.finger_1, self._p),
                            OnlineFingerEstimator(pr.finger_2, self._p))
            self._online_last_pub = t
            self._online_dirty = False
            self._phase = ph
            return self._started(True, 'ONLINE started', report)
        self._reset_phase()
        self._phase = ph
        self._t_begin = t
        self._t_end = t + duration
        return self._started(True, f'{ph.name} started for {duration:.3f} s', report)

    def step(self, inputs: SensorSnapshot, t: float) -> EstimatorReport | None:
        """Process the latest samples (call on each finger-1 twist).

        Args:
            inputs: Latest samples of both fingers.
            t: Current time [s] (node clock); ends the phase once past its window.

        Returns:
            A report when a phase finished or an online update is due, else ``None``.
        """
        if self._phase == EstimationPhase.IDLE:
            return None
        sample = self._synchronised(inputs)
        if sample is not None:
            stamp = sample[2].stamp
            if self._phase == EstimationPhase.ONLINE:
                return self._online_step(sample, stamp)
            if self._t_begin <= stamp < self._t_end:
                self._collect(sample)
        return self.poll(t)

    def poll(self, t: float) -> EstimatorReport | None:
        """End a LINEAR/ROTATIONAL phase whose window has passed at time ``t`` [s]."""
        if self._phase in (EstimationPhase.LINEAR, EstimationPhase.ROTATIONAL) \
                and t >= self._t_end:
            return self._finish()
        return None

    def reset(self, t: float) -> None:
        """Clock jumped backwards: discard a running LINEAR/ROTATIONAL phase.

        Its window is meaningless on the new clock; an ONLINE phase continues with its publish
        timer re-based.

        Args:
            t: Current time [s] on the new clock.
        """
        if self._phase in (EstimationPhase.LINEAR, EstimationPhase.ROTATIONAL):
            was = self._phase
            self._reset_phase()
            self._last_message = f'{was.name} phase discarded: the clock jumped backwards'
        self._online_last_pub = t

    def diagnostics(self) -> EstimatorDiagnostics:
        """Snapshot for diagnostics."""
        def counts(c: _Collector) -> tuple[int, int, int]:
            return len(c.lin_v), len(c.static_q), len(c.rot_w)
        return EstimatorDiagnostics(self._phase, self._props.source, self._props.valid,
                                    self._stale_total, (counts(self._col[0]),
                                                        counts(self._col[1])),
                                    self._last_message)

    # -- internals --------------------------------------------------------------------------

    def _started(self, ok: bool, message: str,
                 report: EstimatorReport | None = None) -> StartOutcome:
        self._last_message = message
        return StartOutcome(ok, message, report)

    def _reset_phase(self) -> None:
        self._phase = EstimationPhase.IDLE
        self._t_end = math.inf
        self._col = (_Collector(), _Collector())
        self._phase_stale = 0
        self._online = None

    def _synchronised(self, s: SensorSnapshot) -> tuple[WrenchSample, WrenchSample,
                                                        TwistSample, TwistSample] | None:
        """The four samples if they are synchronised with the finger-1 twist (§3.2)."""
        p = self._p
        w1, w2, v1, v2 = s.wrench_1, s.wrench_2, s.twist_1, s.twist_2
        if v1 is None:
            return None
        ok = (w1 is not None and w2 is not None and v2 is not None and v1.usable()
              and v2.usable() and w1.finite() and w2.finite()
              and abs(v2.stamp - v1.stamp) <= p.sync_tolerance
              and abs(v1.stamp - w1.stamp) <= p.ft_stale_after
              and abs(v1.stamp - w2.stamp) <= p.ft_stale_after)
        if not ok:
            self._phase_stale += 1
            self._stale_total += 1
            return None
        assert w1 is not None and w2 is not None and v2 is not None
        return w1, w2, v1, v2

    def _collect(self, sample: tuple[WrenchSample, WrenchSample, TwistSample,
                                     TwistSample]) -> None:
        p = self._p
        linear = self._phase == EstimationPhase.LINEAR
        for c, w, tw in ((self._col[0], sample[0], sample[2]),
                         (self._col[1], sample[1], sample[3])):
            c.seen += 1
            f_n = abs(w.fz)
            if f_n < p.min_normal_force:
                c.no_contact += 1
                continue
            v = math.hypot(tw.vx, tw.vy)
            aw = abs(tw.omega)
            if linear:
                if aw > p.linear.max_abs_omega:
                    c.gated += 1
                    continue
                q = math.hypot(w.fx, w.fy) / f_n
                if v < p.linear.static_speed:
                    c.static_q.append(q)
                else:
                    c.lin_v.append(v)
                    c.lin_q.append(q)
            else:
                if aw < p.rotational.min_abs_omega or v > p.rotational.max_speed:
                    c.gated += 1
                    continue
                c.rot_w.append(aw)
                c.rot_y.append(abs(w.tz) / f_n)

    def _finish(self) -> EstimatorReport:
        phase = self._phase
        p = self._p
        attempt: list[FingerContact] = []
        notes: list[str] = []
        for k, c in ((1, self._col[0]), (2, self._col[1])):
            if phase == EstimationPhase.LINEAR:
                fit = fit_line(c.lin_v, c.lin_q, min_span=p.min_speed_span)
                fc = linear_result(fit, c.static_q, p)
                ok = fc.linear_valid
                n_used = fit.n
                need = p.min_samples_linear
            else:
                fit = fit_line(c.rot_w, c.rot_y, min_span=0.0)
                fc = rotational_result(self._props.finger(k), fit, p)
                ok = fc.rotational_valid
                n_used = fit.n
                need = p.min_samples_rotational
            attempt.append(fc)
            note = _ok_note(phase, fc) if ok else _fail_note(phase, fc, c, n_used, need, p,
                                                             self._phase_stale)
            notes.append(f'finger {k}: {note}')
        f1, f2 = attempt
        flag = 'linear_valid' if phase == EstimationPhase.LINEAR else 'rotational_valid'
        valid1, valid2 = getattr(f1, flag), getattr(f2, flag)
        changed = valid1 or valid2
        if changed:
            if phase == EstimationPhase.LINEAR:
                new = ContactProperties(f1, f2, ContactSource.ESTIMATED)
            else:
                new = replace(self._props, finger_1=f1, finger_2=f2,
                              source=ContactSource.ESTIMATED)
            self._props = new
        head = (f'{phase.name} estimation '
                + ('succeeded' if valid1 and valid2 else
                   'partly failed' if changed else 'failed, properties unchanged'))
        message = f'{head}; ' + '; '.join(notes)
        report = EstimatorReport(phase=phase, success=valid1 and valid2, message=message,
                                 properties=self._props, changed=changed,
                                 attempt=(f1, f2), stale_skipped=self._phase_stale)
        self._reset_phase()
        self._last_message = message
        return report

    def _online_step(self, sample: tuple[WrenchSample, WrenchSample, TwistSample,
                                         TwistSample], stamp: float) -> EstimatorReport | None:
        assert self._online is not None
        e1, e2 = self._online
        a = e1.update(sample[0], sample[2])
        b = e2.update(sample[1], sample[3])
        self._online_dirty |= any(a) or any(b)
        o = self._p.online
        if not self._online_dirty or stamp - self._online_last_pub < o.publish_period:
            return None
        if min(e1.n_linear_updates, e2.n_linear_updates) < o.min_updates and \
                min(e1.n_rotational_updates, e2.n_rotational_updates) < o.min_updates:
            return None
        f1, f2 = e1.result(), e2.result()
        self._props = replace(self._props, finger_1=f1, finger_2=f2,
                              source=ContactSource.ESTIMATED, online_updated=True)
        self._online_last_pub = stamp
        self._online_dirty = False
        message = (f'online update: mu_c {f1.mu_c:.3f}/{f2.mu_c:.3f}, '
                   f'r {_mm(f1.r)}/{_mm(f2.r)} mm')
        self._last_message = message
        return EstimatorReport(EstimationPhase.ONLINE, self._props.valid, message,
                               self._props, True, (f1, f2), self._phase_stale)


def _mm(r: float) -> str:
    return 'nan' if not math.isfinite(r) else f'{1000.0 * r:.2f}'


def _ok_note(phase: EstimationPhase, f: FingerContact) -> str:
    if phase == EstimationPhase.LINEAR:
        return (f'mu_c={f.mu_c:.3f}±{f.mu_c_std:.3f} (n={f.n_linear}, static {f.n_static}'
                f'{"" if f.viscous_valid else ", mu_v not identifiable"})')
    return f'r={_mm(f.r)}±{_mm(f.r_std)} mm (n={f.n_rotational})'


def _fail_note(phase: EstimationPhase, f: FingerContact, c: _Collector, n_used: int,
               need: int, p: ContactEstimatorParams, stale: int) -> str:
    if c.seen == 0:
        return f'no synchronised samples ({stale} skipped as stale or unsynchronised)'
    if c.no_contact == c.seen:
        return (f'no contact: 0 of {c.seen} samples had f_n >= {p.min_normal_force} N')
    if n_used < need:
        return (f'too few samples: {n_used} < {need} ({c.no_contact} below the f_n gate, '
                f'{c.gated} outside the motion gates)')
    if phase == EstimationPhase.LINEAR:
        return f'mu_c = {f.mu_c:.4f} outside (0, {p.mu_c_max}]'
    if not math.isfinite(f.mu_c):
        return 'no valid linear result'
    return f'r = {_mm(f.r)} mm outside [{_mm(p.r_min)}, {_mm(p.r_max)}] mm'


# ---------------------------------------------------------------------------------------------
# Presets
# ---------------------------------------------------------------------------------------------

def preset_finger(values: dict[str, Any], params: ContactEstimatorParams) -> FingerContact:
    """One finger of a preset, flags from the plausibility limits (sample counts are 0).

    Args:
        values: ``mu_c`` and ``r`` [m] required; ``mu_s`` (or ``mu_s_over_mu_c``), ``mu_v``
            [1/(m/s)], ``u`` [m²] optional.
        params: Estimator parameters (limits).
    """
    mu_c = float(values['mu_c'])
    r = float(values['r'])
    if 'mu_s' in values:
        mu_s = float(values['mu_s'])
    elif 'mu_s_over_mu_c' in values:
        mu_s = float(values['mu_s_over_mu_c']) * mu_c
    else:
        mu_s = NAN
    mu_v = float(values.get('mu_v', NAN))
    u = float(values.get('u', r * r))
    lin = math.isfinite(mu_c) and 0.0 < mu_c <= params.mu_c_max
    static = lin and math.isfinite(mu_s) and mu_s >= mu_c
    return FingerContact(
        mu_c=mu_c, mu_s=mu_s if static else mu_c, mu_v=mu_v if math.isfinite(mu_v) else 0.0,
        r=r, u=u, linear_valid=lin, viscous_valid=lin and math.isfinite(mu_v),
        static_valid=static,
        rotational_valid=lin and math.isfinite(r) and params.r_min <= r <= params.r_max)


def load_presets(path: str | Path, params: ContactEstimatorParams) -> dict[str, ContactProperties]:
    """Read contact presets (source PRESET) from a CSV or YAML file.

    CSV: the columns of ``data/contact_estimates_reference.csv`` (``object``, ``finger``,
    ``mu_c``, ``mu_s`` or ``mu_s_over_mu_c``, ``mu_v_per_m_per_s``, ``r_m``), one row per object
    and finger. YAML: ``{name: {finger_1: {mu_c, r, mu_s?, mu_v?, u?}, finger_2: {...}}}``,
    optionally under a top-level ``presets`` key.

    Raises:
        ValueError: on a missing finger or column.
    """
    path = Path(path)
    rows: dict[str, dict[int, dict[str, Any]]] = {}
    if path.suffix.lower() == '.csv':
        with path.open(newline='') as fh:
            for row in csv.DictReader(fh):
                vals: dict[str, Any] = {'mu_c': row['mu_c'], 'r': row['r_m']}
                if row.get('mu_s'):
                    vals['mu_s'] = row['mu_s']
                elif row.get('mu_s_over_mu_c'):
                    vals['mu_s_over_mu_c'] = row['mu_s_over_mu_c']
                if row.get('mu_v_per_m_per_s'):
                    vals['mu_v'] = row['mu_v_per_m_per_s']
                rows.setdefault(row['object'], {})[int(row['finger'])] = vals
    else:
        data = yaml.safe_load(path.read_text())
        if isinstance(data, dict) and 'presets' in data:
            data = data['presets']
        if not isinstance(data, dict):
            raise ValueError('expected a mapping of preset names')
        for name, fingers in data.items():
            rows[str(name)] = {1: dict(fingers['finger_1']), 2: dict(fingers['finger_2'])}
    out: dict[str, ContactProperties] = {}
    for name, fingers in rows.items():
        if set(fingers) != {1, 2}:
            raise ValueError(f'preset {name!r} needs fingers 1 and 2, has {sorted(fingers)}')
        out[name] = ContactProperties(preset_finger(fingers[1], params),
                                      preset_finger(fingers[2], params),
                                      ContactSource.PRESET, preset_name=name)
    return out
