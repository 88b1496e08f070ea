# SPDX-License-Identifier: Apache-2.0
"""Command-line tool for the velocity-sensor calibration (hardware_protocols §3.7).

Sub-commands::

    calibration_fit fit RECORDINGS_DIR --out-dir DIR [--model abs|signed|none] ...
        Fit the 12 recordings Sensor<N>chip<k><x|y> and write, per sensor,
        calibration_sensor_<N>.yaml (SI, the file the node loads), a report plot (PNG) and a
        residual table (CSV). A recording is either a CSV file Sensor<N>chip<k><x|y>.csv
        (columns t [s], v [m/s]: raw chip speed in single-chip mode) or a bag directory
        Sensor<N>chip<k><x|y> written by calibration_recorder (the finger_<k>/slip/chips
        samples of chip k in single-chip mode, stamped at acquisition).
    calibration_fit from-table TABLE.csv --out-dir DIR
        Write calibration files from the reference table (velocity_sensor_calibration.csv).
    calibration_fit synth OUT_DIR [--truth-table TABLE.csv]
        Write 12 synthetic recordings of the procedure (to try the tool without hardware).
"""
from __future__ import annotations

import argparse
import csv
import math
import re
import sys
from dataclasses import replace
from pathlib import Path
from collections.abc import Sequence

import numpy as np

from slip_cell_common.core import names
from slip_cell_common.core.cli_args import Parser, non_negative_int, plain_doc, positive_float
from slip_velocity_sensor.core import calibration as cal_mod
from slip_velocity_sensor.core.calibration import (AxisCalibration, ChipCalibration,
                                                   SensorCalibration)
from slip_velocity_sensor.core.calibration_fit import (FIT_MODELS, AxisFit, FitError,
                                                       FitParams, fit_axis)
from slip_velocity_sensor.core.procedure import (ProcedureParams, SynthesisParams,
                                                 synthesize_recording)

RECORDING_RE = re.compile(r'Sensor(\d+)chip([123])([xy])(\.csv)?$')
CHIPS = (1, 2, 3)
AXES = ('x', 'y')


def is_bag(path: Path) -> bool:
    """True for a rosbag2 directory (holds ``metadata.yaml``)."""
    return path.is_dir() and (path / 'metadata.yaml').is_file()


def read_bag_recording(path: Path, chip: int, axis: str,
                       topic: str = '') -> tuple[np.ndarray, np.ndarray]:
    """Stamps ``t`` [s] and raw speed ``v`` [m/s] of chip ``chip``, axis ``axis`` from a bag.

    Uses the ``OpticalChipArray`` samples in single-chip mode ``chip`` (fused-mode samples
    before and after the procedure are skipped) with their acquisition stamps.

    Args:
        path: Bag directory (calibration_recorder output).
        chip: Chip 1..3.
        axis: ``'x'`` (tangential) or ``'y'`` (radial).
        topic: Chips topic; '' = the only ``.../slip/chips`` topic with samples of ``chip``.

    Raises:
        ValueError: No (or an ambiguous) chips topic, or no samples of the chip.
    """
    from slip_cell_common.bag_io import BagError, bag_info, read_messages, stamp_s

    try:
        if topic:
            topics = [topic]
        else:
            topics = [t.name for t in bag_info(path).topics
                      if t.msgtype == 'slip_msgs/msg/OpticalChipArray' and t.count > 0]
        data = read_messages(path, topics) if topics else {}
    except BagError as exc:
        raise ValueError(str(exc)) from exc
    series = {}
    for name, items in data.items():
        rows = [(stamp_s(msg), float((msg.vx if axis == 'x' else msg.vy)[chip - 1]))
                for _, msg in items if msg.chip_mode == chip]
        rows = [r for r in rows if math.isfinite(r[1])]
        if rows:
            series[name] = rows
    if not series:
        raise ValueError(f'{path}: no single-chip samples of chip {chip} on '
                         f'{topics or "any OpticalChipArray topic"}')
    if len(series) > 1:
        raise ValueError(f'{path}: chip {chip} samples on several topics {sorted(series)}; '
                         'choose one with --topic')
    arr = np.asarray(next(iter(series.values())), dtype=np.float64)
    order = np.argsort(arr[:, 0], kind='stable')
    return arr[order, 0], arr[order, 1]


