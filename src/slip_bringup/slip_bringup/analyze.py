"""``slip_analyze``: metrics (JSON) and plots (PNG) of a recorded experiment.

The bag is read once; progress lines go to stderr. Metrics follow control_and_estimation §6,
on header stamps:

* ``force``: grasp-force tracking (target F_d vs measured F_m): RMS error, statistics of the
  measured force, and its peak with what commanded it (source, controller mode). When the
  command holds the force-tracking profile (§5.4): the 5 → 25 N step metrics (a NaN comes
  with its reason in ``step_notes``), and the frequency response and −3 dB bandwidth from
  the sine segments found in the command only. A bag without them says "no excitation in
  this bag" instead of a response.
* ``estimation``: every published estimate; the final one per finger (the last valid value
  of μ_c and r with its 1-sigma uncertainty, never a mean over partial sets); the spread over
  completed explorations (§6.4); the simulator's truth and the final error when recorded.
* ``phases`` and ``ends``: the slip controller's modes over time, and every LINEAR,
  ROTATIONAL or HINGE end; ``aborts`` are the ends that were not "done", with their message.
* ``slip``: per LINEAR / ROTATIONAL segment of ``slip_control/tracking``: target, final
  measured position, tracking errors (§6.5, §6.6), the sensor-based final slip (reference
  magnitude and signed definitions), the outcome, and the true object motion when recorded.
* ``hold``: per HOLD phase: peak and final slip distance and angle from the velocity
  sensors, the measured and commanded force (min, max, span, mean, SD), and the true object
  motion when recorded (§6.7).

Plots: force.png (phases shaded, aborts marked, the peak explained), force_step.png and
force_bode.png (force-tracking bags), slip.png, hold.png, twist.png (mm/s and rad/s on
separate axes) and contact.png (final estimate with ±1σ error bars, and the truth).

Example::

    slip_analyze bags/linear_slip --out /tmp/linear_slip_report
"""
from __future__ import annotations

import json
import math
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, is_dataclass
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from slip_bringup.core import metrics as core_metrics
from slip_bringup.core.excitation import fit_sine, is_excited
from slip_bringup.core.phases import (
    MODE_NAMES,
    ModeEnd,
    Phase,
    StateChange,
    mode_ends,
    phase_at,
    phases,
)
from slip_cell_common.bag_io import BagError, ensure_type, iter_raw, slip_typestore, stamp_s
from slip_cell_common.core import names
from slip_cell_common.core.cli_args import Parser, plain_doc
from slip_cell_common.core.force_profile import ForceTrackingProfile
from slip_cell_common.core.frames import FrameParams

TOPICS = {key: names.absolute(name) for key, name in {
    'cmd': names.GRASP_FORCE_CMD, 'motor': names.MOTOR_COMMAND,
    'ft1': names.ft_wrench(1), 'ft2': names.ft_wrench(2),
    'tw1': names.slip_twist(1), 'tw2': names.slip_twist(2),
    'tracking': names.SLIP_TRACKING, 'state': names.SLIP_CONTROLLER_STATE,
    'props': names.CONTACT_PROPERTIES, 'truth_props': names.SIM_TRUE_CONTACT,
    'sim': names.SIM_STATE,
}.items()}
#: Topics every analysis needs (grasp-force command, force-loop target and measurement); the
#: other metric groups are computed when their topics are in the bag.
REQUIRED = ('cmd', 'motor')
#: ``GraspForceCommand.source`` constants → who commanded.
SOURCE_NAMES = {0: 'a manual command', 1: 'the slip controller', 2: 'the experiment runner',
                3: 'the force-tracking test', 4: 'the simulation'}
NO_EXCITATION = 'no excitation in this bag'
#: HOLD phases shorter than this [s] get no hold metrics (a mode flicker, not a hold).
MIN_HOLD_S = 0.2

Progress = Callable[[str], None]


@dataclass
class Series:
    """Time series of one or more fields: ``t`` [s] and columns."""

    t: np.ndarray
    cols: dict[str, np.ndarray]

    def __len__(self) -> int:
        return int(self.t.size)

    def window(self, t0: float, t1: float) -> Series:
        """Samples with ``t0 <= t <= t1``."""
        m = (self.t >= t0) & (self.t <= t1)
        return Series(self.t[m], {k: v[m] for k, v in self.cols.items()})


