# SPDX-License-Identifier: Apache-2.0
"""SensorSession: validity, chip modes, pose integration with acquisition stamps, diagnostics."""
from __future__ import annotations

import math

import numpy as np
import pytest

from slip_cell_common.core.monitors import Level
from slip_velocity_sensor.core import protocol
from slip_velocity_sensor.core.session import SensorSession, SessionParams

PORT = '/dev/serial/by-id/usb-Silicon_Labs_CP2102N-if00-port0'


def _line(vx_mm_s: float, vy_mm_s: float, omega: float) -> bytes:
    return protocol.format_velocity_line(vx_mm_s, vy_mm_s, omega).rstrip(b'\r\n')


def _session(**kw: float) -> SensorSession:
    s = SensorSession(SessionParams(**kw), port=PORT, expected_name='sensor_1')
    s.mark_initialised(calibration_source='file:cal.yaml', calibration_uploaded=True,
                       speed_term='zero')
    return s


def test_fused_lines_become_valid_si_samples() -> None:
    s = _session()
    sample = s.handle_line(1.0, b'v/t12.3456/t-0.8000/t0.0131\r')
    assert sample is not None and sample.valid and sample.chip_mode == 0
    assert (sample.vx, sample.vy, sample.omega) == pytest.approx((0.0123456, -0.0008, 0.0131))
    assert sample.stamp == 1.0 and math.isnan(sample.chip_vx) and sample.excluded_chip == -1
    assert s.handle_line(1.01, b'n/tsensor_1') is None


def test_samples_are_invalid_until_the_session_is_initialised() -> None:
    s = SensorSession(port=PORT, expected_name='sensor_1')
    sample = s.handle_line(1.0, _line(1.0, 0.0, 0.0))
    assert sample is not None and not sample.valid and math.isnan(sample.vx)
    assert s.needs_reinitialisation and s.is_stale(1.0)


def test_pose_integrates_with_jittered_acquisition_stamps() -> None:
    rng = np.random.default_rng(0)
    s = _session()
    stamps = 10.0 + np.cumsum(rng.uniform(0.004, 0.0125, 600))
    for t in stamps:
        s.handle_line(float(t), _line(20.0, -10.0, 0.5))
    sample = s.latest
    elapsed = stamps[-1] - stamps[0]
    assert sample.x == pytest.approx(0.020 * elapsed, rel=1e-12)
    assert sample.y == pytest.approx(-0.010 * elapsed, rel=1e-12)
    assert sample.theta == pytest.approx(0.5 * elapsed, rel=1e-12)


def test_lines_sharing_one_usb_read_stamp_lose_no_time() -> None:
    """Two lines per USB read (one stamp): the second covers its own period, taken from the
    time the first one claimed, so the total is the stamps' span (no drift, nothing skipped
    after the first read)."""
    s = _session()
    t = 0.0
    for _burst in range(200):
        t += 2 * 0.00833
        for _ in range(2):  # two lines per USB read: same stamp
            s.handle_line(t, _line(10.0, 0.0, 0.0))
    d = s.diagnostics(t)
    assert d.dt_skipped == 1          # the second line of the anchoring read: no time yet
    assert s.latest.x == pytest.approx(0.010 * (t - 2 * 0.00833), rel=1e-12)


def test_slightly_out_of_order_stamps_neither_gain_nor_lose_time() -> None:
    s = _session()
    t0 = t = 1.0
    s.handle_line(t, _line(10.0, 0.0, 0.0))
    for k in range(100):
        t += 0.00833
        s.handle_line(t, _line(10.0, 0.0, 0.0))
        if k % 3 == 0:  # a stamp 1 ms earlier than the previous one (thread scheduling)
            s.handle_line(t - 0.001, _line(10.0, 0.0, 0.0))
    assert s.diagnostics(t).dt_skipped == 0   # each got time from its read, none gained
    assert s.latest.x == pytest.approx(0.010 * (t - t0), rel=1e-12)


