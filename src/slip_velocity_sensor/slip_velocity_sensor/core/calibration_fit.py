# SPDX-License-Identifier: Apache-2.0
"""Offline fit of one chip axis from a stop-to-stop recording (hardware_protocols §3.7).

Input: a single-chip-mode recording of one chip axis, stamps t [s] and raw speed v [m/s],
taken while the surface was moved between two hard stops ``distance`` apart (`procedure`).

1. Integrate the position x (each line is the mean speed over the interval since the previous
   line, so ``x_k = x_{k-1} + v_k·(t_k − t_{k-1})``).
2. **Plateaus**: runs of ≥ ``plateau_min_duration`` (2 s) in which x changes by less than
   ``plateau_tolerance`` (1e-3 mm); runs whose levels differ by ≤ ``plateau_separation``
   (25 mm) are the same rest position and are merged.
3. **Traverses** between consecutive plateaus: start when x leaves the previous plateau by more
   than ``traverse_threshold`` (1 mm), end when it comes within that of the next (crossing
   times interpolated between lines).
4. Per traverse: ``q = dx_m / (±distance)`` with ``dx_m`` the plateau-to-plateau measured
   distance, and ``v_m`` the measured speed over the timed span (distance covered between the
   two crossings / their time difference). Both choices avoid the ≈ 2 % bias of mixing the
   full distance with the trimmed duration.
5. Least squares ``q = b + a·term(v_m)`` with ``term`` = |v_m| (``abs``, symmetric, default),
   v_m (``signed``, the reference) or 0 (``none``, b only); per-direction fits are reported.
   ``a_factor`` (the reference's undocumented 0.88) applies only when given explicitly.
6. Check: re-integrate each traverse with ``v/(b + a·term(v))`` and compare with ±distance.

SI throughout (m, s, m/s, a in 1/(m/s)). Traverses with a non-constant speed bias the a-term
(the fit sees the mean speed); b is unaffected to first order.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from slip_velocity_sensor.core import calibration as cal_mod
from slip_velocity_sensor.core.calibration import AxisCalibration, SpeedTerm

FIT_MODELS = ('abs', 'signed', 'none')
_LAW_TERM = {'abs': SpeedTerm.ABS, 'signed': SpeedTerm.SIGNED_COMPAT, 'none': SpeedTerm.ZERO}


class FitError(ValueError):
    """The recording cannot be fitted (too few plateaus or traverses); says why."""


@dataclass(frozen=True)
class FitParams:
    """Offline fit settings (SI)."""

    distance: float = field(default=0.1, metadata={
        'unit': 'm', 'range': (0.001, 10.0), 'description': 'distance between the hard stops'})
    plateau_min_duration: float = field(default=2.0, metadata={
        'unit': 's', 'range': (0.1, 60.0), 'description': 'shortest rest counted as a plateau'})
    plateau_tolerance: float = field(default=1e-6, metadata={
        'unit': 'm', 'range': (0.0, 0.01),
        'description': 'largest position change within a plateau window'})
    plateau_separation: float = field(default=0.025, metadata={
        'unit': 'm', 'range': (0.0, 10.0),
        'description': 'plateaus closer than this are the same rest position'})
    traverse_threshold: float = field(default=0.001, metadata={
        'unit': 'm', 'range': (0.0, 1.0),
        'description': 'distance from a plateau that starts / ends a traverse'})
    distance_tolerance: float = field(default=0.5, metadata={
        'unit': '-', 'range': (0.0, 1.0),
        'description': 'traverses with |q - 1| above this are rejected as operator errors'})
    model: str = field(default='abs', metadata={
        'choices': FIT_MODELS, 'description': 'speed term of the fit: abs, signed or none'})
    a_factor: float = field(default=1.0, metadata={
        'unit': '-', 'range': (0.0, 10.0),
        'description': 'hand factor applied to the fitted a (reference: 0.88); 1 = raw fit'})
    min_traverses: int = field(default=4, metadata={
        'unit': '-', 'range': (2, 1000), 'description': 'fewest accepted traverses to fit'})


@dataclass(frozen=True)
class Plateau:
    """A rest between traverses.

    Attributes:
        start: Index of the first line of the rest.
        end: Index of the last line.
        t_start: [s].
        t_end: [s].
        arrival: Position when the rest began [m] (first merged run).
        departure: Position when it ended [m] (last merged run).
    """

    start: int
    end: int
    t_start: float
    t_end: float
    arrival: float
    departure: float


@dataclass(frozen=True)
class Traverse:
    """One stop-to-stop move.

    Attributes:
        t_start: Crossing of the start threshold [s].
        t_end: Crossing of the end threshold [s].
        dx_m: Measured plateau-to-plateau distance [m] (signed).
        v_m: Measured mean speed over the timed span [m/s] (signed).
        v_t: True mean speed ``±distance / duration`` [m/s].
        q: Measured / true distance ratio [-].
        direction: +1 or -1.
        accepted: False when rejected (reason given).
        reason: Why it was rejected, else ''.
        first_plateau: Index of the plateau the traverse starts from.
    """

    t_start: float
    t_end: float
    dx_m: float
    v_m: float
    v_t: float
    q: float
    direction: int
    accepted: bool
    reason: str
    first_plateau: int

    @property
    def duration(self) -> float:
        """Timed span [s]."""
        return self.t_end - self.t_start


@dataclass(frozen=True)
class LineFit:
    """Least-squares line ``q = b + a·term(v_m)``.

    Attributes:
        a: Slope [1/(m/s)] (0 for model ``none``).
        b: Intercept [-].
        residual_rms: RMS of ``q − q̂`` [-].
        n: Traverses used.
    """

    a: float
    b: float
    residual_rms: float
    n: int


@dataclass(frozen=True)
class AxisFit:
    """Fit of one chip axis.

    Attributes:
        calibration: Result for the calibration file (a already multiplied by ``a_factor``).
        model: Fit model (abs, signed, none).
        raw: The raw fit (before ``a_factor``).
        positive: Fit of the +1 traverses only (|v_m| regressor), None if too few.
        negative: Fit of the -1 traverses only, None if too few.
        plateaus: Detected rests.
        traverses: All traverses (accepted and rejected).
        residuals: ``q − q̂`` per accepted traverse [-].
        check_errors: Re-integrated distance minus ±distance per accepted traverse [m], with
            the fitted law.
        check_errors_b_only: The same with a = 0 (what ``speed_term: zero`` gives) [m].
    """

    calibration: AxisCalibration
    model: str
    raw: LineFit
    positive: LineFit | None
    negative: LineFit | None
    plateaus: tuple[Plateau, ...]
    traverses: tuple[Traverse, ...]
    residuals: NDArray[np.float64]
    check_errors: NDArray[np.float64]
    check_errors_b_only: NDArray[np.float64]

    @property
    def accepted(self) -> tuple[Traverse, ...]:
        """Traverses used in the fit."""
        return tuple(tr for tr in self.traverses if tr.accepted)

    def summary(self) -> dict[str, float | int | str]:
        """Plain numbers for the calibration file's ``fit`` section and reports."""
        def rms(x: NDArray[np.float64]) -> float:
            return float(np.sqrt(np.mean(np.square(x)))) if len(x) else math.nan
        out: dict[str, float | int | str] = {
            'model': self.model, 'a_raw': self.raw.a, 'b_raw': self.raw.b,
            'traverses': self.raw.n, 'q_residual_rms': self.raw.residual_rms,
            'check_rms_m': rms(self.check_errors),
            'check_max_m': float(np.max(np.abs(self.check_errors))) if len(self.check_errors)
            else math.nan,
            'check_b_only_rms_m': rms(self.check_errors_b_only)}
        for name, fit in (('positive', self.positive), ('negative', self.negative)):
            if fit is not None:
                out[f'{name}_a'] = fit.a
                out[f'{name}_b'] = fit.b
        return out