_FIELDS: dict[str, dict[str, Callable[[Any], float]]] = {
    'cmd': {'force': lambda m: m.force, 'source': lambda m: m.source},
    'motor': {'target': lambda m: m.force_target, 'measured': lambda m: m.measured_force,
              'u': lambda m: m.force_cmd},
    'ft': {'fx': lambda m: m.wrench.force.x, 'fy': lambda m: m.wrench.force.y,
           'fz': lambda m: m.wrench.force.z, 'tz': lambda m: m.wrench.torque.z},
    'tw': {'vx': lambda m: m.twist.linear.x, 'vy': lambda m: m.twist.linear.y,
           'wz': lambda m: m.twist.angular.z},
    'tracking': {'mode': lambda m: m.mode, 'ref_pos': lambda m: m.ref_pos,
                 'ref_vel': lambda m: m.ref_vel, 'meas_pos': lambda m: m.meas_pos,
                 'meas_vel': lambda m: m.meas_vel, 'force': lambda m: m.force_cmd,
                 'done': lambda m: float(m.done)},
    'sim': {'x': lambda m: m.x, 'y': lambda m: m.y, 'theta': lambda m: m.theta,
            'fn1': lambda m: m.normal_force_1, 'fn2': lambda m: m.normal_force_2,
            'arm_angle': lambda m: m.arm_angle},
}


def _series(msgs: list[Any], fields: dict[str, Callable[[Any], float]]) -> Series:
    t = np.array([stamp_s(m) for m in msgs], dtype=np.float64)
    cols = {name: np.array([get(m) for m in msgs], dtype=np.float64)
            for name, get in fields.items()}
    order = np.argsort(t, kind='stable')
    return Series(t[order], {k: v[order] for k, v in cols.items()})


def _read(bag: Path | str, say: Progress, heartbeat_s: float = 2.0
          ) -> tuple[dict[str, list[Any]], int, int]:
    """One pass over the bag: the messages of `TOPICS` (decoded), the total message count and
    the number of topics with messages (checks of `iter_raw`: CRCs, counts).

    A line goes to ``say`` every ``heartbeat_s`` of reading (none for a bag read faster, so
    a bag that fails at once gets its one error line only).
    """
    wanted = {topic: key for key, topic in TOPICS.items()}
    started = time.monotonic()
    next_beat = started + heartbeat_s
    store = slip_typestore()
    known: set[str] = set()
    out: dict[str, list[Any]] = {}
    total = 0
    seen: set[str] = set()
    for topic, msgtype, _, raw in iter_raw(bag):
        total += 1
        seen.add(topic)
        if not total % 1000 and time.monotonic() >= next_beat:
            say(f'reading {bag}: {total} messages so far')
            next_beat = time.monotonic() + heartbeat_s
        key = wanted.get(topic)
        if key is None:
            continue
        if msgtype not in known:
            ensure_type(store, msgtype)
            known.add(msgtype)
        try:
            msg = store.deserialize_cdr(raw, msgtype)
        except Exception as exc:  # rosbags raises several types here
            raise BagError(f'cannot decode a {msgtype} message on {topic}: {exc}') from exc
        out.setdefault(key, []).append(msg)
    return out, total, len(seen)


def load(bag: Path | str, progress: Progress | None = None) -> dict[str, Any]:
    """Read the topics the metrics need in one pass (optional ones may be absent).

    Returns:
        ``{'cmd', 'motor', 'ft1', 'ft2', 'tw1', 'tw2', 'tracking', 'sim'}`` as `Series`
        (those present), ``'state'`` (`StateChange` list), ``'props'`` and ``'truth'``
        (messages), ``'span'`` (first and last stamp [s]) and ``'bag'``.

    Raises:
        BagError: the bag is damaged, empty, or lacks a `REQUIRED` topic (all listed).
    """
    say = progress or (lambda text: None)
    started = time.monotonic()
    msgs, total, n_topics = _read(bag, say)
    if total == 0:
        raise BagError(f'bag {bag} holds no messages (topics declared, none recorded)')
    missing = [TOPICS[k] for k in REQUIRED if not msgs.get(k)]
    if missing:
        raise BagError(f'bag {bag} lacks the topic(s) slip_analyze needs: {", ".join(missing)} '
                       f'(it has {n_topics} topic(s) with {total} messages)')
    say(f'read {bag} in one pass: {total} messages, {sum(len(v) for v in msgs.values())} '
        f'of them used ({time.monotonic() - started:.1f} s)')
    data: dict[str, Any] = {'bag': str(bag)}
    for key in ('cmd', 'motor', 'tracking', 'sim'):
        if msgs.get(key):
            data[key] = _series(msgs[key], _FIELDS[key])
    for k in (1, 2):
        if msgs.get(f'ft{k}'):
            data[f'ft{k}'] = _series(msgs[f'ft{k}'], _FIELDS['ft'])
        if msgs.get(f'tw{k}'):
            data[f'tw{k}'] = _series(msgs[f'tw{k}'], _FIELDS['tw'])
    data['state'] = [StateChange(stamp_s(m), int(m.mode), str(m.reason))
                     for m in msgs.get('state', [])]
    data['props'] = msgs.get('props', [])
    data['truth'] = msgs.get('truth_props', [])
    stamps = [s.t for s in data.values() if isinstance(s, Series) and len(s)]
    data['span'] = (min(float(t[0]) for t in stamps), max(float(t[-1]) for t in stamps))
    return data


