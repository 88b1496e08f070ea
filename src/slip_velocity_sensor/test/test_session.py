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
    """dt <= 0 is skipped, but the next line covers the whole interval (no drift)."""
    s = _session()
    t = 0.0
    for burst in range(200):
        t += 2 * 0.00833
        for _ in range(2):  # two lines per USB read: same stamp
            s.handle_line(t, _line(10.0, 0.0, 0.0))
    d = s.diagnostics(t)
    assert d.dt_skipped == 200
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
    assert s.diagnostics(t).dt_skipped == 34
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


def test_resync_invalidates_until_the_product_ids_arrive() -> None:
    s = _session(resync_timeout=0.2)
    assert s.handle_line(0.00, _line(1.0, 0.0, 0.0)).valid
    s.handle_line(0.01, b'n/tresynch')
    assert not s.handle_line(0.02, _line(0.0, 0.0, 0.0)).valid
    assert s.diagnostics(0.02).resync_active
    s.handle_line(0.06, b'49/t49/t49')
    assert s.handle_line(0.07, _line(1.0, 0.0, 0.0)).valid
    s.handle_line(0.10, b'n/tresynch')                  # end line lost: timeout
    assert not s.handle_line(0.20, _line(1.0, 0.0, 0.0)).valid
    assert s.handle_line(0.31, _line(1.0, 0.0, 0.0)).valid
    assert s.diagnostics(0.31).counters.resync == 2


def test_product_id_mismatch_is_an_error_in_diagnostics() -> None:
    s = _session()
    s.handle_line(0.0, b'n/tresynch')
    s.handle_line(0.05, b'49/t0/t49')
    report = s.reports(0.05)['chips']
    assert report.level is Level.ERROR and '0x00' in dict(report.values)['product_ids']


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
    for _ in range(240):
        t += 1.0 / 120.0
        s.handle_line(t, _line(1.0, 0.0, 0.0))
    assert s.rate_hz(t) == pytest.approx(120.0, abs=1.5)
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
    assert s.reports(2.0)['rate'].level is Level.WARN            # 60 Hz against 120 Hz
    s.update_params(SessionParams(expected_rate=60.0, stale_after=0.5))
    assert s.reports(2.0)['rate'].level is Level.OK
    assert not s.is_stale(2.4)
    s.chip_mode_sent(2, 2.0)
    assert s.chip_mode == -1 and s.target_chip_mode == 2