def read_recording(path: Path, topic: str = '') -> tuple[np.ndarray, np.ndarray]:
    """``t`` [s] and ``v`` [m/s] of a recording: a CSV file or a bag named like a recording."""
    if is_bag(path):
        match = RECORDING_RE.fullmatch(path.name)
        if match is None:
            raise ValueError(f'{path}: bag name must be Sensor<N>chip<k><x|y>')
        return read_bag_recording(path, int(match[2]), match[3], topic)
    with path.open(newline='', encoding='utf-8') as handle:
        reader = csv.DictReader(handle)
        if reader.fieldnames is None or not {'t', 'v'} <= set(reader.fieldnames):
            raise ValueError(f'{path}: needs columns t [s] and v [m/s], got {reader.fieldnames}')
        rows = [(float(r['t']), float(r['v'])) for r in reader]
    data = np.asarray(rows, dtype=np.float64).reshape(-1, 2)
    return data[:, 0], data[:, 1]


def write_recording(path: Path, t: np.ndarray, v: np.ndarray) -> None:
    """Write a recording CSV (``t`` [s], ``v`` [m/s])."""
    with path.open('w', newline='', encoding='utf-8') as handle:
        writer = csv.writer(handle)
        writer.writerow(('t', 'v'))
        writer.writerows(zip((f'{x:.6f}' for x in t), (f'{x:.7f}' for x in v)))


def write_bag_recording(path: Path, t: np.ndarray, v: np.ndarray, chip: int, axis: str,
                        finger: int = 1) -> None:
    """Write a recording as the node publishes it: ``finger_<finger>/slip/chips`` samples.

    Args:
        path: New bag directory (``Sensor<N>chip<k><x|y>``).
        t: Acquisition stamps [s].
        v: Raw speed of chip ``chip`` along ``axis`` [m/s].
        chip: Chip 1..3 (also the chip mode of the samples).
        axis: ``'x'`` or ``'y'``.
        finger: Finger of the topic name.
    """
    from slip_cell_common.bag_io import BagWriter
    from slip_cell_common.time_conv import seconds_to_nanoseconds, split_nanoseconds

    topic = names.absolute(names.slip_chips(finger))
    msgtype = 'slip_msgs/msg/OpticalChipArray'
    with BagWriter(path) as writer:
        types = writer.typestore.types
        writer.add_topic(topic, msgtype)
        zeros = np.zeros(3, dtype=np.int16)
        prev = math.nan
        for t_k, v_k in zip(t, v):
            vx = np.full(3, math.nan)
            vy = np.full(3, math.nan)
            (vx if axis == 'x' else vy)[chip - 1] = v_k
            synced = np.zeros(3, dtype=bool)
            synced[chip - 1] = True
            ns = seconds_to_nanoseconds(float(t_k))
            sec, nanosec = split_nanoseconds(ns)
            stamp = types['builtin_interfaces/msg/Time'](sec=sec, nanosec=nanosec)
            header = types['std_msgs/msg/Header'](stamp=stamp,
                                                  frame_id=names.vel_sensor_frame(finger))
            msg = types[msgtype](header=header, chip_mode=chip, dx=zeros, dy=zeros,
                                 dt=float(t_k) - prev,
                                 vx=vx, vy=vy, calibrated=False, synced=synced)
            writer.write_message(topic, ns, msg)
            prev = float(t_k)


def find_recordings(directory: Path) -> dict[int, dict[tuple[int, str], Path]]:
    """``{sensor: {(chip, axis): path}}`` of the recordings in ``directory``."""
    found: dict[int, dict[tuple[int, str], Path]] = {}
    for path in sorted(directory.iterdir()):
        match = RECORDING_RE.fullmatch(path.name)
        if match and (match[4] is not None or is_bag(path)):
            key = (int(match[2]), match[3])
            files = found.setdefault(int(match[1]), {})
            if key in files:
                raise ValueError(f'{directory}: both {files[key].name} and {path.name} hold '
                                 f'Sensor{match[1]}chip{match[2]}{match[3]}')
            files[key] = path
    return found


