# SPDX-License-Identifier: Apache-2.0
"""`SensorDriver` (the node's ROS-free core) against the firmware emulator on a pseudo-terminal:
configure-time failures, calibration upload, spaced chip-mode commands, stale markers, and
re-initialisation after a board restart and after the port vanished and came back.

Real time (the emulator plays the device), every wait bounded; no ROS needed.
"""
from __future__ import annotations

import math
import os
import threading
import time
from dataclasses import replace
from pathlib import Path
from collections.abc import Callable, Iterator

import pytest

from slip_cell_common.core.monitors import Level
from slip_cell_common.core.param_schema import from_flat
from slip_velocity_sensor.core import calibration as cal_mod
from slip_velocity_sensor.core.driver import DriverError, SensorDriver
from slip_velocity_sensor.core.emulator import (ConstantTwist, EmulatorParams, FirmwareEmulator,
                                                PtyEmulator)
from slip_velocity_sensor.core.params import VelocitySensorParams
from slip_velocity_sensor.core.session import Sample
from slip_velocity_sensor.core.starter import DriverStarter

CONFIG = Path(__file__).resolve().parents[1] / 'config'
TRUTH = cal_mod.load_calibration(CONFIG / 'calibration_sensor_1.yaml')
TWIST = (0.020, -0.010, 0.30)


def _wait(predicate: Callable[[], bool], timeout: float) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.005)
    return predicate()


class Collector:
    """Thread-safe sample sink."""

    def __init__(self) -> None:
        self.samples: list[Sample] = []
        self.events: list[tuple[str, str]] = []
        self._lock = threading.Lock()

    def __call__(self, sample: Sample) -> None:
        with self._lock:
            self.samples.append(sample)

    def event(self, level: str, message: str) -> None:
        self.events.append((level, message))

    def valid_since(self, t: float) -> list[Sample]:
        with self._lock:
            return [s for s in self.samples if s.valid and s.stamp > t]


@pytest.fixture
def ptys() -> Iterator[Callable[..., PtyEmulator]]:
    made: list[PtyEmulator] = []

    def make(name: str = 'sensor_1', motion=ConstantTwist(*TWIST),
             **kw) -> PtyEmulator:
        params = EmulatorParams(name=name, truth=TRUTH, firmware_speed_term='abs', **kw)
        pty = PtyEmulator(FirmwareEmulator(params, motion)).start()
        made.append(pty)
        return pty
    yield make
    for pty in made:
        pty.stop()


@pytest.fixture
def drivers(tmp_path: Path) -> Iterator[Callable[..., tuple[SensorDriver, Collector]]]:
    made: list[SensorDriver] = []

    def make(port: str, **flat: object) -> tuple[SensorDriver, Collector]:
        values = {'port': port, 'lock_dir': str(tmp_path), 'calibration.speed_term': 'abs',
                  'handshake.timeout': 0.5, 'handshake.retries': 2,
                  'reconnect.initial_delay': 0.1, 'reconnect.max_delay': 0.4, **flat}
        params = from_flat(VelocitySensorParams, values)
        sink = Collector()
        driver = SensorDriver(params, TRUTH, clock=time.monotonic, on_sample=sink,
                              on_event=sink.event)
        made.append(driver)
        return driver, sink
    yield make
    for driver in made:
        driver.close()


def test_connect_uploads_the_calibration_and_streams_si_samples(ptys, drivers) -> None:
    pty = ptys()
    driver, sink = drivers(pty.port)
    result = driver.connect()
    assert result.name == 'sensor_1' and result.init_commands == 14
    device = pty.emulator.device_calibration()
    assert device.radius == pytest.approx(TRUTH.radius)
    for chip in (1, 2, 3):
        for axis in ('x', 'y'):
            assert device.axis(chip, axis).b == pytest.approx(TRUTH.axis(chip, axis).b)
            assert device.axis(chip, axis).a == pytest.approx(TRUTH.axis(chip, axis).a)
    t0 = time.monotonic()
    assert _wait(lambda: len(sink.valid_since(t0)) >= 150, 3.0)   # > the 1 s rate window
    valid = sink.valid_since(t0)
    mean = [sum(getattr(s, k) for s in valid) / len(valid) for k in ('vx', 'vy', 'omega')]
    assert mean == pytest.approx(TWIST, rel=0.03)
    reports = driver.reports(time.monotonic())
    assert {k: r.level for k, r in reports.items()} == dict.fromkeys(reports, Level.OK), \
        {k: r.message for k, r in reports.items()}
    assert ('port', pty.port) in reports['link'].values


