# SPDX-License-Identifier: Apache-2.0
"""End to end over a pseudo-terminal: emulator ↔ pyserial (serial_for_url) ↔ SerialLink ↔
handshake ↔ session, including an unplugged port, a silent port and two boards with one name.

Real time, every wait bounded.
"""
from __future__ import annotations

import queue
import time
from pathlib import Path
from collections.abc import Callable, Iterator

import pytest

from slip_cell_common.core.monitors import Level
from slip_cell_common.core.serial_transport import ReconnectParams, SerialLink
from slip_velocity_sensor.core import calibration as cal_mod
from slip_velocity_sensor.core import protocol
from slip_velocity_sensor.core.emulator import (ConstantTwist, EmulatorParams, FirmwareEmulator,
                                                PtyEmulator)
from slip_velocity_sensor.core.handshake import (Handshake, HandshakeError, HandshakeFailure,
                                                 HandshakeParams, HandshakeRunner)
from slip_velocity_sensor.core.identity import DuplicateSensorNameError, NameClaim, assign_ports
from slip_velocity_sensor.core.session import Sample, SensorSession

CONFIG = Path(__file__).resolve().parents[1] / 'config'
TRUTH = cal_mod.load_calibration(CONFIG / 'calibration_sensor_1.yaml')
LineTarget = Callable[[bytes, bool, float], None]


class Router:
    """Switchable targets for the link callbacks (handshake first, then the session)."""

    def __init__(self) -> None:
        self.on_line_target: LineTarget | None = None
        self.on_lost_target: Callable[[float, str], None] | None = None
        self.losses: queue.Queue[str] = queue.Queue()

    def on_line(self, line: bytes, overflow: bool, t: float) -> None:
        if self.on_line_target is not None:
            self.on_line_target(line, overflow, t)

    def on_lost(self, t: float, reason: str) -> None:
        self.losses.put(reason)
        if self.on_lost_target is not None:
            self.on_lost_target(t, reason)


def _wait_until(predicate: Callable[[], bool], timeout: float) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.005)
    return predicate()


@pytest.fixture
def pty_emulator() -> Iterator[Callable[..., PtyEmulator]]:
    started: list[PtyEmulator] = []

    def make(params: EmulatorParams, motion=None) -> PtyEmulator:
        emulator = PtyEmulator(FirmwareEmulator(params, motion)).start()
        started.append(emulator)
        return emulator
    yield make
    for emulator in started:
        emulator.stop()


@pytest.fixture
def links() -> Iterator[Callable[[str, Router], SerialLink]]:
    made: list[SerialLink] = []

    def make(port: str, router: Router) -> SerialLink:
        link = SerialLink(port, clock=time.monotonic, on_line=router.on_line,
                          on_lost=router.on_lost, read_timeout_s=0.02,
                          reconnect=ReconnectParams(initial_delay=0.2, max_delay=0.5))
        link.open()
        link.start()
        made.append(link)
        return link
    yield make
    for link in made:
        link.close()


def _handshake(link: SerialLink, router: Router, expected: str, port: str,
               params: HandshakeParams, init: list[bytes] | None = None,
               session: SensorSession | None = None):
    hs = Handshake(expected, params, init_commands=init or [], command_spacing=0.010, port=port)
    runner = HandshakeRunner(hs, session.parser if session is not None else None)
    router.on_line_target, router.on_lost_target = runner.on_line, runner.on_lost
    try:
        return runner.run(link.write, time.monotonic)
    finally:
        router.on_line_target = router.on_lost_target = None


def test_emulator_end_to_end_over_a_pty(pty_emulator, links) -> None:
    twist = (0.020, -0.005, 0.25)
    pty = pty_emulator(EmulatorParams(truth=TRUTH, firmware_speed_term='abs',
                                      resync_on_identify=1), ConstantTwist(*twist))
    router = Router()
    link = links(pty.port, router)
    session = SensorSession(port=pty.port, expected_name='sensor_1')
    init = cal_mod.upload_commands(TRUTH, 'abs') + [protocol.chip_mode_command(0)]
    result = _handshake(link, router, 'sensor_1', pty.port, HandshakeParams(timeout=1.0),
                        init, session)
    assert result.resyncs == 1 and result.attempts == 2 and result.init_commands == 14
    assert result.text_replies >= 10      # the firmware acknowledged the calibration values
    session.mark_initialised(calibration_source=TRUTH.source, calibration_uploaded=True,
                             speed_term='abs')
    samples: list[Sample] = []
    latency: list[float] = []

    def on_line(line: bytes, overflow: bool, t: float) -> None:
        sample = session.handle_line(t, line, overflow)
        if sample is not None:
            samples.append(sample)
            latency.append(time.monotonic() - t)
    router.on_line_target = on_line
    assert _wait_until(lambda: len(samples) >= 150, timeout=5.0)
    router.on_line_target = None
    valid = [s for s in samples[10:] if s.valid]
    assert len(valid) >= 120
    mean = [sum(getattr(s, k) for s in valid) / len(valid) for k in ('vx', 'vy', 'omega')]
    assert mean == pytest.approx(twist, rel=0.03)
    # Host integration over the stamped window agrees with the true motion.
    first, last = valid[0], valid[-1]
    assert last.x - first.x == pytest.approx(twist[0] * (last.stamp - first.stamp), rel=0.05)
    assert last.theta - first.theta == pytest.approx(twist[2] * (last.stamp - first.stamp),
                                                     rel=0.05)
    d = session.diagnostics(last.stamp)
    assert d.counters.bad == 0 and not d.stale and 90.0 < d.rate_hz < 150.0
    assert all(r.level is Level.OK for r in session.reports(last.stamp).values())
    assert max(latency) < 0.5


