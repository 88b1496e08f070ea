# SPDX-License-Identifier: Apache-2.0
"""Serial transport: line splitting, opening ports/URLs, back-off, reader thread and loss."""
from __future__ import annotations

import threading
import time
from collections.abc import Callable

import numpy as np
import pytest
import serial

from slip_cell_common.core.serial_transport import (LineReader, LinkError, ReconnectParams,
                                                ReconnectPolicy, SerialLink,
                                                describe_link_error, open_stream)


def _wait(predicate: Callable[[], bool], timeout_s: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.002)
    return predicate()


class FakeClock:
    """Manually advanced clock [s]."""

    def __init__(self, t: float = 100.0) -> None:
        self.t = t

    def __call__(self) -> float:
        return self.t


# ---------------------------------------------------------------------- LineReader
def test_line_reader_terminators_and_empty_lines() -> None:
    reader = LineReader(resync=False)
    assert reader.feed(b'1.0000\r\n2.0000\n3.0000\r\r\n\n4.0') == [
        (b'1.0000', False), (b'2.0000', False), (b'3.0000', False)]
    assert reader.feed(b'000\r\n') == [(b'4.0000', False)]


def test_line_reader_independent_of_chunking() -> None:
    rng = np.random.default_rng(0)
    data = b''.join(f'{x:.4f}\r\n'.encode() for x in rng.normal(0, 10, 2000))
    whole = LineReader(resync=False).feed(data)
    reader = LineReader(resync=False)
    pieces, pos = [], 0
    while pos < len(data):
        n = int(rng.integers(1, 20))
        pieces += reader.feed(data[pos:pos + n])
        pos += n
    assert pieces == whole and len(whole) == 2000


def test_line_reader_resync_discards_partial_first_line() -> None:
    reader = LineReader()
    assert reader.feed(b'416\r\n3.1416\r\n') == [(b'3.1416', False)]
    assert reader.discarded_bytes == 3
    reader.reset(resync=True)
    assert reader.feed(b'\r\n1.0000\r\n') == [(b'1.0000', False)]


def test_line_reader_bounds_overlong_lines() -> None:
    reader = LineReader(max_line_length=8, resync=False)
    out = reader.feed(b'1234567890' * 1000)
    assert out == [] and len(reader._buf) <= 8
    out = reader.feed(b'abc\n1.0000\n')
    assert out == [(b'12345678', True), (b'1.0000', False)]
    assert reader.overflows == 1


# ---------------------------------------------------------------------- open_stream
def test_nonexistent_port_error_names_the_port() -> None:
    path = '/dev/serial/by-id/usb-Espressif_USB_JTAG_serial_debug_unit_DOESNOTEXIST-if00'
    with pytest.raises(LinkError) as info:
        open_stream(path, 115200, 0.1)
    assert path in str(info.value)


def test_invalid_url_error_names_it() -> None:
    with pytest.raises(LinkError, match='nosuchscheme://x'):
        open_stream('nosuchscheme://x', 115200, 0.1)
    with pytest.raises(LinkError, match='not set'):
        open_stream('', 115200, 0.1)


def test_loop_url_round_trip() -> None:
    stream = open_stream('loop://', 115200, 0.05)
    try:
        stream.write(b'T0.00\n')
        assert stream.read(6) == b'T0.00\n'
    finally:
        stream.close()


def test_describe_unplugged_error() -> None:
    exc = serial.SerialException('device reports readiness to read but returned no data '
                                 '(device disconnected or multiple access on port?)')
    text = describe_link_error('/dev/ttyACM0', exc)
    assert text.startswith('/dev/ttyACM0') and 'disconnected' in text


# ---------------------------------------------------------------------- ReconnectPolicy
def test_reconnect_backoff_with_fake_clock() -> None:
    clock = FakeClock()
    policy = ReconnectPolicy(0.5, 5.0, clock=clock)
    assert policy.due()
    delays = []
    for _ in range(7):
        delays.append(policy.record_failure())
        assert not policy.due()
        assert policy.time_until_next() == pytest.approx(delays[-1])
        clock.t += delays[-1] - 1e-6
        assert not policy.due()
        clock.t += 2e-6
        assert policy.due()
    assert delays == [0.5, 1.0, 2.0, 4.0, 5.0, 5.0, 5.0]
    policy.record_success()
    assert policy.due() and policy.record_failure() == 0.5