def test_chip_mode_commands_are_spaced_and_invalidate_the_twist(ptys, drivers) -> None:
    pty = ptys()
    driver, sink = drivers(pty.port, command_spacing=0.02)
    driver.connect()
    t0 = time.monotonic()
    for mode in (1, 2):
        driver.set_chip_mode(mode)
    assert _wait(lambda: any(s.chip_mode == 2 for s in sink.samples if s.stamp > t0), 2.0)
    sent = [t for t, cmd in pty.emulator.received if cmd in (b'c1', b'c2')]
    assert len(sent) == 2 and sent[1] - sent[0] >= 0.018   # pty time, spacing 20 ms
    chip = [s for s in sink.samples if s.chip_mode == 2][-1]
    assert not chip.valid and math.isnan(chip.omega) and math.isfinite(chip.chip_vx)
    assert driver.reports(time.monotonic())['chips'].level is Level.WARN
    with pytest.raises(ValueError, match='0..3'):
        driver.set_chip_mode(4)
    driver.set_chip_mode(0)
    t1 = time.monotonic() + 0.05
    assert _wait(lambda: len(sink.valid_since(t1)) > 5, 2.0)


def test_configure_failures_name_the_port_and_leave_nothing_open(ptys, drivers,
                                                                 tmp_path: Path) -> None:
    missing = str(tmp_path / 'ttyUSB_missing')
    driver, _ = drivers(missing)
    with pytest.raises(DriverError, match='ttyUSB_missing'):
        driver.connect()

    silent = ptys()
    silent.emulator.set_silent(True)
    driver, _ = drivers(silent.port, **{'handshake.timeout': 0.2})
    with pytest.raises(DriverError) as err:
        driver.connect()
    assert silent.port in str(err.value) and 'no answer' in str(err.value)
    assert not driver.status().connected
    driver, _ = drivers(silent.port)           # the port was released: it opens again
    silent.emulator.set_silent(False)
    driver.connect()
    driver.close()

    wrong = ptys(name='sensor_2')
    driver, _ = drivers(wrong.port)
    with pytest.raises(DriverError, match="answered 'sensor_2', expected 'sensor_1'"):
        driver.connect()


def test_a_second_board_with_the_same_name_is_refused(ptys, drivers) -> None:
    first, second = ptys(), ptys()
    driver_1, _ = drivers(first.port)
    driver_1.connect()
    driver_2, _ = drivers(second.port)
    with pytest.raises(DriverError) as err:
        driver_2.connect()
    assert first.port in str(err.value) and second.port in str(err.value)
    assert not driver_2.status().connected
    driver_1.close()                          # the claim is released with the port
    driver_3, _ = drivers(second.port)
    driver_3.connect()


def test_board_restart_is_detected_and_the_calibration_uploaded_again(ptys, drivers) -> None:
    pty = ptys(boot_duration=0.05)
    driver, sink = drivers(pty.port)
    driver.connect()
    driver.set_chip_mode(3)
    pty.emulator.restart()                    # boot banner; calibration and mode lost
    assert _wait(lambda: driver.status().reinit_attempts >= 1 and
                 not driver.session.needs_reinitialisation, 4.0)
    assert pty.emulator.device_calibration().axis(1, 'x').b == pytest.approx(
        TRUTH.axis(1, 'x').b)
    assert pty.emulator.chip_mode == 3        # the requested mode is restored too
    assert driver.session.diagnostics(time.monotonic()).device_restarts == 1
    assert any('re-initialised' in m for _, m in sink.events)


def test_unplugged_port_reconnects_when_it_comes_back(ptys, drivers, tmp_path: Path) -> None:
    link = tmp_path / 'ttyVEL1'                # a stable by-id-like path to a changing pty
    first = ptys()
    os.symlink(first.port, link)
    driver, sink = drivers(str(link))
    driver.connect()
    assert _wait(lambda: len(sink.valid_since(0.0)) > 10, 2.0)
    first.vanish()
    assert _wait(lambda: driver.status().losses == 1, 2.0)
    report = driver.reports(time.monotonic())['link']
    assert report.level is Level.ERROR and str(link) in report.message
    assert driver.stale_marker(time.monotonic() + 1.0) is not None   # state goes invalid once
    assert driver.stale_marker(time.monotonic() + 1.0) is None
    assert _wait(lambda: driver.status().connect_failures >= 1, 2.0)  # back-off retries
    second = ptys()
    tmp = tmp_path / 'tmp_link'
    os.symlink(second.port, tmp)
    os.replace(tmp, link)                     # the adapter re-enumerated at the same path
    t_back = time.monotonic()
    assert _wait(lambda: len(sink.valid_since(t_back)) > 10, 5.0)
    st = driver.status()
    assert st.reconnects >= 1 and st.reinit_attempts >= 1 and st.initialised
    assert second.emulator.device_calibration().axis(3, 'y').b == pytest.approx(
        TRUTH.axis(3, 'y').b)
    assert driver.reports(time.monotonic())['link'].level is Level.OK


def test_runtime_parameter_updates(ptys, drivers) -> None:
    pty = ptys()
    driver, _ = drivers(pty.port)
    driver.connect()
    params = driver.params
    deferred = driver.update_params(
        replace(params, session=replace(params.session, stale_after=0.2), radius=0.03))
    assert deferred == ('radius',)
    assert driver.session.params.stale_after == 0.2


# --------------------------------------------------------------------------- start retries