# --------------------------------------------------------------------------- steps


def integrate_position(t: ArrayLike, v: ArrayLike) -> NDArray[np.float64]:
    """Position [m] from line stamps t [s] and speeds v [m/s] (x_0 = 0)."""
    tt = np.asarray(t, dtype=np.float64)
    vv = np.asarray(v, dtype=np.float64)
    dt = np.diff(tt, prepend=tt[0])
    return np.cumsum(vv * dt)


def detect_plateaus(t: NDArray[np.float64], x: NDArray[np.float64],
                    params: FitParams) -> list[Plateau]:
    """Rest plateaus of a position trace (see the module docstring)."""
    n = len(x)
    if n < 3:
        return []
    step = float(np.median(np.diff(t)))
    if not step > 0.0:
        raise FitError('stamps must increase')
    window = max(2, int(math.ceil(params.plateau_min_duration / step)))
    if window >= n:
        return []
    view = np.lib.stride_tricks.sliding_window_view(x, window + 1)
    still = (view.max(axis=1) - view.min(axis=1)) < params.plateau_tolerance
    mark = np.zeros(n + 1, dtype=np.int64)
    starts = np.flatnonzero(still)
    np.add.at(mark, starts, 1)
    np.add.at(mark, starts + window + 1, -1)
    covered = np.cumsum(mark[:n]) > 0
    runs: list[tuple[int, int]] = []
    edges = np.flatnonzero(np.diff(np.concatenate(([0], covered.astype(np.int8), [0]))))
    for a, b in zip(edges[0::2], edges[1::2]):
        if t[b - 1] - t[a] >= params.plateau_min_duration * 0.999:
            runs.append((int(a), int(b - 1)))
    plateaus: list[Plateau] = []
    for a, b in runs:
        level = float(np.mean(x[a:b + 1]))
        if plateaus and abs(level - plateaus[-1].departure) <= params.plateau_separation:
            prev = plateaus[-1]
            plateaus[-1] = Plateau(prev.start, b, prev.t_start, float(t[b]), prev.arrival, level)
        else:
            plateaus.append(Plateau(a, b, float(t[a]), float(t[b]), level, level))
    return plateaus