def test_gaps_are_capped_and_a_backwards_clock_re_anchors() -> None:
    s = _session(max_integration_dt=0.05)
    s.handle_line(1.0, _line(10.0, 0.0, 0.0))
    s.handle_line(1.5, _line(10.0, 0.0, 0.0))          # 0.5 s gap: lost lines / stall
    assert s.latest.x == pytest.approx(0.010 * 0.05)
    s.handle_line(0.2, _line(10.0, 0.0, 0.0))          # clock went back (bag loop, sim reset)
    s.handle_line(0.21, _line(10.0, 0.0, 0.0))
    d = s.diagnostics(0.21)
    assert d.dt_capped == 1 and d.clock_jumps == 1
    assert s.latest.x == pytest.approx(0.010 * 0.06)


def test_single_chip_mode_marks_the_twist_and_stale_omega_invalid() -> None:
    s = _session(chip_mode_settle=0.025)
    t = 0.0
    for _ in range(10):
        t += 0.00833
        s.handle_line(t, _line(5.0, 0.0, 0.2))
    x_before = s.latest.x
    s.chip_mode_sent(2, t)
    t += 0.00833
    settling = s.handle_line(t, _line(5.0, 0.0, 0.2))
    assert not settling.valid and settling.chip_mode == -1 and math.isnan(settling.chip_vx)
    samples = []
    for _ in range(20):
        t += 0.00833
        samples.append(s.handle_line(t, _line(7.5, -1.25, 0.2)))
    last = samples[-1]
    assert last.chip_mode == 2 and not last.valid
    assert math.isnan(last.omega) and math.isnan(last.vx) and math.isnan(last.vy)
    assert (last.chip_vx, last.chip_vy) == pytest.approx((0.0075, -0.00125))
    assert last.x == x_before                          # no integration of chip-frame values
    assert s.reports(t)['chips'].level is Level.WARN
    s.chip_mode_sent(0, t)
    for _ in range(10):
        t += 0.00833
        s.handle_line(t, _line(5.0, 0.0, 0.2))
    assert s.latest.valid and s.latest.chip_mode == 0
    # Integration restarts from the first valid line: no jump over the single-chip period.
    assert s.latest.x - x_before == pytest.approx(0.005 * 0.00833 * 6, rel=1e-9)


def _resync_pass(s: SensorSession, t: float, ids: bytes = b'0 49 49') -> None:
    """What the firmware prints on every sensor pass while a chip does not answer."""
    assert s.handle_line(t, b'n/tresynch\r') is None
    assert s.handle_line(t, ids + b'\r') is None


def test_resync_keeps_samples_invalid_until_a_line_follows_a_clean_pass() -> None:
    """The firmware prints the notice and the IDs *before* re-syncing, repeats them every pass
    while the chip is out and meanwhile sends zero lines; nothing marks the end."""
    s = _session()
    period = 0.007
    t = 1.0
    assert s.handle_line(t, _line(20.0, 0.0, 0.0)).valid
    published = []
    for _ in range(70):                       # a blind chip for about 0.5 s
        t += period
        _resync_pass(s, t - 0.003)
        published.append(s.handle_line(t, _line(0.0, 0.0, 0.0)))
    assert not any(p.valid for p in published)    # the zeros are not "no slip"
    assert s.diagnostics(t).resync_active and s.diagnostics(t).resyncs == 1
    # The chip answers again: no more notices. The first line covers the tail of the last
    # re-sync (reads low), so only the line after a clean period is a measurement.
    t += period
    first = s.handle_line(t, _line(7.0, 0.0, 0.0))
    t += period
    second = s.handle_line(t, _line(20.0, 0.0, 0.0))
    assert not first.valid and second.valid and second.vx == pytest.approx(0.020)
    d = s.diagnostics(t)
    assert not d.resync_active and d.counters.resync == 70 and d.resyncs == 1


