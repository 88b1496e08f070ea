# SPDX-License-Identifier: Apache-2.0
"""Contact-property estimator: phases, gating, reports (control_and_estimation §3; CE-3, CE-4).

`ContactEstimator` is the core of the ``contact_estimator`` node. Per finger, from bias-removed
wrenches and slip twists in the raw sensor frames (``f_n = |Fz|``, ``f_t = ‖(Fx, Fy)‖``,
``τ = Tz``, ``v = ‖(vx, vy)‖``, ``ω``), it gates the samples of a phase and hands them to the
fits of `slip_control.core.estimation_fits`:

* LINEAR (§3.3) — samples with ``f_n ≥ min_normal_force`` and ``|ω| ≤ max_abs_omega``;
  ``v < static_speed`` → static sample, else a sliding pair ``(v, f_t/f_n)``;
* ROTATIONAL (§3.4) — samples with ``f_n ≥ min_normal_force``, ``|ω| ≥ min_abs_omega``,
  ``v ≤ max_speed``; pairs ``(|ω|, |τ/f_n|)``;
* ONLINE (§3.6) — one `slip_control.core.online_estimation.OnlineFingerEstimator` per finger;
  results are published at most every ``publish_period`` once ``min_updates`` updates have been
  made, with ``online_updated = true`` and 1-σ values from the filter.

No silent defaults (CE-4): a phase in which no finger produced a valid result leaves the
published property set (values *and* source) unchanged and reports why (e.g. "no contact");
a partly valid result is published with its flags. The raw attempt is always reported.
Presets (`slip_control.core.contact_presets`) replace the set as a whole.

Timing: a step is triggered by a finger-1 twist; the finger-2 twist must be within
``sync_tolerance`` and both wrenches within ``ft_stale_after`` of its stamp, otherwise the
sample is skipped and counted as stale (§3.2). Phase windows are judged on stamps; `poll`
ends a phase whose window has passed even if no sample arrives.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from enum import IntEnum
from pathlib import Path

import yaml

from slip_control.core.contact import ContactProperties, ContactSource, FingerContact
from slip_control.core.contact_presets import load_presets
from slip_control.core.estimation_fits import (fit_line, fit_torsional_radius, linear_result,
                                              rotational_result)
from slip_control.core.online_estimation import OnlineFingerEstimator
from slip_control.core.params import ContactEstimatorParams
from slip_control.core.signals import SensorSnapshot, TwistSample, WrenchSample


class EstimationPhase(IntEnum):
    """Estimator phases (mirror ``slip_msgs/StartEstimation``)."""

    IDLE = 0
    LINEAR = 1
    ROTATIONAL = 2
    LIMIT_SURFACE = 3
    ONLINE = 4


class _Collector:
    """Gated samples of one finger in one phase."""

    __slots__ = (
        'gated',
        'lin_q',
        'lin_v',
        'no_contact',
        'rot_fn',
        'rot_ft',
        'rot_tau',
        'rot_w',
        'seen',
        'static_q',
    )

    def __init__(self) -> None:
        self.lin_v: list[float] = []
        self.lin_q: list[float] = []
        self.static_q: list[float] = []
        self.rot_w: list[float] = []      # |ω| [rad/s]
        self.rot_fn: list[float] = []     # f_n [N]
        self.rot_ft: list[float] = []     # f_t [N]
        self.rot_tau: list[float] = []    # torque about the centre of pressure [N·m]
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
                c.rot_fn.append(f_n)
                c.rot_ft.append(w.tangential_force)
                c.rot_tau.append(w.torque_about_cop(p.frames.pad_offset))

    def _finish(self) -> EstimatorReport:
        phase = self._phase
        p = self._p
        attempt: list[FingerContact] = []
        notes: list[str] = []
        for k, c in ((1, self._col[0]), (2, self._col[1])):
            if phase == EstimationPhase.LINEAR:
                v, q = _fast_enough(c.lin_v, c.lin_q, p.linear.fit_min_speed,
                                    p.min_samples_linear)
                fit = fit_line(v, q, min_span=p.min_speed_span)
                fc = linear_result(fit, c.static_q, p)
                ok = fc.linear_valid
                n_used = fit.n
                need = p.min_samples_linear
            else:
                base = self._props.finger(k)
                rfit = fit_torsional_radius(c.rot_w, c.rot_fn, c.rot_ft, c.rot_tau, base.mu_c,
                                            base.mu_c_std, base.mu_v, p)
                fc = rotational_result(base, rfit, p)
                ok = fc.rotational_valid
                n_used = rfit.n
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


def _fast_enough(v: list[float], q: list[float], min_speed: float, need: int
                 ) -> tuple[list[float], list[float]]:
    """The ``(v, q)`` pairs at ``v ≥ min_speed``, or all of them when fewer than ``need``."""
    keep = [(a, b) for a, b in zip(v, q) if a >= min_speed]
    if len(keep) < need:
        return v, q
    return [a for a, _ in keep], [b for _, b in keep]


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