@pytest.mark.parametrize('initial, maximum', [(0.0, 1.0), (2.0, 1.0), (-1.0, 1.0)])
def test_reconnect_policy_rejects_bad_delays(initial: float, maximum: float) -> None:
    with pytest.raises(ValueError):
        ReconnectPolicy(initial, maximum, clock=FakeClock())


# ---------------------------------------------------------------------- SerialLink
class ScriptedStream:
    """A ByteStream that yields scripted chunks, then fails like an unplugged CDC device."""

    def __init__(self, chunks: list[bytes], fail: bool = True) -> None:
        self.chunks = list(chunks)
        self.fail = fail
        self.written: list[bytes] = []
        self.closed = False

    def read(self, size: int = 1) -> bytes:
        if self.chunks:
            return self.chunks.pop(0)
        if self.fail:
            raise serial.SerialException('device reports readiness to read but returned no '
                                         'data (device disconnected or multiple access on '
                                         'port?)')
        time.sleep(0.001)
        return b''

    def write(self, data: bytes) -> int:
        self.written.append(data)
        return len(data)

    def close(self) -> None:
        self.closed = True


def test_serial_link_stamps_lines_detects_loss_and_reconnects_with_backoff() -> None:
    clock_value = [0.0]
    streams = [ScriptedStream([b'junk\r\n1.0000\r\n2.00', b'00\r\n']),
               ScriptedStream([b'\r\n3.0000\r\n'], fail=False)]
    opened: list[str] = []
    failures_left = [2]

    def opener(url: str, baudrate: int, timeout_s: float, **_: object) -> ScriptedStream:
        opened.append(url)
        if len(opened) > 1 and failures_left[0] > 0:
            failures_left[0] -= 1
            raise LinkError(f'cannot open serial port {url!r}: gone')
        return streams.pop(0)

    lines: list[tuple[bytes, float]] = []
    events: list[tuple[str, str]] = []
    lock = threading.Lock()

    def on_line(line: bytes, overflow: bool, t: float) -> None:
        clock_value[0] += 1.0
        with lock:
            lines.append((line, t))

    link = SerialLink('/dev/serial/by-id/fake', clock=lambda: clock_value[0], on_line=on_line,
                      on_connected=lambda t, p: events.append(('connected', p)),
                      on_lost=lambda t, r: events.append(('lost', r)),
                      on_error=lambda t, m: events.append(('error', m)),
                      reconnect=ReconnectParams(initial_delay=0.01, max_delay=0.04),
                      opener=opener)
    link.open()
    link.start()
    try:
        assert _wait(lambda: len(lines) >= 2 and link.stats().reconnects == 1)
        assert _wait(lambda: any(line == b'3.0000' for line, _ in lines))
    finally:
        link.close()
    got = [line for line, _ in lines]
    # 'junk' is the partial first line (resync); lines 1 and 2 survive the chunk split
    assert got[:2] == [b'1.0000', b'2.0000'] and b'junk' not in got
    lost = [r for kind, r in events if kind == 'lost']
    assert len(lost) >= 1 and '/dev/serial/by-id/fake' in lost[0] and 'disconnected' in lost[0]
    stats = link.stats()
    assert stats.connect_failures == 2 and stats.reconnects == 1 and stats.losses >= 1
    assert [kind for kind, _ in events].count('error') == 2
    assert stats.callback_errors == 0


def test_serial_link_write_while_disconnected_is_dropped_not_raised() -> None:
    link = SerialLink('loop://', clock=time.monotonic, on_line=lambda *a: None)
    assert link.write(b'T0.00\n') is False
    assert link.stats().writes_dropped == 1
    with pytest.raises(LinkError):
        link.start()


def test_serial_link_counts_callback_errors_and_keeps_running() -> None:
    calls = []

    def bad(line: bytes, overflow: bool, t: float) -> None:
        calls.append(line)
        raise RuntimeError('bug in callback')

    stream = ScriptedStream([b'\r\n1.0000\r\n2.0000\r\n'], fail=False)
    link = SerialLink('fake://', clock=time.monotonic, on_line=bad,
                      opener=lambda *a, **k: stream)
    link.open()
    link.start()
    try:
        assert _wait(lambda: len(calls) == 2)
    finally:
        link.close()
    assert link.stats().callback_errors == 2 and 'bug in callback' in link.stats().last_error
    assert stream.closed