def test_a_transient_resync_invalidates_exactly_the_lines_it_touches() -> None:
    s = _session()
    t = 0.0
    kinds = ['v', 'v', 'r', 'v', 'r', 'v', 'v', 'v', 'v', 'r', 'v', 'v', 'v']
    validity = []
    for kind in kinds:
        t += 0.007
        if kind == 'r':
            _resync_pass(s, t)
        else:
            validity.append(s.handle_line(t, _line(20.0, 0.0, 0.0)).valid)
    # v v | r v(inv) | r v(inv) v(inv: first clean) v v | r v(inv) v(inv) v
    assert validity == [True, True, False, False, False, True, True, False, False, True]


def test_the_product_id_line_does_not_end_a_resync() -> None:
    """The old emulator's invented end line must not be taken as 're-sync done'."""
    s = _session()
    t = 0.0
    s.handle_line(t, _line(1.0, 0.0, 0.0))
    _resync_pass(s, 0.005)
    s.handle_line(0.006, b'49 49 49')          # even "healthy" IDs: still a notice pair
    assert not s.handle_line(0.007, _line(0.0, 0.0, 0.0)).valid
    _resync_pass(s, 0.010)
    assert not s.handle_line(0.014, _line(0.0, 0.0, 0.0)).valid
    assert s.diagnostics(0.014).resync_active


def test_chips_diagnostics_name_the_chip_and_clear_when_the_resyncs_stop() -> None:
    s = _session(resync_timeout=0.2)
    t = 0.0
    s.handle_line(t, _line(1.0, 0.0, 0.0))
    for _ in range(10):
        t += 0.007
        _resync_pass(s, t - 0.002, b'-1 49 49')
        s.handle_line(t, _line(0.0, 0.0, 0.0))
    report = s.reports(t)['chips']
    assert report.level is Level.WARN and 'chip 1' in report.message
    assert 'pulled high' in report.message
    assert dict(report.values)['product_ids'] == '-1 49 49'
    for _ in range(30):                        # the chip stays out: longer than the timeout
        t += 0.007
        _resync_pass(s, t - 0.002, b'49 0 49')
        s.handle_line(t, _line(0.0, 0.0, 0.0))
    report = s.reports(t)['chips']
    assert report.level is Level.ERROR and 'chip 2 reads 0' in report.message
    for _ in range(3):                         # the chip answers again
        t += 0.007
        s.handle_line(t, _line(1.0, 0.0, 0.0))
    report = s.reports(t)['chips']
    assert report.level is Level.OK, report.message      # no permanent error
    values = dict(report.values)
    assert values['resyncs'] == '1' and values['resync_notices'] == '40'
    assert values['resync_active'] == 'False'
    reports = s.reports(t)
    assert reports['link'].level is Level.OK and reports['calibration'].level is Level.OK


def test_bursts_of_lines_with_one_stamp_integrate_every_line_over_its_period() -> None:
    """A stalled reader returns the queued lines together with one stamp; each line still
    stands for one firmware period, so the pose is the sum of v_i · period (nothing lost, with
    any velocities), where the old integration capped the first step and skipped the rest."""
    rng = np.random.default_rng(17)
    s = _session(expected_rate=1.0 / 0.007, max_integration_dt=0.05)
    period = 0.007
    v_mm_s = rng.uniform(-30.0, 30.0, 2000)
    v_mm_s = np.round(v_mm_s, 4)
    t = 5.0
    s.handle_line(t, _line(v_mm_s[0], 0.0, 0.0))   # anchors: integration starts here
    i = 1
    sizes = []
    while i < len(v_mm_s):
        burst = int(rng.choice([1, 1, 1, 2, 3, rng.integers(5, 45)]))  # up to 0.3 s stalls
        burst = min(burst, len(v_mm_s) - i)
        t += burst * period                        # read when the last queued line arrived
        for v in v_mm_s[i:i + burst]:
            s.handle_line(t, _line(v, 0.0, 0.0))
        sizes.append(burst)
        i += burst
    expected = float(np.sum(v_mm_s[1:])) / 1000.0 * period
    assert max(sizes) * period > 0.2                # stalls far beyond max_integration_dt
    assert s.latest.x == pytest.approx(expected, rel=1e-9, abs=1e-12)
    assert s.diagnostics(t).dt_skipped == 0


