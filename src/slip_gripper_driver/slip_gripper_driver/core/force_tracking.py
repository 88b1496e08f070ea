# SPDX-License-Identifier: Apache-2.0
"""Analysis of a force-tracking recording (control_and_estimation §6.1, §6.2).

The profile itself (§5.4: 5 N, the square wave, the 1–64 Hz sines, 5 N, then 0 N) is
`slip_cell_common.core.force_profile.ForceTrackingProfile`, the one definition that this tool
and the experiment runner's ``force_tracking_test`` mode both play.

Step metrics (§6.1) on the 5 → 25 N step (the 8th level), signal resampled to 500 Hz with
time zero at the commanded step: rise time 10 → 90 % (7 → 23 N), ``t50`` (15 N), overshoot
``peak − 25 N``, and 2 % settling: the first time after which the signal stays within
±0.4 N of 25 N for 200 consecutive samples.

Frequency response (§6.2), per sine with 0.1 s trimmed at each end, both signals resampled to
the same 500 Hz grid and their means removed: magnitude ``20·log10(RMS(out)/RMS(in))``;
phase ``−360°·f·lag`` from the lag of the cross-correlation peak (searched over one period,
from a quarter period of lead to three quarters of lag); the −3 dB bandwidth is interpolated
in log f between the tested frequencies.
"""
from __future__ import annotations

import argparse
import csv
import math
import sys
from dataclasses import dataclass
from typing import NamedTuple
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from slip_cell_common.core.force_profile import FloatArray, ForceTrackingProfile


class StepMetrics(NamedTuple):
    """Step-response metrics (§6.1); times from the commanded step [s], forces [N].

    NaN when the signal never reaches the level (or never settles).
    """

    rise_time: float
    t50: float
    overshoot: float
    settling_time: float
    peak: float


class FrequencyPoint(NamedTuple):
    """Response at one frequency (§6.2)."""

    frequency_hz: float
    magnitude_db: float
    phase_deg: float
    lag_s: float


@dataclass(frozen=True)
class ForceTrackingReport:
    """Step metrics, frequency response and bandwidth of one recording."""

    step: StepMetrics
    response: tuple[FrequencyPoint, ...]
    bandwidth_hz: float


def _resample(t: ArrayLike, y: ArrayLike, grid: FloatArray) -> FloatArray:
    tt = np.asarray(t, dtype=np.float64)
    yy = np.asarray(y, dtype=np.float64)
    if tt.shape != yy.shape or tt.ndim != 1 or tt.size < 2:
        raise ValueError('t and y must be 1-D arrays of equal length >= 2')
    order = np.argsort(tt, kind='stable')
    tt, yy = tt[order], yy[order]
    ok = np.isfinite(tt) & np.isfinite(yy)
    if ok.sum() < 2:
        raise ValueError('fewer than two finite samples')
    return np.interp(grid, tt[ok], yy[ok])


def _first_crossing(y: FloatArray, level: float, dt: float) -> float:
    """Time of the first upward crossing of ``level`` (linear interpolation), NaN if none."""
    above = np.nonzero(y >= level)[0]
    if above.size == 0:
        return math.nan
    k = int(above[0])
    if k == 0:
        return 0.0
    y0, y1 = float(y[k - 1]), float(y[k])
    return (k - 1 + (level - y0) / (y1 - y0)) * dt


def step_metrics(t: ArrayLike, measured: ArrayLike, *, t_step: float, f_from: float,
                 f_to: float, window_s: float = 1.0, fs: float = 500.0, band: float = 0.4,
                 hold_samples: int = 200) -> StepMetrics:
    """Step metrics of a recorded response.

    Args:
        t: Sample stamps [s].
        measured: Measured force [N].
        t_step: Time of the commanded step [s].
        f_from: Force before the step [N].
        f_to: Commanded force after the step [N].
        window_s: Analysed time after the step [s] (the level duration).
        fs: Resampling rate [Hz].
        band: Settling band [N] (±).
        hold_samples: Consecutive samples inside the band.

    Returns:
        The metrics (rising or falling steps; overshoot beyond ``f_to`` is positive).
    """
    dt = 1.0 / fs
    grid = t_step + np.arange(int(round(window_s * fs)), dtype=np.float64) * dt
    y = _resample(t, measured, grid)
    sign = 1.0 if f_to >= f_from else -1.0
    z = sign * (y - f_from)  # rising from 0 to |Δ|
    span = abs(f_to - f_from)
    t10 = _first_crossing(z, 0.1 * span, dt)
    t50 = _first_crossing(z, 0.5 * span, dt)
    t90 = _first_crossing(z, 0.9 * span, dt)
    peak_z = float(np.max(z))
    inside = np.abs(y - f_to) <= band
    settling = math.nan
    run = 0
    for k, ok in enumerate(inside):
        run = run + 1 if ok else 0
        if run >= hold_samples:
            settling = (k - hold_samples + 1) * dt
            break
    return StepMetrics(rise_time=t90 - t10, t50=t50, overshoot=peak_z - span,
                       settling_time=settling, peak=f_from + sign * peak_z)