def _data(bag_or_data: Path | str | dict[str, Any]) -> dict[str, Any]:
    return bag_or_data if isinstance(bag_or_data, dict) else load(bag_or_data)


# --- timeline ------------------------------------------------------------------------------

def _segments(track: Series) -> list[tuple[int, float, float]]:
    """Contiguous runs of one mode in the tracking topic: (mode, t_start, t_end)."""
    out: list[tuple[int, float, float]] = []
    if not len(track):
        return out
    modes = track.cols['mode'].astype(int)
    start = 0
    for i in range(1, len(modes) + 1):
        gap = i < len(modes) and track.t[i] - track.t[i - 1] > 0.5
        if i == len(modes) or modes[i] != modes[start] or gap:
            out.append((int(modes[start]), float(track.t[start]), float(track.t[i - 1])))
            start = i
    return out


def timeline(data: dict[str, Any]) -> tuple[list[Phase], list[ModeEnd]]:
    """Controller phases and mode ends of a recording (``slip_control/state``; without it,
    the LINEAR/ROTATIONAL segments of ``slip_control/tracking``)."""
    t0, t1 = data['span']
    if data['state']:
        return phases(data['state'], t0, t1), mode_ends(data['state'])
    runs = [Phase(MODE_NAMES[m], a, b, '') for m, a, b in
            (_segments(data['tracking']) if 'tracking' in data else []) if b > a]
    return runs, []


# --- metrics -------------------------------------------------------------------------------

def _finger(f: Any) -> dict[str, Any]:
    return {k: getattr(f, k) for k in ('mu_c', 'mu_s', 'mu_v', 'r', 'u', 'mu_c_std', 'r_std',
                                       'n_linear', 'n_static', 'n_rotational', 'linear_valid',
                                       'rotational_valid')}


def final_estimate(estimated: list[Any]) -> dict[str, dict[str, Any]]:
    """Per finger: the last valid value of μ_c, μ_s, μ_v and r, with its uncertainty and
    the index of the estimate it came from (`metrics.last_valid`)."""
    out: dict[str, dict[str, Any]] = {}
    for key in ('finger_1', 'finger_2'):
        fs = [getattr(p, key) for p in estimated]
        nan = [math.nan] * len(fs)
        last = core_metrics.last_valid
        picks = {
            'mu_c': last([f.mu_c for f in fs], [f.mu_c_std for f in fs],
                         [f.linear_valid for f in fs]),
            'mu_s': last([f.mu_s for f in fs], nan, [f.static_valid for f in fs]),
            'mu_v': last([f.mu_v for f in fs], nan, [f.viscous_valid for f in fs]),
            'r': last([f.r for f in fs], [f.r_std for f in fs],
                      [f.rotational_valid for f in fs])}
        entry: dict[str, Any] = {}
        for name, pick in picks.items():
            entry[name] = pick.value
            if name in ('mu_c', 'r'):
                entry[f'{name}_std'] = pick.std
        entry['from_estimate'] = {name: pick.index for name, pick in picks.items()}
        out[key] = entry
    return out