def test_stalled_reader_loses_no_path_against_the_firmware_emulator() -> None:
    """The issue's case: a 30 mm path at 20 mm/s, lines from the emulated firmware (6–8 ms
    periods), read by a host that stalls (lines queue, one stamp per read). The integrated
    pose matches the path; capping and skipping lost 10 % of it."""
    from slip_velocity_sensor.core.emulator import ConstantTwist, EmulatorParams, \
        FirmwareEmulator
    rng = np.random.default_rng(4)
    emulator = FirmwareEmulator(EmulatorParams(default_radius=0.0243, seed=3),
                                ConstantTwist(0.020, 0.0, 0.0))
    s = _session()
    splitter = protocol.LineSplitter()
    t = 0.0
    samples = []
    while t < 1.6:
        t += 0.002 if rng.random() < 0.8 else float(rng.uniform(0.03, 0.25))   # stalls
        stamp = t + float(rng.uniform(0.0, 0.001))                     # USB latency
        for line, _ in splitter.feed(emulator.advance(t)):
            sample = s.handle_line(stamp, line)
            if sample is not None:
                samples.append(sample)
    first, last = samples[0], samples[-1]
    # The device's own account: the counts it reported between the two lines.
    true_path = 0.020 * (last.stamp - first.stamp)
    assert last.x - first.x == pytest.approx(true_path, rel=0.02)
    assert last.x - first.x > 0.029


def test_rate_window_fits_the_firmware_period_of_6_to_8_ms() -> None:
    """vTaskDelay(6) plus printing and scheduling: 125–167 Hz is a healthy sensor."""
    rng = np.random.default_rng(5)
    for low, high in ((0.006, 0.008), (0.006, 0.0061), (0.0079, 0.008)):
        s = _session()
        t = 0.0
        levels = []
        while t < 4.0:
            t += float(rng.uniform(low, high))
            s.handle_line(t, _line(1.0, 0.0, 0.0))
            if t > 1.0:
                levels.append(s.reports(t)['rate'].level)
        assert set(levels) == {Level.OK}, (low, high)
    s = _session()
    for k in range(360):                             # 120 Hz: the firmware cannot be that slow
        s.handle_line(k / 120.0, _line(1.0, 0.0, 0.0))
    assert s.reports(3.0)['rate'].level is Level.WARN


def test_device_restart_invalidates_and_requests_reinitialisation() -> None:
    s = _session()
    s.handle_line(0.0, _line(1.0, 0.0, 0.0))
    s.handle_line(0.1, b'ESP-ROM:esp32s3-20210327')
    assert s.needs_reinitialisation and not s.handle_line(0.5, _line(1.0, 0.0, 0.0)).valid
    link = s.reports(0.5)['link']
    assert link.level is Level.ERROR and 'restarted' in link.message and PORT in link.message
    s.mark_initialised(calibration_source='x', calibration_uploaded=True, speed_term='zero')
    assert s.handle_line(0.6, _line(1.0, 0.0, 0.0)).valid


def test_a_different_name_on_the_port_invalidates_the_data() -> None:
    s = _session()
    s.handle_line(0.0, b'n/tsensor_2')
    assert not s.handle_line(0.01, _line(1.0, 0.0, 0.0)).valid
    assert s.diagnostics(0.01).name_conflicts == 1
    assert s.reports(0.01)['link'].level is Level.ERROR


def test_staleness_rate_and_age_use_acquisition_stamps() -> None:
    s = _session(stale_after=0.05)
    t = 0.0
    for _ in range(290):
        t += 1.0 / 143.0
        s.handle_line(t, _line(1.0, 0.0, 0.0))
    assert s.rate_hz(t) == pytest.approx(143.0, abs=1.5)
    assert not s.is_stale(t + 0.04) and s.is_stale(t + 0.06)
    assert s.age(t + 0.03) == pytest.approx(0.03)
    assert s.reports(t)['rate'].level is Level.OK
    assert s.reports(t + 2.0)['rate'].level is Level.ERROR   # no data in the window