@pytest.fixture
def starter(tmp_path: Path) -> Iterator[Callable[..., tuple[DriverStarter, Collector, list]]]:
    """Factory: a `DriverStarter` for a port, with its sample/event sink and started drivers."""
    made: list[tuple[DriverStarter, list[SensorDriver]]] = []

    def make(port: str, **flat: object) -> tuple[DriverStarter, Collector, list]:
        values = {'port': port, 'lock_dir': str(tmp_path), 'calibration.speed_term': 'abs',
                  'handshake.timeout': 0.2, 'handshake.retries': 1,
                  'reconnect.initial_delay': 0.1, 'reconnect.max_delay': 0.4, **flat}
        params = from_flat(VelocitySensorParams, values)
        sink = Collector()
        started: list[SensorDriver] = []

        def make_driver() -> SensorDriver:
            return SensorDriver(params, TRUTH, clock=time.monotonic, on_sample=sink,
                                on_event=sink.event)
        st = DriverStarter(port, make_driver, params.reconnect,
                           on_started=lambda driver, result: started.append(driver),
                           on_event=sink.event)
        made.append((st, started))
        return st, sink, started
    yield make
    for st, started in made:
        st.stop()
        for driver in started:
            driver.close()


def test_a_failed_start_is_retried_with_back_off_until_the_sensor_answers(ptys,
                                                                          starter) -> None:
    pty = ptys()
    pty.emulator.set_silent(True)                   # powered but not answering yet
    st, sink, started = starter(pty.port)
    st.start()
    assert _wait(lambda: sum(level == 'error' for level, _ in sink.events) >= 3, 5.0)
    failures = [m for level, m in sink.events if level == 'error']
    assert all(pty.port in m and 'no answer' in m for m in failures)
    delays = [float(m.rsplit('retrying in ', 1)[1].split(' s')[0]) for m in failures]
    assert delays[:3] == [0.1, 0.2, 0.4]            # exponential back-off, capped
    pty.emulator.set_silent(False)
    assert _wait(lambda: bool(started), 5.0), sink.events
    status = st.status()
    assert status.started and not status.running and status.last_error == ''
    assert any(level == 'info' and 'started at attempt' in m for level, m in sink.events)
    t0 = time.monotonic()
    assert _wait(lambda: len(sink.valid_since(t0)) > 20, 3.0)
    assert started[0].reports(time.monotonic())['link'].level is Level.OK


def test_a_port_that_appears_later_is_started(ptys, starter, tmp_path: Path) -> None:
    link = tmp_path / 'ttyVEL_later'
    st, sink, started = starter(str(link))
    st.start()
    assert _wait(lambda: st.status().attempts >= 2, 3.0)
    assert 'ttyVEL_later' in st.status().last_error and st.status().running
    pty = ptys()
    os.symlink(pty.port, link)                      # the adapter is plugged in
    assert _wait(lambda: bool(started), 5.0), sink.events
    t0 = time.monotonic()
    assert _wait(lambda: len(sink.valid_since(t0)) > 20, 3.0)


def test_a_wrong_name_is_not_retried_and_stop_ends_the_attempts(ptys, starter) -> None:
    wrong = ptys(name='sensor_2')
    st, sink, started = starter(wrong.port)
    st.start()
    assert _wait(lambda: st.status().gave_up, 3.0)
    assert st.status().attempts == 1 and not started and not st.status().running
    assert "answered 'sensor_2'" in st.status().last_error

    silent = ptys()
    silent.emulator.set_silent(True)
    st, sink, started = starter(silent.port, **{'handshake.timeout': 30.0})
    st.start()
    assert _wait(lambda: st.status().attempts == 1, 2.0)   # an attempt is waiting for "n"
    st.stop(timeout_s=5.0)             # deactivate: the 30 s attempt is aborted, not awaited
    assert not st.status().running
    silent.emulator.set_silent(False)
    time.sleep(0.3)
    assert not started and st.status().attempts == 1


def test_a_blind_chip_invalidates_samples_and_the_chips_report_recovers(ptys, drivers) -> None:
    pty = ptys(resync_chip=1)
    driver, sink = drivers(pty.port, resync_timeout=0.1)
    driver.connect()
    assert _wait(lambda: len(sink.valid_since(0.0)) > 20, 3.0)
    n_before = len(sink.samples)
    pty.emulator.set_chip_blind(1)
    assert _wait(lambda: driver.reports(time.monotonic())['chips'].level is Level.ERROR, 3.0)
    report = driver.reports(time.monotonic())['chips']
    assert 'chip 1 reads 0' in report.message and 'not answering' in report.message
    time.sleep(0.2)
    n_blind = len(sink.samples)          # every sample so far since the re-sync began ...
    pty.emulator.set_chip_blind(1, False)
    t_back = time.monotonic()
    assert _wait(lambda: len(sink.valid_since(t_back)) > 20, 3.0)
    first_invalid = next(i for i in range(n_before, n_blind) if not sink.samples[i].valid)
    blind = sink.samples[first_invalid:n_blind]
    assert len(blind) > 20 and not any(s.valid for s in blind)   # ... is invalid
    assert min(s.vx for s in sink.valid_since(0.0)) > 0.010   # no zero passed as valid
    assert driver.reports(time.monotonic())['chips'].level is Level.OK