def _estimation(data: dict[str, Any]) -> dict[str, Any]:
    estimated = [p for p in data['props'] if p.source == 1]
    out: dict[str, Any] = {'estimates': [{'t': stamp_s(p), 'finger_1': _finger(p.finger_1),
                                          'finger_2': _finger(p.finger_2), 'valid': p.valid,
                                          'online_updated': p.online_updated}
                                         for p in estimated]}
    if estimated:
        out['final'] = final_estimate(estimated)
        complete = [p for p in estimated if not p.online_updated and all(
            getattr(p, k).linear_valid and getattr(p, k).rotational_valid
            for k in ('finger_1', 'finger_2'))]
        out['spread'] = {'n_explorations': len(complete)}
        for key in ('finger_1', 'finger_2'):
            out['spread'][key] = {name: asdict(core_metrics.spread([getattr(getattr(p, key), name)
                                                         for p in complete]))
                                  for name in ('mu_c', 'mu_s', 'mu_v', 'r')}
    if data['truth']:
        truth = data['truth'][-1]
        out['truth'] = {'preset': truth.preset_name, 'finger_1': _finger(truth.finger_1),
                        'finger_2': _finger(truth.finger_2)}
        if estimated:
            out['error_final'] = {
                key: {name: out['final'][key][name] - getattr(getattr(truth, key), name)
                      for name in ('mu_c', 'r')}
                for key in ('finger_1', 'finger_2')}
    return out