def test_reset_pose_and_reset() -> None:
    s = _session()
    for k in range(10):
        s.handle_line(k * 0.01, _line(10.0, 10.0, 1.0))
    s.reset_pose()
    s.handle_line(0.10, _line(10.0, 10.0, 1.0))
    assert s.latest.x == pytest.approx(0.010 * 0.01)
    s.reset()
    assert s.latest is None and s.is_stale(0.10)
    s.handle_line(0.05, _line(10.0, 10.0, 1.0))
    assert s.latest.x == 0.0 and s.latest.valid


def test_link_loss_is_an_error_naming_the_port_and_calibration_is_reported() -> None:
    s = _session()
    assert s.reports(0.0)['calibration'].level is Level.OK
    s.link_lost(f'{PORT}: device disconnected or port taken by another process')
    link = s.reports(0.0)['link']
    assert link.level is Level.ERROR and PORT in link.message
    assert not s.handle_line(0.1, _line(1.0, 0.0, 0.0)).valid
    identity = SensorSession(port=PORT)
    identity.mark_initialised(calibration_source='parameters (identity: uncalibrated)',
                              calibration_uploaded=True, speed_term='zero')
    assert identity.reports(0.0)['calibration'].level is Level.WARN


def test_byte_feed_with_garbage_counts_every_line() -> None:
    rng = np.random.default_rng(3)
    s = _session()
    good = _line(1.0, 2.0, 0.01) + b'\r\n'
    data = b''.join(good if rng.random() < 0.7 else bytes(rng.integers(0, 256, 20,
                                                                        dtype=np.uint8))
                    for _ in range(5000))
    samples = []
    for i in range(0, len(data), 37):
        samples += s.feed(i * 1e-4, data[i:i + 37])
    c = s.diagnostics(1.0).counters
    assert len(samples) == c.velocity >= 2000  # garbage without a newline eats the next line
    assert c.total == data.count(b'\n')


def test_stale_stream_yields_one_invalid_marker_per_outage() -> None:
    s = _session(stale_after=0.05)
    for k in range(5):
        s.handle_line(1.0 + k / 120, _line(10.0, 0.0, 0.0))
    last = s.latest
    assert s.stale_marker(last.stamp + 0.04) is None            # still fresh
    marker = s.stale_marker(last.stamp + 0.06)
    assert marker is not None and not marker.valid and marker.stamp == last.stamp + 0.06
    assert math.isnan(marker.vx) and marker.x == last.x          # pose kept, no old twist
    assert s.stale_marker(last.stamp + 1.0) is None             # once per outage
    s.handle_line(3.0, _line(10.0, 0.0, 0.0))
    assert s.stale_marker(3.1) is not None                      # a new outage, a new marker


def test_a_multi_line_boot_banner_is_one_restart() -> None:
    s = _session()
    s.handle_line(1.0, b'ESP-ROM:esp32s3-20210327')
    s.handle_line(1.0, b'rst:0x1 (POWERON),boot:0x8 (SPI_FAST_FLASH_BOOT)')
    s.handle_line(1.3, _line(0.0, 0.0, 0.0))
    s.handle_line(2.0, b'ESP-ROM:esp32s3-20210327')
    assert s.diagnostics(2.0).device_restarts == 2


def test_runtime_parameter_update_keeps_the_history() -> None:
    s = _session()
    for k in range(60):
        s.handle_line(1.0 + k / 60, _line(1.0, 0.0, 0.0))
    assert s.reports(2.0)['rate'].level is Level.WARN            # 60 Hz against 146 Hz
    s.update_params(SessionParams(expected_rate=60.0, stale_after=0.5))
    assert s.reports(2.0)['rate'].level is Level.OK
    assert not s.is_stale(2.4)
    s.chip_mode_sent(2, 2.0)
    assert s.chip_mode == -1 and s.target_chip_mode == 2