def test_resync_window_over_a_pty(pty_emulator, links) -> None:
    """A chip stops answering while the surface moves at 20 mm/s: the emulated firmware prints
    notice + signed IDs every pass and zero velocity lines. From the first notice up to the
    first velocity line after a clean pass nothing is valid; then valid samples measure the
    motion again and the chips report clears."""
    twist = (0.020, 0.0, 0.0)
    pty = pty_emulator(EmulatorParams(truth=TRUTH, firmware_speed_term='abs'),
                       ConstantTwist(*twist))
    router = Router()
    link = links(pty.port, router)
    session = SensorSession(port=pty.port, expected_name='sensor_1')
    init = cal_mod.upload_commands(TRUTH, 'abs') + [protocol.chip_mode_command(0)]
    _handshake(link, router, 'sensor_1', pty.port, HandshakeParams(timeout=1.0), init, session)
    session.mark_initialised(calibration_source=TRUTH.source, calibration_uploaded=True,
                             speed_term='abs')
    events: list[tuple[str, Sample | None]] = []        # arrival order, reader thread

    def on_line(line: bytes, overflow: bool, t: float) -> None:
        sample = session.handle_line(t, line, overflow)
        if line.rstrip(b'\r') == b'n/tresynch':
            events.append(('r', None))
        elif sample is not None:
            events.append(('v', sample))

    def count(kind: str, valid: bool | None = None) -> int:
        return sum(1 for k, s in list(events)
                   if k == kind and (valid is None or (s is not None and s.valid == valid)))
    router.on_line_target = on_line
    assert _wait_until(lambda: count('v', True) >= 30, timeout=5.0)
    pty.emulator.set_chip_blind(2, product_id=0)
    assert _wait_until(lambda: count('r') >= 40, timeout=5.0)
    chips = session.reports(time.monotonic())['chips']
    assert chips.level in (Level.WARN, Level.ERROR) and 'chip 2 reads 0' in chips.message
    pty.emulator.set_chip_blind(2, False)
    valid_before = count('v', True)
    assert _wait_until(lambda: count('v', True) >= valid_before + 60, timeout=5.0)
    router.on_line_target = None
    kinds = [k for k, _ in events]
    first, last = kinds.index('r'), len(kinds) - 1 - kinds[::-1].index('r')
    window = [s for k, s in events[first:last] if k == 'v']
    assert len(window) >= 30 and not any(s.valid for s in window)
    after = [s for k, s in events[last:] if k == 'v']
    assert [s.valid for s in after[:3]] == [False, False, True]
    assert all(s.valid for s in after[2:])
    valid = [s for k, s in events if k == 'v' and s.valid]
    assert min(s.vx for s in valid) > 0.010            # no zero published as a measurement
    mean_after = sum(s.vx for s in after[2:]) / len(after[2:])
    assert mean_after == pytest.approx(twist[0], rel=0.05)
    assert session.reports(after[-1].stamp)['chips'].level is Level.OK


def test_unplugged_port_mid_stream_is_reported_not_swallowed(pty_emulator, links) -> None:
    pty = pty_emulator(EmulatorParams(), ConstantTwist(0.01, 0.0, 0.0))
    router = Router()
    link = links(pty.port, router)
    session = SensorSession(port=pty.port, expected_name='sensor_1')
    _handshake(link, router, 'sensor_1', pty.port, HandshakeParams(timeout=1.0))
    session.mark_initialised(calibration_source='t', calibration_uploaded=True, speed_term='zero')
    samples: list[Sample] = []
    router.on_line_target = lambda line, ov, t: samples.append(session.handle_line(t, line, ov))
    router.on_lost_target = lambda t, reason: session.link_lost(reason)
    assert _wait_until(lambda: len(samples) > 20, timeout=3.0)
    pty.vanish()
    reason = router.losses.get(timeout=3.0)
    assert pty.port in reason and 'disconnected' in reason
    assert not link.connected and link.stats().losses == 1
    report = session.reports(time.monotonic())['link']
    assert report.level is Level.ERROR and pty.port in report.message
    assert session.needs_reinitialisation


def test_silent_port_fails_the_handshake_with_a_clear_error(pty_emulator, links) -> None:
    pty = pty_emulator(EmulatorParams())
    pty.emulator.set_silent(True)
    router = Router()
    link = links(pty.port, router)
    start = time.monotonic()
    with pytest.raises(HandshakeError) as err:
        _handshake(link, router, 'sensor_1', pty.port, HandshakeParams(timeout=0.2, retries=2))
    elapsed = time.monotonic() - start
    assert err.value.reason is HandshakeFailure.NO_ANSWER
    assert pty.port in str(err.value) and 'no answer' in str(err.value)
    assert 0.35 < elapsed < 2.0