def read_table(path: Path) -> dict[int, SensorCalibration]:
    """Calibrations from the reference table (a in 1/(mm/s) converted to SI)."""
    values: dict[int, dict[tuple[int, str], AxisCalibration]] = {}
    radius: dict[int, float] = {}
    with path.open(newline='', encoding='utf-8') as handle:
        for row in csv.DictReader(handle):
            sensor = int(row['sensor'])
            a_si = round(float(row['a_per_mm_s']) * 1000.0, 10)
            values.setdefault(sensor, {})[(int(row['chip']), row['axis'])] = \
                AxisCalibration(a=a_si, b=float(row['b']))
            radius[sensor] = round(float(row['radius_mm']) / 1000.0, 10)
    out = {}
    for sensor, axes in values.items():
        chips = tuple(ChipCalibration(x=axes[(c, 'x')], y=axes[(c, 'y')]) for c in CHIPS)
        out[sensor] = SensorCalibration(
            sensor=f'sensor_{sensor}', radius=radius[sensor], chips=chips,
            source=f'reference table {path.name} (hardware_protocols §3.6)')
    return out


# --------------------------------------------------------------------------- fit


def _plot(path: Path, sensor: int, fits: dict[tuple[int, str], AxisFit]) -> None:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 3, figsize=(13, 7), sharex=True, squeeze=False)
    for col, chip in enumerate(CHIPS):
        for row, axis in enumerate(AXES):
            ax = axes[row][col]
            fit = fits[(chip, axis)]
            for direction, marker, label in ((1, 'o', '+ direction'), (-1, 's', '- direction')):
                trs = [tr for tr in fit.accepted if tr.direction == direction]
                ax.plot([abs(tr.v_m) * 1e3 for tr in trs], [tr.q for tr in trs], marker,
                        ls='none', mfc='none', label=label)
            speeds = np.linspace(0.0, max(abs(tr.v_m) for tr in fit.accepted), 50)
            reg = speeds if fit.model != 'none' else np.zeros_like(speeds)
            ax.plot(speeds * 1e3, fit.raw.b + fit.raw.a * reg, 'k-', label=f'fit ({fit.model})')
            for sub, style in ((fit.positive, 'C0:'), (fit.negative, 'C1:')):
                if sub is not None:
                    ax.plot(speeds * 1e3, sub.b + sub.a * speeds, style)
            check = fit.summary()['check_rms_m']
            ax.set_title(f'chip {chip} {axis}: b={fit.calibration.b:.4f} '
                         f'a={fit.calibration.a:.3f} 1/(m/s)\n'
                         f'check rms {float(check) * 1e3:.3f} mm', fontsize=9)
            ax.grid(True, alpha=0.3)
            ax.ticklabel_format(axis='y', useOffset=False)
            if row == 1:
                ax.set_xlabel('|v_m| [mm/s]')
            if col == 0:
                ax.set_ylabel('q = measured / true')
    axes[0][0].legend(fontsize=8)
    fig.suptitle(f'Sensor {sensor}: q = b + a·term(v_m)')
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _write_residuals(path: Path, fits: dict[tuple[int, str], AxisFit]) -> None:
    with path.open('w', newline='', encoding='utf-8') as handle:
        writer = csv.writer(handle)
        writer.writerow(('chip', 'axis', 'traverse', 'direction', 'duration_s', 'v_m_m_s', 'q',
                         'q_residual', 'check_error_mm', 'check_error_b_only_mm'))
        for (chip, axis), fit in sorted(fits.items()):
            for i, tr in enumerate(fit.accepted):
                writer.writerow((chip, axis, i, tr.direction, f'{tr.duration:.4f}',
                                 f'{tr.v_m:.6f}', f'{tr.q:.6f}', f'{fit.residuals[i]:.6f}',
                                 f'{fit.check_errors[i] * 1e3:.4f}',
                                 f'{fit.check_errors_b_only[i] * 1e3:.4f}'))