def _crossing(t: NDArray[np.float64], d: NDArray[np.float64], i: int) -> float:
    """Time where d (distance beyond a threshold, sign change between i-1 and i) crosses 0."""
    if i <= 0 or d[i] == d[i - 1]:
        return float(t[i])
    frac = d[i - 1] / (d[i - 1] - d[i])
    return float(t[i - 1] + frac * (t[i] - t[i - 1]))


def detect_traverses(t: NDArray[np.float64], x: NDArray[np.float64],
                     plateaus: list[Plateau], params: FitParams) -> list[Traverse]:
    """Traverses between consecutive plateaus with their ratio q and measured speed v_m."""
    out: list[Traverse] = []
    thr = params.traverse_threshold
    for k in range(len(plateaus) - 1):
        p0, p1 = plateaus[k], plateaus[k + 1]
        seg = slice(p0.end, p1.start + 1)
        ts, xs = t[seg], x[seg]
        away = np.abs(xs - p0.departure) - thr        # > 0 once left the start plateau
        near = thr - np.abs(xs - p1.arrival)          # > 0 once within reach of the next
        left = np.flatnonzero(away > 0.0)
        if len(left) == 0:
            continue
        i0 = int(left[0])
        arrived = np.flatnonzero(near[i0:] > 0.0)
        if len(arrived) == 0:
            continue
        i1 = i0 + int(arrived[0])
        t0 = _crossing(ts, away, i0)
        t1 = _crossing(ts, near, i1)
        dx = p1.arrival - p0.departure
        direction = 1 if dx > 0.0 else -1
        duration = t1 - t0
        span = (p1.arrival - direction * thr) - (p0.departure + direction * thr)
        v_m = span / duration if duration > 0.0 else math.nan
        v_t = direction * params.distance / duration if duration > 0.0 else math.nan
        q = abs(dx) / params.distance
        reason = ''
        if not duration > 0.0:
            reason = 'zero duration'
        elif abs(q - 1.0) > params.distance_tolerance:
            reason = f'measured distance {abs(dx) * 1e3:.1f} mm is not stop-to-stop'
        elif out and out[-1].accepted and out[-1].direction == direction:
            reason = 'same direction as the previous traverse'
        out.append(Traverse(t0, t1, dx, v_m, v_t, q, direction, not reason, reason, k))
    return out


def _regressor(v_m: NDArray[np.float64], model: str) -> NDArray[np.float64]:
    if model == 'abs':
        return np.abs(v_m)
    if model == 'signed':
        return v_m
    return np.zeros_like(v_m)


