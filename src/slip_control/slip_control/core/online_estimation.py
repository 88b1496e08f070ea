# SPDX-License-Identifier: Apache-2.0
"""Online refinement of one finger's contact properties during controlled slip (§3.6, corrected).

Recursive least squares with forgetting factor ``λ`` per finger, run by
`slip_control.core.contact_estimator.ContactEstimator` (ONLINE phase) on every synchronised
sample while the slip controllers slide the object:

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
objects slide in the air below the exploration's 1 N gate).
"""
from __future__ import annotations

import math
from dataclasses import replace

from slip_control.core.contact import NAN, FingerContact
from slip_control.core.params import ContactEstimatorParams
from slip_control.core.signals import TwistSample, WrenchSample


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