def _middle(data: dict[str, Any], t0: float, t1: float, frames: FrameParams
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """Finger velocities in ``gripper_middle`` on finger 1's stamps within ``[t0, t1]``:
    ``(t, v1 (n, 2), v2 (n, 2), ω1_raw, ω2_raw)``, or None without both twists."""
    if 'tw1' not in data or 'tw2' not in data:
        return None
    w1, w2 = data['tw1'].window(t0, t1), data['tw2'].window(t0, t1)
    if len(w1) < 2 or len(w2) < 2:
        return None
    x1, y1, _ = core_metrics.to_middle(frames, 1, w1.cols['vx'], w1.cols['vy'], w1.cols['wz'])
    x2, y2, _ = core_metrics.to_middle(frames, 2, w2.cols['vx'], w2.cols['vy'], w2.cols['wz'])
    v2 = np.column_stack([np.interp(w1.t, w2.t, x2), np.interp(w1.t, w2.t, y2)])
    return (w1.t, np.column_stack([x1, y1]), v2, w1.cols['wz'],
            np.interp(w1.t, w2.t, w2.cols['wz']))


def _trapezoid_target(seg: Series, accel_fraction: float = 0.2) -> float:
    """Commanded distance or angle P of a tracked trapezoid (control_and_estimation §4.3).

    The controller may stop (x ≥ P) before the reference reaches P, so P is recovered from the
    reference itself: acceleration A from the first samples, cruise speed v_c, acceleration
    time t_c = v_c/A = a·T, and P = v_c·T·(1 − a) = v_c·t_c·(1 − a)/a (4·v_c·t_c for a = 0.2).
    """
    vel = np.abs(seg.cols['ref_vel'])
    pos = np.abs(seg.cols['ref_pos'])
    if vel.size < 4 or vel.max() <= 0.0:
        return float(pos.max(initial=0.0))
    v_c = float(vel.max())
    i_c = int(np.argmax(vel >= 0.999 * v_c))
    k = max(1, i_c // 2)
    if seg.t[k] <= seg.t[0] or vel[k] <= vel[0]:
        return float(pos.max())
    accel = float((vel[k] - vel[0]) / (seg.t[k] - seg.t[0]))
    t_c = v_c / accel
    return max(v_c * t_c * (1.0 - accel_fraction) / accel_fraction, float(pos.max()))


def _outcome(ends: list[ModeEnd], mode: str, t0: float, t1: float) -> dict[str, Any] | None:
    """The end of a ``mode`` run that started at ``t0`` and was tracked until ``t1``."""
    for end in ends:
        if end.mode == mode and t0 <= end.t <= t1 + 1.0:
            return {'success': end.success, 'message': end.message, 't': end.t}
    return None


def _slip(data: dict[str, Any], frames: FrameParams, ends: list[ModeEnd]
          ) -> list[dict[str, Any]]:
    out: list[dict[str, Any]] = []
    track: Series | None = data.get('tracking')
    if track is None:
        return out
    for mode, t0, t1 in _segments(track):
        if mode not in (1, 2):
            continue
        seg = track.window(t0, t1)
        err = core_metrics.tracking_errors(seg.cols['ref_pos'], seg.cols['meas_pos'],
                                           seg.cols['ref_vel'], seg.cols['meas_vel'])
        item: dict[str, Any] = {
            'mode': MODE_NAMES[mode], 't_start': t0, 't_end': t1,
            'target': _trapezoid_target(seg),
            'final_measured': float(seg.cols['meas_pos'][-1]), 'tracking': asdict(err),
            'force_range': [float(seg.cols['force'].min()), float(seg.cols['force'].max())],
            'outcome': _outcome(ends, MODE_NAMES[mode], t0, t1)}
        vel = _middle(data, t0, t1, frames)
        if vel is not None:
            t, v1, v2, wz1, wz2 = vel
            if mode == 2:
                item['sensor_slip'] = asdict(core_metrics.linear_slip_distance(t, v1, v2))
            else:
                item['sensor_angle'] = core_metrics.rotational_slip_angle(t, wz1, wz2)
        if 'sim' in data:
            sim = data['sim'].window(t0, t1 + 1.0)
            if len(sim) >= 2:
                dx, dy = sim.cols['x'][-1] - sim.cols['x'][0], sim.cols['y'][-1] - sim.cols['y'][0]
                item['true_motion'] = {'distance': float(math.hypot(dx, dy)),
                                       'angle': float(sim.cols['theta'][-1] - sim.cols['theta'][0])}
        out.append(item)
    return out


def hold_series(data: dict[str, Any], phase: Phase, frames: FrameParams
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Accumulated slip during one phase: ``(t, distance [m], angle [rad])`` from the mean
    middle-frame velocity ``v̄`` and rate ``(ω1 − ω2)/2`` (raw frames), zero at the start."""
    vel = _middle(data, phase.t_start, phase.t_end, frames)
    if vel is None:
        return None
    t, v1, v2, wz1, wz2 = vel
    disp = core_metrics.cumulative_integral(t, 0.5 * (v1 + v2))
    angle = core_metrics.cumulative_integral(t, 0.5 * (wz1 - wz2))
    return t, np.hypot(disp[:, 0], disp[:, 1]), angle


def _hold(data: dict[str, Any], runs: list[Phase], frames: FrameParams
          ) -> list[dict[str, Any]]:
    out = []
    for phase in runs:
        if phase.mode != 'hold' or phase.duration < MIN_HOLD_S:
            continue
        item: dict[str, Any] = {'t_start': phase.t_start, 't_end': phase.t_end,
                                'duration': phase.duration}
        vel = _middle(data, phase.t_start, phase.t_end, frames)
        if vel is not None:
            t, v1, v2, wz1, wz2 = vel
            motor = data['motor'].window(phase.t_start, phase.t_end)
            measured = np.interp(t, motor.t, motor.cols['measured']) if len(motor) >= 2 \
                else np.full(t.size, math.nan)
            hm = core_metrics.hold_metrics(t, 0.5 * (v1 + v2), 0.5 * (wz1 - wz2), measured)
            series = hold_series(data, phase, frames)
            assert series is not None
            item.update(peak_slip_distance=hm.peak_slip_distance,
                        peak_slip_angle=hm.peak_slip_angle,
                        final_slip_distance=hm.final_slip_distance,
                        final_slip_angle=float(series[2][-1]))
        else:
            item['slip_note'] = 'no velocity-sensor twists of both fingers in this phase'
        motor = data['motor'].window(phase.t_start, phase.t_end)
        stats = core_metrics.force_stats(motor.cols['measured'])
        item['force'] = {**asdict(stats), 'span': stats.span}
        if 'cmd' in data:
            window = data['cmd'].window(phase.t_start, phase.t_end)
            cmd = core_metrics.force_stats(window.cols['force'])
            item['command'] = {**asdict(cmd), 'span': cmd.span}
        if 'sim' in data:
            sim = data['sim'].window(phase.t_start, phase.t_end)
            if len(sim) >= 2:
                dist = np.hypot(sim.cols['x'] - sim.cols['x'][0], sim.cols['y'] - sim.cols['y'][0])
                ang = np.abs(sim.cols['theta'] - sim.cols['theta'][0])
                item['true_motion'] = {'peak_distance': float(dist.max()),
                                       'peak_angle': float(ang.max())}
        out.append(item)
    return out


def _step_notes(step: Any, window_s: float) -> dict[str, str]:
    """Why a step metric is NaN (§6.1), per field."""
    notes = {}
    if not math.isfinite(step.rise_time):
        notes['rise_time'] = f'never reached 90 % of the step within the {window_s:g} s level'
    if not math.isfinite(step.t50):
        notes['t50'] = f'never reached 50 % of the step within the {window_s:g} s level'
    if not math.isfinite(step.settling_time):
        notes['settling_time'] = (f'not settled within the {window_s:g} s level (±0.4 N of the '
                                  'target for 0.4 s)')
    return notes


def _level(t: np.ndarray, y: np.ndarray, t0: float, t1: float) -> float:
    m = (t >= t0) & (t < t1)
    return float(np.median(y[m])) if m.any() else math.nan


def force_tracking(data: dict[str, Any], profile: ForceTrackingProfile | None = None
                   ) -> dict[str, Any]:
    """Step metrics and frequency response of the force-tracking profile (§6.1, §6.2) — from
    the parts of the profile that the command actually holds.

    The profile is aligned on the command's first rise; the step counts only when the
    command sits at 5 N before and 25 N after it, and each sine only when the command holds
    it (`excitation.is_excited`). Anything else is reported as absent, with the reason.
    """
    out: dict[str, Any] = {'excitation': {'found': False, 'sines_hz': [], 'note': NO_EXCITATION
                                          + ': the force command holds none of the sines of '
                                          'the force-tracking profile (§5.4)'},
                           'frequency_response': None, 'bandwidth_hz': None,
                           'bandwidth_note': NO_EXCITATION, 'step': None,
                           'step_note': 'no 5 → 25 N step of the force-tracking profile in the '
                                        'force command'}
    if 'cmd' not in data or 'ft1' not in data or len(data['cmd']) < 100:
        return out
    profile = profile or ForceTrackingProfile()
    sources = data['cmd'].cols['source'].astype(int)
    # Commands of several sources interleave on one topic (the slip controller's HOLD keeps
    # publishing while a test plays the profile): look at each source's commands alone and
    # keep the one that holds the most of the profile.
    results = []
    for source in sorted(set(sources.tolist())):
        keep = sources == source
        if keep.sum() < 100:
            continue
        found = _profile_response(data['cmd'].t[keep], data['cmd'].cols['force'][keep],
                                  data['ft1'].t, -data['ft1'].cols['fz'], profile)
        if found is not None:
            found.update(command_source=SOURCE_NAMES.get(source, f'source {source}'),
                         command_source_id=source)
            results.append(((len(found['excitation']['sines_hz']), found['step'] is not None,
                             int(keep.sum())), found))
    if not results:
        return out
    best = {**out, **max(results, key=lambda r: r[0])[1]}
    if best['step'] is not None:
        best.pop('step_note')
    return best


def _profile_response(tc: np.ndarray, fc: np.ndarray, tm: np.ndarray, fm: np.ndarray,
                      profile: ForceTrackingProfile) -> dict[str, Any] | None:
    """`force_tracking` on one source's commands ``(tc, fc)`` and the measured ``(tm, fm)``;
    None when the profile cannot be aligned."""
    from slip_gripper_driver.core.force_tracking import (
        align_profile,
        bandwidth_3db,
        frequency_point,
        step_metrics,
    )
    out: dict[str, Any] = {'excitation': {'found': False, 'sines_hz': [], 'note': NO_EXCITATION
                                          + ': the force command holds none of the sines of '
                                          'the force-tracking profile (§5.4)'},
                           'frequency_response': None, 'bandwidth_hz': None,
                           'bandwidth_note': NO_EXCITATION, 'step': None}
    try:
        t0 = align_profile(tc, fc, profile)
    except ValueError:
        return None
    t_step, f_from, f_to, t_end = profile.step_segment()
    before = _level(tc, fc, t0 + t_step - 0.5, t0 + t_step - 0.02)
    after = _level(tc, fc, t0 + t_step + 0.02, t0 + t_end - 0.02)
    if abs(before - f_from) <= 0.5 and abs(after - f_to) <= 0.5:
        try:
            step = step_metrics(tm, fm, t_step=t0 + t_step, f_from=f_from, f_to=f_to,
                                window_s=t_end - t_step, fs=profile.rate_hz)
            out['step'] = step._asdict()
            out['step_t'] = t0 + t_step
            out['step_notes'] = _step_notes(step, t_end - t_step)
        except ValueError as exc:
            out['step_note'] = f'step not analysable: {exc}'
    amplitude = 0.5 * (profile.sine_high - profile.sine_low)
    points, found, fits = [], [], []
    for seg in profile.sine_segments():
        a, b = t0 + seg.t_start + 0.1, t0 + seg.t_end - 0.1
        m = (tc >= a) & (tc <= b)
        fit = fit_sine(tc[m], fc[m], seg.frequency)
        fits.append({'frequency_hz': seg.frequency, 'amplitude': fit.amplitude,
                     'explained': fit.explained, 'n': fit.n})
        if not is_excited(fit, amplitude):
            continue
        try:
            point = frequency_point(tc[m], fc[m], np.interp(tc[m], tm, fm),
                                    frequency=seg.frequency, t_start=t0 + seg.t_start,
                                    duration=seg.t_end - seg.t_start, fs=profile.rate_hz)
        except ValueError:
            continue
        points.append(point._asdict())
        found.append(seg.frequency)
    out['excitation']['fits'] = fits
    if points:
        missing = [s.frequency for s in profile.sine_segments() if s.frequency not in found]
        out['excitation'].update(found=True, sines_hz=found,
                                 note=f'sines found in the force command at '
                                      f'{", ".join(f"{f:g}" for f in found)} Hz'
                                      + (f'; absent at {", ".join(f"{f:g}" for f in missing)} Hz'
                                         if missing else ''))
        out['frequency_response'] = points
        bw = bandwidth_3db([p['frequency_hz'] for p in points],
                           [p['magnitude_db'] for p in points])
        out['bandwidth_hz'] = bw
        out['bandwidth_note'] = ('interpolated −3 dB crossing' if math.isfinite(bw) else
                                 'not determined: the tested frequencies do not bracket the '
                                 '−3 dB crossing')
    return out


def force_peak(data: dict[str, Any], runs: list[Phase], lookback_s: float = 0.5
               ) -> dict[str, Any] | None:
    """The largest measured grasp force and what commanded it.

    Looks at the grasp-force commands of the ``lookback_s`` before the peak (and the one in
    force when that window began): their maximum, its source, and the controller phase.
    ``commanded`` is true when the command reached at least 90 % of the peak (a commanded
    force, e.g. a controller spike, not an overshoot or a disturbance).
    """
    m = data['motor']
    ok = np.isfinite(m.cols['measured'])
    if not ok.any():
        return None
    i = int(np.flatnonzero(ok)[np.argmax(m.cols['measured'][ok])])
    t, f = float(m.t[i]), float(m.cols['measured'][i])
    phase = phase_at(runs, t)
    out: dict[str, Any] = {'t': t, 'force': f, 'phase': phase.mode if phase else None,
                           'since_phase_start': t - phase.t_start if phase else None,
                           'target': float(m.cols['target'][i])}
    if 'cmd' in data:
        c = data['cmd']
        # The commands of the last lookback_s, and the one still standing at its start.
        first = max(int(np.searchsorted(c.t, t - lookback_s, side='right')) - 1, 0)
        last = int(np.searchsorted(c.t, t, side='right'))
        if last > first:
            k = first + int(np.argmax(c.cols['force'][first:last]))
            cmd, source = float(c.cols['force'][k]), int(c.cols['source'][k])
            out.update(command_peak=cmd, command_t=float(c.t[k]),
                       source=SOURCE_NAMES.get(source, f'source {source}'),
                       commanded=bool(cmd >= 0.9 * f))
    return out


def peak_explanation(peak: dict[str, Any]) -> str:
    """One sentence on the force peak for plots and reports."""
    where = (f' {peak["since_phase_start"]:.2f} s after {peak["phase"].upper()} began'
             if peak.get('phase') else '')
    text = f'peak {peak["force"]:.1f} N{where}'
    if 'command_peak' not in peak:
        return text + ' (no grasp-force command recorded)'
    if peak['commanded']:
        text += (f': commanded by {peak["source"]} (up to {peak["command_peak"]:.1f} N'
                 + (f', limited by the force loop to {peak["target"]:.1f} N'
                    if peak['target'] < peak['command_peak'] - 0.5 else '')
                 + ') — a real command, not a sensor artefact')
    else:
        text += (f': the command stayed at or below {peak["command_peak"]:.1f} N '
                 f'({peak["source"]}) — overshoot or an external load')
    return text


def _force(data: dict[str, Any], runs: list[Phase]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    m = data['motor']
    ok = np.isfinite(m.cols['measured'])
    if ok.any():
        err = m.cols['target'][ok] - m.cols['measured'][ok]
        out['tracking_rms'] = float(np.sqrt(np.mean(err ** 2)))
        out['measured_range'] = [float(m.cols['measured'][ok].min()),
                                 float(m.cols['measured'][ok].max())]
        stats = core_metrics.force_stats(m.cols['measured'])
        out['measured'] = {**asdict(stats), 'span': stats.span}
        peak = force_peak(data, runs)
        if peak is not None:
            out['peak'] = {**peak, 'explanation': peak_explanation(peak)}
    if 'cmd' in data:
        sources = data['cmd'].cols['source'].astype(int)
        out['command_sources'] = {SOURCE_NAMES.get(int(s), f'source {s}'): int(n)
                                  for s, n in zip(*np.unique(sources, return_counts=True))}
    out.update(force_tracking(data))
    return out


def analyze_bag(bag_or_data: Path | str | dict[str, Any], frames: FrameParams | None = None
                ) -> dict[str, Any]:
    """All metrics of a bag (a path, or what `load` returned) as a dict (see the module
    docstring); `jsonable` makes it JSON-serialisable."""
    frames = frames or FrameParams()
    data = _data(bag_or_data)
    runs, ends = timeline(data)
    return {'bag': data['bag'], 'span': list(data['span']),
            'phases': [asdict(p) for p in runs], 'ends': [asdict(e) for e in ends],
            'aborts': [asdict(e) for e in ends if not e.success],
            'force': _force(data, runs), 'estimation': _estimation(data),
            'slip': _slip(data, frames, ends), 'hold': _hold(data, runs, frames)}


def plot_bag(bag_or_data: Path | str | dict[str, Any], out_dir: Path | str,
             metrics: dict[str, Any] | None = None, progress: Progress | None = None
             ) -> list[Path]:
    """Write the PNG plots (see the module docstring) to ``out_dir``; returns their paths."""
    from slip_bringup.analysis_plots import save_figures
    data = _data(bag_or_data)
    return save_figures(data, metrics if metrics is not None else analyze_bag(data),
                        Path(out_dir), progress)


def report(bag: Path | str, out_dir: Path | str | None, *, plots: bool = True,
           progress: Progress | None = None) -> tuple[dict[str, Any], list[Path]]:
    """Read ``bag`` once, compute the metrics and (with ``out_dir``) write ``metrics.json``
    and the plots there. Returns the JSON-ready metrics and the written plot paths."""
    say = progress or (lambda text: None)
    data = load(bag, progress)
    say('computing metrics')
    metrics = analyze_bag(data)
    result = jsonable(metrics)
    written: list[Path] = []
    if out_dir is not None:
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        (out / 'metrics.json').write_text(json.dumps(result, indent=2) + '\n')
        say(f'wrote {out / "metrics.json"}')
        if plots:
            written = plot_bag(data, out, metrics, progress)
    return result, written


def jsonable(value: Any) -> Any:
    """``value`` with dataclasses as dicts and NaN/inf as None (JSON has neither)."""
    if is_dataclass(value) and not isinstance(value, type):
        return jsonable(asdict(value))
    if isinstance(value, dict):
        return {k: jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (np.floating, float)):
        return None if not math.isfinite(float(value)) else float(value)
    if isinstance(value, np.integer):
        return int(value)
    return value


_jsonable = jsonable  # the name slip_demo imports


def stage_printer(stream: TextIO | None = None, prog: str = 'slip_analyze') -> Progress:
    """Progress lines ``prog: [  1.2 s] text`` on ``stream`` (default: the current
    ``sys.stderr``), flushed, so that a pipe shows them as they happen."""
    started = time.monotonic()

    def say(text: str) -> None:
        print(f'{prog}: [{time.monotonic() - started:5.1f} s] {text}',
              file=stream or sys.stderr, flush=True)
    return say


def _parser() -> Parser:
    parser = Parser(prog='slip_analyze', description=plain_doc(__doc__))
    parser.add_argument('bag', help='bag folder (rosbag2, MCAP) to analyse')
    parser.add_argument('--out', metavar='DIR',
                        help='write metrics.json and the PNG plots to this directory '
                             '(default: none; the metrics are printed only)')
    parser.add_argument('--no-plots', action='store_true',
                        help='with --out: write metrics.json only, no PNG plots')
    parser.add_argument('--quiet', action='store_true',
                        help='no progress lines on stderr (errors are still printed)')
    return parser


def main(argv: list[str] | None = None) -> int:
    """Console script ``slip_analyze``: prints the metrics JSON on stdout; exit code 2 with
    one error line for a bag it cannot read."""
    ns = _parser().parse_args(argv)
    progress = None if ns.quiet else stage_printer()
    try:
        metrics, plots = report(ns.bag, ns.out, plots=not ns.no_plots, progress=progress)
    except (BagError, OSError) as exc:
        print(f'slip_analyze: error: {BagError(str(exc))}', file=sys.stderr, flush=True)
        return 2
    print(json.dumps(metrics, indent=2), flush=True)
    if progress is not None:
        progress('done' + (f': {len(plots)} plot(s) in {ns.out}' if plots else ''))
    return 0


if __name__ == '__main__':
    sys.exit(main())