def fit_line(v_m: ArrayLike, q: ArrayLike, model: str = 'abs') -> LineFit:
    """Least squares ``q = b + a·term(v_m)``.

    Args:
        v_m: Measured mean speeds [m/s].
        q: Measured / true distance ratios [-].
        model: ``abs``, ``signed`` or ``none`` (b = mean q, a = 0).

    Raises:
        FitError: Fewer than 2 points (1 for ``none``) or a degenerate regressor.
    """
    if model not in FIT_MODELS:
        raise FitError(f'unknown fit model {model!r}; use one of {FIT_MODELS}')
    vv = np.asarray(v_m, dtype=np.float64)
    qq = np.asarray(q, dtype=np.float64)
    if model == 'none':
        if len(qq) < 1:
            raise FitError('no traverse to fit')
        b = float(np.mean(qq))
        return LineFit(0.0, b, float(np.sqrt(np.mean((qq - b) ** 2))), len(qq))
    if len(qq) < 2:
        raise FitError(f'need at least 2 traverses for a line fit, got {len(qq)}')
    reg = _regressor(vv, model)
    if np.ptp(reg) <= 0.0:
        raise FitError('all traverses have the same speed: the a-term is not identifiable')
    design = np.column_stack((np.ones_like(reg), reg))
    (b, a), *_ = np.linalg.lstsq(design, qq, rcond=None)
    res = qq - (b + a * reg)
    return LineFit(float(a), float(b), float(np.sqrt(np.mean(res ** 2))), len(qq))


def reintegration_errors(t: NDArray[np.float64], v: NDArray[np.float64],
                         traverses: tuple[Traverse, ...], plateaus: list[Plateau],
                         cal: AxisCalibration, speed_term: SpeedTerm | str,
                         distance: float) -> NDArray[np.float64]:
    """Corrected stop-to-stop distance minus ±distance for each traverse [m]."""
    corrected = cal_mod.corrected_speed(np.asarray(v, dtype=np.float64), cal, speed_term)
    x = integrate_position(t, corrected)
    errors = []
    for tr in traverses:
        p0, p1 = plateaus[tr.first_plateau], plateaus[tr.first_plateau + 1]
        before = np.mean(x[max(p0.end - 2, 0):p0.end + 1])
        moved = float(np.mean(x[p1.start:p1.start + 3]) - before)
        errors.append(moved - tr.direction * distance)
    return np.asarray(errors, dtype=np.float64)


def fit_axis(t: ArrayLike, v: ArrayLike, params: FitParams | None = None) -> AxisFit:
    """Fit one chip axis from its procedure recording.

    Args:
        t: Line stamps [s], increasing.
        v: Raw (uncalibrated) chip speed along the axis [m/s].
        params: Fit settings.

    Raises:
        FitError: When the recording has too few usable traverses (the message says what was
            found).
    """
    p = params if params is not None else FitParams()
    tt = np.asarray(t, dtype=np.float64)
    vv = np.asarray(v, dtype=np.float64)
    if tt.shape != vv.shape or tt.ndim != 1:
        raise FitError(f't and v must be 1-D of equal length, got {tt.shape} and {vv.shape}')
    if not (np.all(np.isfinite(tt)) and np.all(np.isfinite(vv))):
        raise FitError('recording contains non-finite values')
    x = integrate_position(tt, vv)
    plateaus = detect_plateaus(tt, x, p)
    traverses = tuple(detect_traverses(tt, x, plateaus, p))
    accepted = tuple(tr for tr in traverses if tr.accepted)
    if len(accepted) < p.min_traverses:
        rejected = '; '.join(f'{tr.reason}' for tr in traverses if not tr.accepted)
        raise FitError(f'{len(plateaus)} plateau(s), {len(accepted)} usable traverse(s) '
                       f'(need {p.min_traverses}){": " + rejected if rejected else ""}')
    v_m = np.array([tr.v_m for tr in accepted])
    q = np.array([tr.q for tr in accepted])
    raw = fit_line(v_m, q, p.model)
    by_dir = {}
    for direction in (1, -1):
        sel = np.array([tr.direction == direction for tr in accepted])
        try:
            by_dir[direction] = fit_line(v_m[sel], q[sel], 'abs') if sel.sum() >= 2 else None
        except FitError:
            by_dir[direction] = None
    cal = AxisCalibration(a=raw.a * p.a_factor, b=raw.b)
    residuals = q - (raw.b + raw.a * _regressor(v_m, p.model))
    check = reintegration_errors(tt, vv, accepted, plateaus, cal, _LAW_TERM[p.model], p.distance)
    check_b = reintegration_errors(tt, vv, accepted, plateaus, AxisCalibration(0.0, cal.b),
                                   SpeedTerm.ZERO, p.distance)
    return AxisFit(calibration=cal, model=p.model, raw=raw, positive=by_dir[1],
                   negative=by_dir[-1], plateaus=tuple(plateaus), traverses=traverses,
                   residuals=residuals, check_errors=check, check_errors_b_only=check_b)
