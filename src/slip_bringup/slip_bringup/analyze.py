"""``slip_analyze``: metrics (JSON) and plots (PNG) of any recorded experiment.

Metrics follow control_and_estimation §6, on header stamps:

* ``force``: grasp-force tracking (target vs measured); when the bag holds the force-tracking
  profile (§5.4), the 5 → 25 N step metrics, the frequency response and the −3 dB bandwidth.
* ``estimation``: every estimated contact-property set and their spread (§6.4); the simulator's
  ground truth when recorded (``sim/true_contact``).
* ``slip``: per LINEAR / ROTATIONAL segment of ``slip_control/tracking``: target, final
  measured position, tracking errors (§6.5, §6.6), the sensor-based final slip (reference
  magnitude and signed definitions), and the simulator's true object motion when recorded.
* ``hold``: peak slip and force range while holding (§6.7).

    slip_analyze bags/linear_slip --out /tmp/linear_slip_report
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import asdict, dataclass, is_dataclass
from pathlib import Path
from typing import Any

import numpy as np

from slip_cell_common.bag_io import BagError, read_messages, stamp_s
from slip_cell_common.core.frames import FrameParams, planar_to_middle

TOPICS = {
    'cmd': '/gripper/grasp_force_cmd', 'motor': '/gripper/motor_command',
    'status': '/gripper/status', 'ft1': '/finger_1/ft/wrench', 'ft2': '/finger_2/ft/wrench',
    'tw1': '/finger_1/slip/twist', 'tw2': '/finger_2/slip/twist',
    'tracking': '/slip_control/tracking', 'props': '/contact/properties',
    'truth_props': '/sim/true_contact', 'sim': '/sim/state',
}
MODE_NAMES = {1: 'rotational', 2: 'linear', 3: 'hinge', 4: 'hold'}


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


def _series(items: list[tuple[int, Any]], fields: dict[str, Any]) -> Series:
    t = np.array([stamp_s(m) for _, m in items], dtype=np.float64)
    cols = {name: np.array([get(m) for _, m in items], dtype=np.float64)
            for name, get in fields.items()}
    order = np.argsort(t, kind='stable')
    return Series(t[order], {k: v[order] for k, v in cols.items()})


def load(bag: Path | str) -> dict[str, Any]:
    """Read the topics the metrics need (absent topics are simply missing)."""
    msgs = read_messages(bag)
    data: dict[str, Any] = {}
    if TOPICS['cmd'] in msgs:
        data['cmd'] = _series(msgs[TOPICS['cmd']], {'force': lambda m: m.force})
    if TOPICS['motor'] in msgs:
        data['motor'] = _series(msgs[TOPICS['motor']], {
            'target': lambda m: m.force_target, 'measured': lambda m: m.measured_force,
            'u': lambda m: m.force_cmd})
    for k in (1, 2):
        if TOPICS[f'ft{k}'] in msgs:
            data[f'ft{k}'] = _series(msgs[TOPICS[f'ft{k}']], {
                'fx': lambda m: m.wrench.force.x, 'fy': lambda m: m.wrench.force.y,
                'fz': lambda m: m.wrench.force.z, 'tz': lambda m: m.wrench.torque.z})
        if TOPICS[f'tw{k}'] in msgs:
            data[f'tw{k}'] = _series(msgs[TOPICS[f'tw{k}']], {
                'vx': lambda m: m.twist.linear.x, 'vy': lambda m: m.twist.linear.y,
                'wz': lambda m: m.twist.angular.z})
    if TOPICS['tracking'] in msgs:
        data['tracking'] = _series(msgs[TOPICS['tracking']], {
            'mode': lambda m: m.mode, 'ref_pos': lambda m: m.ref_pos,
            'ref_vel': lambda m: m.ref_vel, 'meas_pos': lambda m: m.meas_pos,
            'meas_vel': lambda m: m.meas_vel, 'force': lambda m: m.force_cmd,
            'done': lambda m: float(m.done)})
    if TOPICS['sim'] in msgs:
        data['sim'] = _series(msgs[TOPICS['sim']], {
            'x': lambda m: m.x, 'y': lambda m: m.y, 'theta': lambda m: m.theta,
            'fn1': lambda m: m.normal_force_1, 'fn2': lambda m: m.normal_force_2,
            'arm_angle': lambda m: m.arm_angle})
    data['props'] = [m for _, m in msgs.get(TOPICS['props'], [])]
    data['truth'] = [m for _, m in msgs.get(TOPICS['truth_props'], [])]
    return data


def _finger(f: Any) -> dict[str, Any]:
    return {k: getattr(f, k) for k in ('mu_c', 'mu_s', 'mu_v', 'r', 'u', 'mu_c_std', 'r_std',
                                       'n_linear', 'n_static', 'n_rotational', 'linear_valid',
                                       'rotational_valid')}


def _estimation(data: dict[str, Any]) -> dict[str, Any]:
    estimated = [p for p in data['props'] if p.source == 1]
    out: dict[str, Any] = {'estimates': [{'finger_1': _finger(p.finger_1),
                                          'finger_2': _finger(p.finger_2), 'valid': p.valid,
                                          'online_updated': p.online_updated}
                                         for p in estimated]}
    for key in ('finger_1', 'finger_2'):
        for name in ('mu_c', 'r'):
            vals = [getattr(getattr(p, key), name) for p in estimated
                    if getattr(getattr(p, key), 'linear_valid')]
            if vals:
                out.setdefault('spread', {}).setdefault(key, {})[name] = {
                    'mean': float(np.mean(vals)), 'sd': float(np.std(vals)), 'n': len(vals)}
    if data['truth']:
        truth = data['truth'][-1]
        out['truth'] = {'preset': truth.preset_name, 'finger_1': _finger(truth.finger_1),
                        'finger_2': _finger(truth.finger_2)}
        if estimated:
            last = estimated[-1]
            out['error_last'] = {
                key: {'mu_c': getattr(last, key).mu_c - getattr(truth, key).mu_c,
                      'r': getattr(last, key).r - getattr(truth, key).r}
                for key in ('finger_1', 'finger_2')}
    return out


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


def _middle_velocity(data: dict[str, Any], t0: float, t1: float,
                     frames: FrameParams) -> tuple[np.ndarray, np.ndarray, np.ndarray, Series,
                                                   Series] | None:
    if 'tw1' not in data or 'tw2' not in data:
        return None
    w1, w2 = data['tw1'].window(t0, t1), data['tw2'].window(t0, t1)
    if len(w1) < 2 or len(w2) < 2:
        return None
    v1 = np.array([planar_to_middle(frames, 1, a, b, c)[:2] for a, b, c in
                   zip(w1.cols['vx'], w1.cols['vy'], w1.cols['wz'])])
    v2_raw = np.array([planar_to_middle(frames, 2, a, b, c)[:2] for a, b, c in
                       zip(w2.cols['vx'], w2.cols['vy'], w2.cols['wz'])])
    v2 = np.column_stack([np.interp(w1.t, w2.t, v2_raw[:, i]) for i in range(2)])
    return w1.t, v1, v2, w1, w2


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


def _slip(data: dict[str, Any], frames: FrameParams) -> list[dict[str, Any]]:
    from slip_bringup.core.metrics import (linear_slip_distance, rotational_slip_angle,
                                           tracking_errors)
    out = []
    track = data.get('tracking')
    for mode, t0, t1 in _segments(track) if track is not None else []:
        if mode not in (1, 2):
            continue
        seg = track.window(t0, t1)
        err = tracking_errors(seg.cols['ref_pos'], seg.cols['meas_pos'], seg.cols['ref_vel'],
                              seg.cols['meas_vel'])
        item: dict[str, Any] = {
            'mode': MODE_NAMES[mode], 't_start': t0, 't_end': t1,
            'target': _trapezoid_target(seg),
            'final_measured': float(seg.cols['meas_pos'][-1]), 'tracking': asdict(err),
            'force_range': [float(seg.cols['force'].min()), float(seg.cols['force'].max())]}
        vel = _middle_velocity(data, t0, t1, frames)
        if vel is not None:
            t, v1, v2, w1, w2 = vel
            if mode == 2:
                item['sensor_slip'] = asdict(linear_slip_distance(t, v1, v2))
            else:
                wz2 = np.interp(w1.t, w2.t, w2.cols['wz'])
                item['sensor_angle'] = rotational_slip_angle(t, w1.cols['wz'], wz2)
        if 'sim' in data:
            sim = data['sim'].window(t0, t1 + 1.0)
            if len(sim) >= 2:
                dx, dy = sim.cols['x'][-1] - sim.cols['x'][0], sim.cols['y'][-1] - sim.cols['y'][0]
                item['true_motion'] = {'distance': float(math.hypot(dx, dy)),
                                       'angle': float(sim.cols['theta'][-1] - sim.cols['theta'][0])}
        out.append(item)
    return out


def _force(data: dict[str, Any]) -> dict[str, Any]:
    from slip_gripper_driver.core.force_tracking import analyze as analyze_tracking
    out: dict[str, Any] = {}
    if 'motor' in data and len(data['motor']):
        m = data['motor']
        ok = np.isfinite(m.cols['measured'])
        if ok.any():
            err = m.cols['target'][ok] - m.cols['measured'][ok]
            out['tracking_rms'] = float(np.sqrt(np.mean(err ** 2)))
            out['measured_range'] = [float(m.cols['measured'][ok].min()),
                                     float(m.cols['measured'][ok].max())]
    if 'cmd' in data and 'ft1' in data and len(data['cmd']) > 100:
        try:
            report = analyze_tracking(data['cmd'].t, data['cmd'].cols['force'], data['ft1'].t,
                                      -data['ft1'].cols['fz'])
        except (ValueError, IndexError):
            return out  # not a force-tracking recording
        out['step'] = report.step._asdict()
        out['frequency_response'] = [p._asdict() for p in report.response]
        out['bandwidth_hz'] = report.bandwidth_hz
    return out


def analyze_bag(bag: Path | str, frames: FrameParams | None = None) -> dict[str, Any]:
    """All metrics of a bag as a JSON-serialisable dict."""
    frames = frames or FrameParams()
    data = load(bag)
    return {'bag': str(bag), 'force': _force(data), 'estimation': _estimation(data),
            'slip': _slip(data, frames)}


def plot_bag(bag: Path | str, out_dir: Path | str) -> list[Path]:
    """PNG plots: force vs target, slip vs reference, twist per finger, contact estimates."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    data = load(bag)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []

    def save(fig: Any, name: str) -> None:
        path = out_dir / name
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)

    if 'motor' in data or 'ft1' in data:
        fig, ax = plt.subplots(figsize=(9, 3.5))
        if 'motor' in data:
            ax.plot(data['motor'].t, data['motor'].cols['target'], label='target F_d')
            ax.plot(data['motor'].t, data['motor'].cols['measured'], label='measured F_m')
        if 'ft1' in data:
            ax.plot(data['ft1'].t, -data['ft1'].cols['fz'], lw=0.6, alpha=0.6,
                    label='finger 1 −Fz')
        ax.set(xlabel='time [s]', ylabel='grasp force [N]', title='Grasp force')
        ax.legend(loc='upper right')
        save(fig, 'force.png')
    if 'tracking' in data:
        segs = [s for s in _segments(data['tracking']) if s[0] in (1, 2)]
        if segs:
            fig, axes = plt.subplots(len(segs), 1, figsize=(9, 2.8 * len(segs)), squeeze=False)
            for ax, (mode, t0, t1) in zip(axes[:, 0], segs):
                seg = data['tracking'].window(t0, t1)
                scale, unit = (1e3, 'mm') if mode == 2 else (180 / math.pi, 'deg')
                ax.plot(seg.t - t0, seg.cols['ref_pos'] * scale, label='reference')
                ax.plot(seg.t - t0, seg.cols['meas_pos'] * scale, label='measured')
                ax.set(xlabel='time [s]', ylabel=f'slip [{unit}]',
                       title=f'{MODE_NAMES[mode]} slip')
                ax.legend(loc='lower right')
            save(fig, 'slip.png')
    if 'tw1' in data:
        fig, axes = plt.subplots(2, 1, figsize=(9, 5), sharex=True)
        for ax, k in zip(axes, (1, 2)):
            if f'tw{k}' in data:
                s = data[f'tw{k}']
                ax.plot(s.t, s.cols['vx'] * 1e3, label='vx [mm/s]')
                ax.plot(s.t, s.cols['vy'] * 1e3, label='vy [mm/s]')
                ax.plot(s.t, s.cols['wz'] * 1e2, label='ω [rad/s ×100]')
                ax.set(ylabel=f'finger {k}')
                ax.legend(loc='upper right', fontsize=8)
        axes[-1].set(xlabel='time [s]')
        fig.suptitle('Slip twist per finger (pad frames)')
        save(fig, 'twist.png')
    est = [p for p in data['props'] if p.source == 1]
    if est or data['truth']:
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(9, 3.2))
        for offset, (label, sets) in enumerate((('estimated', est), ('truth', data['truth'][-1:]))):
            for k, key in enumerate(('finger_1', 'finger_2')):
                vals = [getattr(p, key) for p in sets]
                if vals:
                    x = k + 0.35 * offset
                    a1.bar(x, np.mean([v.mu_c for v in vals]), 0.3,
                           label=label if k == 0 else None, color=f'C{offset}')
                    a2.bar(x, np.mean([v.r for v in vals]) * 1e3, 0.3, color=f'C{offset}')
        for ax, title in ((a1, 'μ_c'), (a2, 'r [mm]')):
            ax.set_xticks([0.15, 1.15], ['finger 1', 'finger 2'])
            ax.set_title(title)
        a1.legend()
        save(fig, 'contact.png')
    return written


def _jsonable(value: Any) -> Any:
    if is_dataclass(value):
        return _jsonable(asdict(value))
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, (np.floating, float)):
        return None if not math.isfinite(float(value)) else float(value)
    if isinstance(value, np.integer):
        return int(value)
    return value


def main(argv: list[str] | None = None) -> int:
    """Console script ``slip_analyze``."""
    parser = argparse.ArgumentParser(prog='slip_analyze', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('bag')
    parser.add_argument('--out', help='directory for metrics.json and PNG plots')
    parser.add_argument('--no-plots', action='store_true')
    ns = parser.parse_args(argv)
    try:
        metrics = _jsonable(analyze_bag(ns.bag))
        text = json.dumps(metrics, indent=2)
        if ns.out:
            out = Path(ns.out)
            out.mkdir(parents=True, exist_ok=True)
            (out / 'metrics.json').write_text(text + '\n')
            if not ns.no_plots:
                for path in plot_bag(ns.bag, out):
                    print(path, file=sys.stderr)
        print(text)
    except BagError as exc:
        print(f'slip_analyze: error: {exc}', file=sys.stderr)
        return 2
    return 0


if __name__ == '__main__':
    sys.exit(main())
