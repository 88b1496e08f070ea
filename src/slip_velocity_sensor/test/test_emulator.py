# SPDX-License-Identifier: Apache-2.0
"""Firmware emulator (virtual time): chip model, device calibration and fusion, commands."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from slip_cell_common.core.monitors import Level
from slip_velocity_sensor.core import calibration as cal_mod
from slip_velocity_sensor.core import protocol
from slip_velocity_sensor.core.chip_model import ChipModelParams, CountQuantizer, quantize_series
from slip_velocity_sensor.core.emulator import (ConstantTwist, EmulatorParams, FirmwareEmulator,
                                                SineTwist)
from slip_velocity_sensor.core.fusion import RigidBodyFusion
from slip_velocity_sensor.core.handshake import Handshake, HandshakeState
from slip_velocity_sensor.core.protocol import BadLine, LineParser, LineSplitter, VelocityLine
from slip_velocity_sensor.core.session import SensorSession

CONFIG = Path(__file__).resolve().parents[1] / 'config'
TRUTH = cal_mod.load_calibration(CONFIG / 'calibration_sensor_1.yaml')
COUNT_MM = 25.4 / 3200.0


def _velocity_lines(stream, duration: float, clock) -> list[VelocityLine]:
    parser, splitter, out = LineParser(), LineSplitter(), []
    end = clock() + duration
    while clock() < end:
        for line, overflow in splitter.feed(stream.read(4096)):
            parsed = parser.parse(line, overflow)
            if isinstance(parsed, VelocityLine):
                out.append(parsed)
    return out


def _initialised(emulator, virtual_stream, drive_handshake,
                 term: str = 'abs'):
    stream = virtual_stream(emulator)
    hs = Handshake('sensor_1', init_commands=cal_mod.upload_commands(TRUTH, term))
    drive_handshake(hs, stream)
    assert hs.state is HandshakeState.DONE, hs.error
    return stream


def test_calibrated_fused_output_recovers_the_true_twist(clock, virtual_stream,
                                                         drive_handshake) -> None:
    twist = (0.020, -0.010, 0.3)
    emulator = FirmwareEmulator(EmulatorParams(truth=TRUTH, firmware_speed_term='abs'),
                                ConstantTwist(*twist))
    stream = _initialised(emulator, virtual_stream, drive_handshake)
    lines = _velocity_lines(stream, 3.0, clock)[12:]
    mean = np.mean([(v.vx, v.vy, v.omega) for v in lines], axis=0)
    assert mean == pytest.approx(twist, rel=5e-3)
    # Quantisation: single lines scatter by about one count (≈ 1 mm/s), never more than ~3.
    spread = np.std([v.vx for v in lines])
    assert 1e-4 < spread < 3e-3


def test_uncalibrated_chips_read_low(clock, virtual_stream) -> None:
    emulator = FirmwareEmulator(EmulatorParams(truth=TRUTH, default_radius=0.0243),
                                ConstantTwist(0.02, 0.0, 0.0))
    lines = _velocity_lines(virtual_stream(emulator), 2.0, clock)[5:]
    ratio = np.mean([v.vx for v in lines]) / 0.02
    assert 0.85 < ratio < 0.95   # mean of the b values of sensor 1 (0.88 .. 0.93)


@pytest.mark.parametrize('chip', [1, 2, 3])
def test_one_chip_off_is_rejected_on_the_device(chip: int, clock, virtual_stream,
                                                drive_handshake) -> None:
    twist = (0.015, 0.010, -0.2)
    emulator = FirmwareEmulator(EmulatorParams(truth=TRUTH, firmware_speed_term='abs',
                                               chips_off=(chip,)), ConstantTwist(*twist))
    stream = _initialised(emulator, virtual_stream, drive_handshake)
    lines = _velocity_lines(stream, 2.0, clock)[12:]
    mean = np.mean([(v.vx, v.vy, v.omega) for v in lines], axis=0)
    assert mean == pytest.approx(twist, rel=2e-2, abs=2e-4)


def test_single_chip_mode_prints_raw_chip_speeds_and_a_stale_omega(clock, virtual_stream,
                                                                   drive_handshake) -> None:
    twist = np.array([0.01, 0.005, 0.5])
    emulator = FirmwareEmulator(EmulatorParams(truth=TRUTH), ConstantTwist(*twist))
    stream = _initialised(emulator, virtual_stream, drive_handshake, term='zero')
    _velocity_lines(stream, 0.5, clock)
    stream.write(b'c3\n')
    after = _velocity_lines(stream, 2.0, clock)
    fused, lines = after[0], after[5:]  # the command is handled after that loop's line
    readings = RigidBodyFusion().forward(twist)
    b3x, b3y = TRUTH.axis(3, 'x').b, TRUTH.axis(3, 'y').b
    a3y = TRUTH.axis(3, 'y').a
    raw_x = cal_mod.raw_speed(readings[4], TRUTH.axis(3, 'x'), 'abs')
    raw_y = cal_mod.raw_speed(readings[5], TRUTH.axis(3, 'y'), 'abs')
    assert raw_x == pytest.approx(b3x * readings[4]) and raw_y != pytest.approx(b3y * readings[5])
    assert a3y > 0.0
    assert np.mean([v.vx for v in lines]) == pytest.approx(raw_x, rel=1e-2)
    assert np.mean([v.vy for v in lines]) == pytest.approx(raw_y, rel=1e-2)
    assert {v.omega for v in lines} == {fused.omega}   # the last fused ω, repeated


def test_counts_saturate_at_127_per_poll(clock, virtual_stream) -> None:
    emulator = FirmwareEmulator(EmulatorParams(), ConstantTwist(1.5, 0.0, 0.0))
    stream = virtual_stream(emulator)
    stream.write(b'c3\n')                        # chip 3 (φ = 0): vx is its radial axis
    lines = _velocity_lines(stream, 2.0, clock)[5:]
    ceiling = 127 * COUNT_MM / 1000.0 / 0.0017  # ≈ 0.59 m/s per chip
    assert np.mean([v.vy for v in lines]) == pytest.approx(ceiling, rel=0.01)


def _mean_vy(speed: float, threshold: float, clock, virtual_stream) -> float:
    emulator = FirmwareEmulator(EmulatorParams(default_radius=0.0243,
                                               outlier_threshold=threshold),
                                ConstantTwist(0.0, speed, 0.0))
    lines = _velocity_lines(virtual_stream(emulator), 10.0, clock)
    return float(np.mean([v.vy for v in lines]))


def test_rest_reads_exactly_zero_and_slow_motion_is_quantised(clock, virtual_stream) -> None:
    # A fixed period, so that a count maps to one speed (with the firmware's 6-8 ms jitter
    # each period divides the counts by its own dt).
    emulator = FirmwareEmulator(EmulatorParams(period_jitter=0.0), ConstantTwist(0.0, 0.0, 0.0))
    rest = _velocity_lines(virtual_stream(emulator), 0.5, clock)
    assert rest and all(v.vx == 0.0 and v.vy == 0.0 and v.omega == 0.0 for v in rest)
    emulator.set_motion(ConstantTwist(0.0, 0.0005, 0.0))  # 0.5 mm/s: about half a count/line
    slow = _velocity_lines(virtual_stream(emulator), 2.0, clock)
    assert len({round(v.vy, 7) for v in slow}) <= 8      # a handful of quantisation levels
    # Counts carry their remainders: without outlier rejection the mean is unbiased ...
    assert _mean_vy(0.0005, np.inf, clock, virtual_stream) == pytest.approx(0.0005, rel=0.01)


def test_device_outlier_rejection_biases_sub_count_speeds(clock, virtual_stream) -> None:
    """A firmware artefact the host inherits: below ~1 count per line, a single count on one
    chip looks like an outlier, the 'slowest' chip is dropped and the mean is biased up."""
    slow = _mean_vy(0.0005, 0.2, clock, virtual_stream)
    assert slow > 1.1 * 0.0005
    assert _mean_vy(0.005, 0.2, clock, virtual_stream) == pytest.approx(0.005, rel=0.005)


def test_quantizer_carries_remainders_and_matches_the_series_version() -> None:
    params = ChipModelParams()
    rng = np.random.default_rng(0)
    disp = rng.normal(0.0, 0.2e-3, 5000)
    q = CountQuantizer(1, params)
    online = np.array([q.read([d])[0] for d in disp])
    series = quantize_series(disp, params)
    assert np.array_equal(online, series)
    assert abs(online.sum() * params.metres_per_count - disp.sum()) < params.metres_per_count
    big = quantize_series(np.full(10, 2e-3), params)   # 252 counts per read requested
    assert np.all(big == 127)


def test_garbage_injection_is_counted_and_never_breaks_the_session(clock, virtual_stream,
                                                                   drive_handshake) -> None:
    emulator = FirmwareEmulator(EmulatorParams(garbage_probability=0.3, seed=4),
                                SineTwist(0.02, 0.01, 0.5, 1.0))
    stream = _initialised(emulator, virtual_stream, drive_handshake)
    session = SensorSession(expected_name='sensor_1')
    session.mark_initialised(calibration_source='t', calibration_uploaded=True, speed_term='abs')
    samples = []
    end = clock() + 5.0
    while clock() < end:
        samples += session.feed(clock(), stream.read(4096))
    c = session.diagnostics(clock()).counters
    assert emulator.garbage_lines > 100 and c.bad > 100
    assert len(samples) == c.velocity and c.velocity > 0.85 * emulator.velocity_lines - 20
    assert all(s.valid for s in samples)


def test_restart_prints_a_boot_banner_and_loses_the_calibration(clock, virtual_stream,
                                                                drive_handshake) -> None:
    emulator = FirmwareEmulator(EmulatorParams(truth=TRUTH))
    stream = _initialised(emulator, virtual_stream, drive_handshake)
    assert emulator.device_radius == pytest.approx(0.0243)
    emulator.restart()
    parser, splitter = LineParser(), LineSplitter()
    end = clock() + 1.0
    while clock() < end:
        for line, ov in splitter.feed(stream.read(4096)):
            parser.parse(line, ov)
    assert parser.counters.boot == 2 and parser.counters.velocity > 50
    assert emulator.device_radius == pytest.approx(0.0203)
    assert emulator.device_calibration().is_identity


def test_at_most_one_command_per_serial_iteration() -> None:
    emulator = FirmwareEmulator(EmulatorParams())
    emulator.advance(0.0)
    emulator.receive(0.001, b'k0024.3\nc2\nn\n')
    out = emulator.advance(0.009)           # one iteration
    assert emulator.device_radius == pytest.approx(0.0243) and emulator.chip_mode == 0
    assert b'radius is updated to: 24.30' in out
    out = emulator.advance(0.0175)
    assert emulator.chip_mode == 2 and b'n/t' not in out
    assert b'n/tsensor_1' in emulator.advance(0.026)


def test_bad_commands_are_ignored_like_the_firmware() -> None:
    emulator = FirmwareEmulator(EmulatorParams())
    emulator.advance(0.0)
    emulator.receive(0.0, b'c7\nk1x0.5\nk11nan\nk00-3\nhello\n')
    emulator.advance(0.1)
    assert emulator.chip_mode == 0 and emulator.device_calibration().is_identity
    assert emulator.device_radius == pytest.approx(0.0203)


def test_emitted_lines_parse_as_good_lines(clock, virtual_stream) -> None:
    emulator = FirmwareEmulator(EmulatorParams(period_jitter=0.2, seed=1),
                                SineTwist(0.05, -0.03, 1.0, 2.0))
    stream = virtual_stream(emulator)
    parser, splitter = LineParser(), LineSplitter()
    end = clock() + 2.0
    while clock() < end:
        for line, ov in splitter.feed(stream.read(4096)):
            assert not isinstance(parser.parse(line, ov), BadLine)
    assert parser.counters.velocity == emulator.velocity_lines > 200
    assert protocol.EXPECTED_PRODUCT_ID == 0x31


# --------------------------------------------------------------------------- firmware behaviour

def _timed_output(emulator: FirmwareEmulator, until: float, step: float = 0.0005,
                  start: float = 0.0) -> list[tuple[float, bytes]]:
    """Lines the emulator prints from ``start`` to ``until``, with the time they came out."""
    splitter, out, t = LineSplitter(), [], start
    while t < until:
        t += step
        out += [(t, line) for line, _ in splitter.feed(emulator.advance(t))]
    return out


def test_output_period_is_6_to_8_ms_like_the_firmware() -> None:
    emulator = FirmwareEmulator(EmulatorParams(seed=2))
    times = np.array([t for t, line in _timed_output(emulator, 3.0, step=0.0001)
                      if line.startswith(b'v/t')])
    periods = np.diff(times)
    assert periods.min() >= 0.006 - 2e-4 and periods.max() <= 0.008 + 2e-4
    assert periods.std() > 0.0004                         # really jittered, not fixed
    assert 135.0 < 1.0 / periods.mean() < 150.0            # ≈ 143 Hz


def test_a_blind_chip_repeats_notice_and_signed_ids_every_pass_with_zero_lines() -> None:
    emulator = FirmwareEmulator(EmulatorParams(default_radius=0.0243, seed=1),
                                ConstantTwist(0.020, 0.0, 0.0))
    emulator.advance(0.2)
    emulator.set_chip_blind(1, product_id=-1)
    lines = _timed_output(emulator, 0.7, start=0.2)
    text = [line.rstrip(b'\r') for _, line in lines]
    notices = [i for i, line in enumerate(text) if line == b'n/tresynch']
    # Every notice is followed by the three signed product IDs, space-separated.
    assert all(text[i + 1] == b'-1 49 49' for i in notices)
    notice_times = np.array([lines[i][0] for i in notices])
    assert np.diff(notice_times).max() < 0.0065 and len(notices) > 70    # every ≈ 6 ms pass
    velocity = [line for line in text if line.startswith(b'v/t')]
    assert set(velocity[1:]) == {b'v/t0.0000/t0.0000/t0.0000'}             # nothing is read
    assert len(velocity) > 60
    kinds = {b'notice' if line == b'n/tresynch' else b'ids' if line == b'-1 49 49'
             else b'v' if line.startswith(b'v/t') else line for line in text}
    assert kinds == {b'notice', b'ids', b'v'}


def test_after_a_resync_the_notices_just_stop_and_motion_resumes() -> None:
    emulator = FirmwareEmulator(EmulatorParams(default_radius=0.0243, resync_duration=0.05,
                                               resync_chip=2, seed=1),
                                ConstantTwist(0.020, 0.0, 0.0))
    emulator.advance(0.1)
    emulator.inject_resync()
    lines = _timed_output(emulator, 0.5, start=0.1)
    text = [line.rstrip(b'\r') for _, line in lines]
    notice_times = [t for t, line in lines if line.rstrip(b'\r') == b'n/tresynch']
    assert set(text) - {b'n/tresynch', b'49 0 49'} == {line for line in text
                                                        if line.startswith(b'v/t')}
    assert 0.044 <= notice_times[-1] - notice_times[0] <= 0.05    # for resync_duration
    last = text.index(b'49 0 49', len(text) - 1 - text[::-1].index(b'49 0 49'))
    after = [LineParser().parse(line) for line in text[last + 1:]]
    assert all(isinstance(p, VelocityLine) for p in after)       # no invented end line
    speeds = [p.vx for p in after]
    assert speeds[0] < 0.018                                      # covers part of the re-sync
    assert np.mean(speeds[2:]) == pytest.approx(0.020, rel=0.02)
    assert not emulator.resyncing and emulator.resync_notices == len(notice_times)


def test_the_session_publishes_no_valid_sample_during_an_emulated_resync() -> None:
    emulator = FirmwareEmulator(EmulatorParams(default_radius=0.0243, seed=5),
                                ConstantTwist(0.020, 0.0, 0.0))
    session = SensorSession(expected_name='sensor_1')
    session.mark_initialised(calibration_source='t', calibration_uploaded=True, speed_term='abs')
    emulator.advance(0.1)
    emulator.set_chip_blind(3)
    lines = _timed_output(emulator, 0.3, start=0.1)    # blind for 0.2 s
    emulator.set_chip_blind(3, False)
    lines += _timed_output(emulator, 0.45, start=0.3)
    sequence = []                       # ('r' | 'v', sample) in arrival order
    for t, line in lines:
        sample = session.handle_line(t, line)
        if line.startswith(b'n/tresynch'):
            sequence.append(('r', None))
        elif sample is not None:
            sequence.append(('v', sample))
    first_notice = next(i for i, (kind, _) in enumerate(sequence) if kind == 'r')
    last_notice = max(i for i, (kind, _) in enumerate(sequence) if kind == 'r')
    window = [s for kind, s in sequence[first_notice:last_notice] if kind == 'v']
    assert len(window) > 20 and not any(s.valid for s in window)
    after = [s for kind, s in sequence[last_notice:] if kind == 'v']
    assert [s.valid for s in after[:3]] == [False, False, True]   # covers, clean, measures
    assert all(s.valid for s in after[2:]) and after[-1].vx == pytest.approx(0.020, rel=0.25)
    assert session.reports(after[-1].stamp)['chips'].level is Level.OK


def test_every_command_line_option_has_a_help_text_with_its_default(capsys) -> None:
    from slip_velocity_sensor.core import emulator as emulator_module
    with pytest.raises(SystemExit):
        emulator_module._parse_args(['--help'])
    help_text = capsys.readouterr().out
    options = re.findall(r'^  (--[a-z-]+)', help_text, flags=re.MULTILINE)
    assert len(options) >= 20
    blocks = re.split(r'\n  (?=--)', help_text.split('options:')[1])
    for block in blocks[1:]:
        assert '(default:' in ' '.join(block.split()), block
    args = emulator_module._parse_args([])
    assert 1.0 / args.rate == pytest.approx(0.007, rel=1e-3)
    assert args.jitter == pytest.approx(1 / 7, abs=1e-4)