def _print_table(sensor: int, fits: dict[tuple[int, str], AxisFit]) -> None:
    print(f'\nSensor {sensor}')
    print(f'{"chip":>4} {"ax":>2} {"b":>7} {"a[1/(m/s)]":>10} {"b+":>7} {"a+":>7} {"b-":>7} '
          f'{"a-":>7} {"n":>3} {"q rms":>8} {"chk rms":>8} {"b-only":>8}')
    for (chip, axis), fit in sorted(fits.items()):
        s = fit.summary()
        pos = fit.positive or fit.raw
        neg = fit.negative or fit.raw
        print(f'{chip:>4} {axis:>2} {fit.calibration.b:7.4f} {fit.calibration.a:10.4f} '
              f'{pos.b:7.4f} {pos.a:7.3f} {neg.b:7.4f} {neg.a:7.3f} {fit.raw.n:>3} '
              f'{fit.raw.residual_rms:8.5f} {float(s["check_rms_m"]) * 1e3:6.3f}mm '
              f'{float(s["check_b_only_rms_m"]) * 1e3:6.3f}mm')


def _fit_command(args: argparse.Namespace) -> int:
    params = FitParams(distance=args.distance, model=args.model, a_factor=args.a_factor)
    try:
        found = find_recordings(Path(args.recordings))
    except (OSError, ValueError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    if not found:
        print(f'no recordings Sensor<N>chip<k><x|y>.csv or bags Sensor<N>chip<k><x|y> in '
              f'{args.recordings}', file=sys.stderr)
        return 2
    out_dir = Path(args.out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    status = 0
    for sensor, files in sorted(found.items()):
        missing = [f'chip{c}{a}' for c in CHIPS for a in AXES if (c, a) not in files]
        if missing:
            print(f'Sensor {sensor}: missing recordings {missing}; skipped', file=sys.stderr)
            status = 1
            continue
        fits: dict[tuple[int, str], AxisFit] = {}
        try:
            for key, path in sorted(files.items()):
                t, v = read_recording(path, args.topic)
                fits[key] = fit_axis(t, v, params)
        except (FitError, ValueError) as exc:
            print(f'Sensor {sensor}: {path.name}: {exc}', file=sys.stderr)
            status = 1
            continue
        chips = []
        for chip in CHIPS:
            axes = {}
            for axis in AXES:
                axis_cal = fits[(chip, axis)].calibration
                if axis == 'x' and args.zero_x_a:
                    axis_cal = replace(axis_cal, a=0.0)
                axes[axis] = axis_cal
            chips.append(ChipCalibration(**axes))
        cal = SensorCalibration(
            sensor=f'sensor_{sensor}', radius=args.radius, chips=tuple(chips),
            source=f'calibration_fit of {args.recordings} (model {args.model}, '
                   f'a_factor {args.a_factor:g}{", x a zeroed" if args.zero_x_a else ""})')
        report = {f'chip_{c}.{a}': fits[(c, a)].summary() for c in CHIPS for a in AXES}
        yaml_path = out_dir / f'calibration_sensor_{sensor}.yaml'
        cal_mod.save_calibration(yaml_path, cal, fit=report)
        _write_residuals(out_dir / f'calibration_sensor_{sensor}_residuals.csv', fits)
        if not args.no_plot:
            _plot(out_dir / f'calibration_sensor_{sensor}_report.png', sensor, fits)
        _print_table(sensor, fits)
        print(f'wrote {yaml_path}')
    return status


def _from_table_command(args: argparse.Namespace) -> int:
    out_dir = Path(args.out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    for sensor, cal in sorted(read_table(Path(args.table)).items()):
        path = out_dir / f'calibration_sensor_{sensor}.yaml'
        cal_mod.save_calibration(path, cal, header=(
            'Generated by `calibration_fit from-table` from the reference calibration table.\n'
            'Values as used by the reference system (x-axis a zeroed by hand there).'))
        print(f'wrote {path}')
    return 0


def _synth_command(args: argparse.Namespace) -> int:
    out_dir = Path(args.out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    if args.truth_table:
        truths = read_table(Path(args.truth_table))
    else:
        truths = {s: SensorCalibration(sensor=f'sensor_{s}') for s in (1, 2)}
    rng = np.random.default_rng(args.seed)
    synthesis = SynthesisParams(profile=args.profile)
    for sensor, cal in sorted(truths.items()):
        for chip in CHIPS:
            for axis in AXES:
                rec = synthesize_recording(cal.axis(chip, axis), ProcedureParams(), synthesis, rng)
                name = f'Sensor{sensor}chip{chip}{axis}'
                if args.format == 'bag':
                    write_bag_recording(out_dir / name, rec.t, rec.v, chip, axis, finger=sensor)
                else:
                    write_recording(out_dir / f'{name}.csv', rec.t, rec.v)
    print(f'wrote {6 * len(truths)} recordings ({args.format}) to {out_dir}')
    return 0


def build_parser() -> Parser:
    """Argument parser of the tool."""
    parser = Parser(prog='calibration_fit', description=plain_doc(__doc__))
    sub = parser.add_subparsers(dest='command', metavar='COMMAND', required=True,
                                help='step of the procedure (COMMAND --help for its options)')
    fit = sub.add_parser('fit', help='fit recordings and write calibration files',
                         description='Fit the 12 recordings Sensor<N>chip<k><x|y> and write, '
                                     'per sensor, calibration_sensor_<N>.yaml, a report plot '
                                     'and a residual table.')
    fit.add_argument('recordings',
                     help='directory with Sensor<N>chip<k><x|y>.csv files or bag directories')
    fit.add_argument('--topic', default='',
                     help="chips topic in the bags (default: the one with the chip's samples)")
    fit.add_argument('--out-dir', required=True, metavar='DIR',
                     help='directory for the calibration files, plots and tables (required)')
    fit.add_argument('--model', choices=FIT_MODELS, default='abs',
                     help='speed term of the fit (abs: symmetric in the speed; signed: as the '
                          'reference; none: no speed term, a constant scale)')
    fit.add_argument('--a-factor', type=positive_float, default=1.0,
                     help='hand factor on a (the reference used 0.88; 1.0 keeps the raw fit)')
    fit.add_argument('--zero-x-a', action='store_true',
                     help='set the x-axis a to 0 (as the reference did by hand)')
    fit.add_argument('--distance', type=positive_float, default=0.1,
                     help='stop-to-stop distance of each recording [m]')
    fit.add_argument('--radius', type=positive_float, default=0.0243,
                     help='chip radius written to the files [m]')
    fit.add_argument('--no-plot', action='store_true', help='skip the PNG report')
    fit.set_defaults(func=_fit_command)
    table = sub.add_parser('from-table', help='calibration files from the reference table',
                           description='Write calibration_sensor_<N>.yaml files from the '
                                       'reference table (velocity_sensor_calibration.csv).')
    table.add_argument('table', help='the reference table, velocity_sensor_calibration.csv')
    table.add_argument('--out-dir', required=True, metavar='DIR',
                       help='directory for the calibration files (required)')
    table.set_defaults(func=_from_table_command)
    synth = sub.add_parser('synth', help='synthetic procedure recordings',
                           description='Write 12 synthetic recordings of the procedure, to try '
                                       'the tool without hardware.')
    synth.add_argument('out_dir', help='directory for the recordings (created)')
    synth.add_argument('--truth-table', default='',
                       help='true calibration table (CSV) to synthesise from (default: the '
                            'nominal calibration of both sensors)')
    synth.add_argument('--profile', default='trapezoid',
                       choices=('constant', 'trapezoid', 'minimum_jerk'),
                       help='speed profile of each synthetic stroke')
    synth.add_argument('--seed', type=non_negative_int, default=0,
                       help='seed of the synthetic noise')
    synth.add_argument('--format', choices=('csv', 'bag'), default='csv',
                       help='CSV files or bags like calibration_recorder writes')
    synth.set_defaults(func=_synth_command)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point (``calibration_fit``)."""
    args = build_parser().parse_args(argv)
    return int(args.func(args))


if __name__ == '__main__':
    sys.exit(main())