def test_unplugged_during_the_handshake_fails_it_naming_the_port(pty_emulator, links) -> None:
    pty = pty_emulator(EmulatorParams())
    pty.emulator.set_silent(True)
    router = Router()
    link = links(pty.port, router)
    hs = Handshake('sensor_1', HandshakeParams(timeout=5.0, retries=3), port=pty.port)
    runner = HandshakeRunner(hs)
    router.on_line_target, router.on_lost_target = runner.on_line, runner.on_lost
    pty.vanish()
    start = time.monotonic()
    with pytest.raises(HandshakeError) as err:
        runner.run(link.write, time.monotonic)
    assert err.value.reason is HandshakeFailure.LINK_ERROR and pty.port in str(err.value)
    assert time.monotonic() - start < 3.0


def test_a_second_sensor_claiming_the_same_name(pty_emulator, links, tmp_path: Path) -> None:
    first = pty_emulator(EmulatorParams(name='sensor_1'))
    second = pty_emulator(EmulatorParams(name='sensor_1'))   # flashed with the wrong name
    answers, opened = {}, {}
    for pty in (first, second):
        router = Router()
        opened[pty.port] = link = links(pty.port, router)
        answers[pty.port] = _handshake(link, router, '', pty.port, HandshakeParams()).name
    assert set(answers.values()) == {'sensor_1'}
    with pytest.raises(DuplicateSensorNameError) as err:
        assign_ports(answers, ('sensor_1', 'sensor_2'))
    assert first.port in str(err.value) and second.port in str(err.value)

    # Two driver processes (one per port) that both identified 'sensor_1': the second claim
    # fails and names the port that holds the name.
    with NameClaim('sensor_1', first.port, tmp_path):
        with pytest.raises(DuplicateSensorNameError) as claim_err:
            NameClaim('sensor_1', second.port, tmp_path).acquire()
        assert first.port in str(claim_err.value) and second.port in str(claim_err.value)
    NameClaim('sensor_1', second.port, tmp_path).acquire()   # released: can be claimed now

    # The finger-2 node (expecting 'sensor_2') on the second port refuses it. (The port is
    # opened exclusively: one owner per device, so the discovery link is closed first.)
    opened[second.port].close()
    router = Router()
    link = links(second.port, router)
    with pytest.raises(HandshakeError) as wrong:
        _handshake(link, router, 'sensor_2', second.port, HandshakeParams(timeout=0.5))
    assert wrong.value.reason is HandshakeFailure.WRONG_NAME and second.port in str(wrong.value)


def test_emulator_command_line_serves_a_pty(tmp_path: Path) -> None:
    import os
    import subprocess
    import sys

    import serial
    link_path = tmp_path / 'ttyVEL2'
    env = dict(os.environ, PYTHONUNBUFFERED='1')
    proc = subprocess.Popen(
        [sys.executable, '-m', 'slip_velocity_sensor.core.emulator', '--name', 'sensor_2',
         '--motion', 'constant', '--vx', '0.01', '--duration', '10', '--link', str(link_path)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        port = proc.stdout.readline().strip()
        assert port.startswith('/dev/') and os.path.realpath(link_path) == port
        with serial.serial_for_url(str(link_path), baudrate=115200, timeout=0.05) as ser:
            ser.write(b'n\n')
            seen = b''
            end = time.monotonic() + 5.0
            while b'n/tsensor_2' not in seen and time.monotonic() < end:
                seen += ser.read(256)
        assert b'n/tsensor_2\r\n' in seen and b'v/t' in seen
    finally:
        proc.terminate()
        returncode = proc.wait(5.0)
    assert returncode == 0                   # SIGTERM is a clean stop
    assert not os.path.lexists(link_path)    # and the symlink is removed


def test_emulator_command_line_plays_a_blind_chip(tmp_path: Path) -> None:
    import os
    import subprocess
    import sys

    import serial
    env = dict(os.environ, PYTHONUNBUFFERED='1')
    proc = subprocess.Popen(
        [sys.executable, '-m', 'slip_velocity_sensor.core.emulator', '--blind-chip', '2',
         '--blind-id', '-1', '--motion', 'constant', '--vx', '0.02', '--duration', '10'],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        port = proc.stdout.readline().strip()
        with serial.serial_for_url(port, baudrate=115200, timeout=0.05) as ser:
            seen = b''
            end = time.monotonic() + 5.0
            while seen.count(b'n/tresynch') < 20 and time.monotonic() < end:
                seen += ser.read(512)
    finally:
        proc.terminate()
        proc.wait(5.0)
    assert seen.count(b'n/tresynch\r\n49 -1 49\r\n') >= 20
    velocity = [line for line in seen.split(b'\r\n') if line.startswith(b'v/t')]
    assert velocity[2:] and set(velocity[2:]) == {b'v/t0.0000/t0.0000/t0.0000'}