def frequency_point(t: ArrayLike, target: ArrayLike, measured: ArrayLike, *, frequency: float,
                    t_start: float, duration: float, trim_s: float = 0.1, fs: float = 500.0,
                    subsample: bool = False) -> FrequencyPoint:
    """Magnitude and phase of the measured force against the target at one frequency.

    Args:
        t: Stamps of both signals [s] (resample them to a common time base first if they
            were recorded separately; `analyze` accepts separate stamps).
        target: Commanded force [N].
        measured: Measured force [N].
        frequency: Sine frequency [Hz].
        t_start: Start of the sine segment [s].
        duration: Segment length [s].
        trim_s: Trimmed at each end [s].
        fs: Common sampling rate [Hz].
        subsample: Refine the correlation peak by a parabola (finer than 1/fs).
    """
    return _frequency_point(t, target, t, measured, frequency, t_start, duration, trim_s, fs,
                            subsample)


def _frequency_point(t_in: ArrayLike, target: ArrayLike, t_out: ArrayLike, measured: ArrayLike,
                     frequency: float, t_start: float, duration: float, trim_s: float,
                     fs: float, subsample: bool) -> FrequencyPoint:
    n = int(math.floor((duration - 2.0 * trim_s) * fs))
    if n < 4:
        raise ValueError('segment too short after trimming')
    grid = t_start + trim_s + np.arange(n, dtype=np.float64) / fs
    x = _resample(t_in, target, grid)
    y = _resample(t_out, measured, grid)
    x -= x.mean()
    y -= y.mean()
    rms_x = math.sqrt(float(np.mean(x * x)))
    rms_y = math.sqrt(float(np.mean(y * y)))
    if rms_x == 0.0:
        raise ValueError('target has no variation in this segment')
    magnitude = 20.0 * math.log10(rms_y / rms_x) if rms_y > 0.0 else -math.inf
    period = max(2, int(round(fs / frequency)))
    lags = np.arange(-(period // 4), period - period // 4)
    corr = np.empty(lags.size)
    for i, k in enumerate(lags):  # c[k] = mean(y[n + k] · x[n])
        if k >= 0:
            corr[i] = float(np.dot(y[k:], x[:n - k])) / (n - k)
        else:
            corr[i] = float(np.dot(y[:n + k], x[-k:])) / (n + k)
    i = int(np.argmax(corr))
    lag = float(lags[i])
    if subsample and 0 < i < lags.size - 1:
        c0, c1, c2 = corr[i - 1], corr[i], corr[i + 1]
        denom = c0 - 2.0 * c1 + c2
        if denom < 0.0:
            lag += 0.5 * (c0 - c2) / denom
    lag_s = lag / fs
    return FrequencyPoint(frequency, magnitude, -360.0 * frequency * lag_s, lag_s)


def bandwidth_3db(frequencies: Sequence[float], magnitudes_db: Sequence[float],
                  level_db: float = -3.0) -> float:
    """First crossing of ``level_db``, interpolated linearly in log f [Hz].

    Returns:
        The bandwidth, or NaN when the tested range does not bracket the crossing (already
        below at the lowest frequency, or never below).
    """
    pairs = sorted(zip(frequencies, magnitudes_db))
    if not pairs or pairs[0][1] < level_db:
        return math.nan
    for (f0, m0), (f1, m1) in zip(pairs, pairs[1:]):
        if m1 < level_db <= m0:
            frac = (level_db - m0) / (m1 - m0)
            return float(10.0 ** (math.log10(f0) + frac * (math.log10(f1) - math.log10(f0))))
    return math.nan


def align_profile(t: ArrayLike, target: ArrayLike,
                  profile: ForceTrackingProfile = ForceTrackingProfile()) -> float:
    """Profile start on the recording's clock [s], from the first rise of the target.

    The first level above the initial force (10 N at 3 s) is located at the first sample
    exceeding the midpoint between the two.

    Raises:
        ValueError: The target never rises.
    """
    tt = np.asarray(t, dtype=np.float64)
    yy = np.asarray(target, dtype=np.float64)
    levels = [s for s in profile.segments() if s.kind == 'level']
    first_up = next(s for s in levels if s.value > profile.initial_force)
    threshold = 0.5 * (profile.initial_force + first_up.value)
    idx = np.nonzero(yy > threshold)[0]
    if idx.size == 0:
        raise ValueError('the target never rises above the initial force')
    return float(tt[idx[0]]) - first_up.t_start


def analyze(t_target: ArrayLike, target: ArrayLike, t_measured: ArrayLike,
            measured: ArrayLike, *, profile: ForceTrackingProfile = ForceTrackingProfile(),
            t0: float | None = None, subsample: bool = False) -> ForceTrackingReport:
    """Step metrics, frequency response and bandwidth of one force-tracking recording.

    Args:
        t_target: Stamps of the commanded force [s].
        target: Commanded force [N].
        t_measured: Stamps of the measured force [s].
        measured: Measured force [N] (finger-1 ``−Fz``, bias removed, in the reference).
        profile: The profile that was played.
        t0: Profile start on the recording clock [s]; found by `align_profile` when None.
        subsample: See `frequency_point`.
    """
    if t0 is None:
        t0 = align_profile(t_target, target, profile)
    t_step, f_from, f_to, t_end = profile.step_segment()
    step = step_metrics(t_measured, measured, t_step=t0 + t_step, f_from=f_from, f_to=f_to,
                        window_s=t_end - t_step, fs=profile.rate_hz)
    points = tuple(
        _frequency_point(t_target, target, t_measured, measured, seg.frequency,
                         t0 + seg.t_start, seg.t_end - seg.t_start, 0.1, profile.rate_hz,
                         subsample)
        for seg in profile.sine_segments())
    bandwidth = bandwidth_3db([p.frequency_hz for p in points], [p.magnitude_db for p in points])
    return ForceTrackingReport(step, points, bandwidth)


def format_report(report: ForceTrackingReport) -> str:
    """Human-readable table of a report."""
    s = report.step
    lines = ['step 5 -> 25 N:',
             f'  rise time 10-90 %  {s.rise_time * 1e3:8.1f} ms',
             f'  t50                {s.t50 * 1e3:8.1f} ms',
             f'  overshoot          {s.overshoot:8.2f} N (peak {s.peak:.2f} N)',
             f'  settling (±0.4 N)  {s.settling_time * 1e3:8.1f} ms',
             'frequency response:',
             '  f [Hz]   |G| [dB]   phase [deg]']
    lines += [f'  {p.frequency_hz:6.1f}   {p.magnitude_db:8.2f}   {p.phase_deg:10.1f}'
              for p in report.response]
    bw = report.bandwidth_hz
    lines.append(f'-3 dB bandwidth: {bw:.2f} Hz' if math.isfinite(bw)
                 else '-3 dB bandwidth: not bracketed by the tested frequencies')
    return '\n'.join(lines)


def _load_csv(path: str) -> tuple[FloatArray, FloatArray, FloatArray]:
    with open(path, newline='') as handle:
        rows = list(csv.DictReader(handle))
    if not rows or not {'t', 'target', 'measured'} <= set(rows[0]):
        raise ValueError(f'{path}: need a header with columns t, target, measured')
    arr = np.array([[float(r['t']), float(r['target']), float(r['measured'])] for r in rows])
    return arr[:, 0], arr[:, 1], arr[:, 2]


def main(argv: Sequence[str] | None = None) -> int:
    """Console entry point: print the profile or analyse a CSV recording."""
    parser = argparse.ArgumentParser(description='Force-tracking profile and analysis '
                                                 '(control_and_estimation §5.4, §6.1, §6.2).')
    parser.add_argument('csv', nargs='?', help='recording with columns t, target, measured')
    parser.add_argument('--t0', type=float, default=None,
                        help='profile start in the recording [s]; detected when omitted')
    parser.add_argument('--profile', action='store_true', help='print the profile segments')
    args = parser.parse_args(argv)
    profile = ForceTrackingProfile()
    if args.profile or not args.csv:
        for seg in profile.segments():
            what = f'sine {seg.frequency:g} Hz' if seg.kind == 'sine' else f'{seg.value:g} N'
            print(f'{seg.t_start:7.2f} - {seg.t_end:7.2f} s  {seg.kind:5s} {what}')
        if not args.csv:
            return 0
    t, target, measured = _load_csv(args.csv)
    print(format_report(analyze(t, target, t, measured, profile=profile, t0=args.t0)))
    return 0


if __name__ == '__main__':
    sys.exit(main())
