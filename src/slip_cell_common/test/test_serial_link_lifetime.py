# SPDX-License-Identifier: Apache-2.0
"""SerialLink: descriptor lifetime against its reader thread, lines read together, a start
that retries opening, and resynchronisation after a quiet port (issues 16 and 17)."""
from __future__ import annotations

import os
import threading
import time
from pathlib import Path
from collections.abc import Callable

from slip_cell_common.core.serial_transport import (LineReader, ReconnectParams, SerialLink,
                                                open_stream)


def _wait(predicate: Callable[[], bool], timeout_s: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.002)
    return predicate()


def test_close_never_closes_the_port_under_a_reader_that_still_runs(pty) -> None:
    """The reader is stuck in a callback: close() hands the close over to it (a descriptor
    closed under a thread that still reads or selects on its number is a use-after-close)."""
    master, path = pty
    release = threading.Event()
    entered = threading.Event()
    streams = []

    def opener(*args, **kwargs):
        streams.append(open_stream(*args, **kwargs))
        return streams[-1]

    def on_line(line: bytes, overflow: bool, t: float) -> None:
        entered.set()
        release.wait(5.0)

    link = SerialLink(path, clock=time.monotonic, on_line=on_line, opener=opener)
    link.open()
    link.start()
    os.write(master, b'x\r\n1.0000\r\n')
    assert entered.wait(5.0)
    link.close(timeout_s=0.05)  # the reader is still inside on_line
    assert streams[0].is_open and streams[0].fd is not None
    release.set()
    assert _wait(lambda: not streams[0].is_open)  # closed by the reader on its way out
    assert not link.running and not link.connected


def test_lines_read_together_arrive_together_and_input_pending_counts_waiting_bytes(
        pty) -> None:
    master, path = pty
    chunks: list[tuple[list[tuple[bytes, bool]], float]] = []
    gate = threading.Event()

    def on_chunk(lines: list[tuple[bytes, bool]], t: float) -> None:
        chunks.append((lines, t))
        gate.wait(5.0)

    link = SerialLink(path, clock=time.monotonic, on_line=lambda *a: None, on_chunk=on_chunk)
    link.open()
    link.start()
    os.write(master, b'\r\n1.0000\r\n')
    assert _wait(lambda: len(chunks) == 1)  # the reader now waits inside on_chunk
    os.write(master, b'2.0000\r\n3.0000\r\n4.0000\r\n')
    assert _wait(lambda: link.input_pending() == 24)  # arrived, not read: a host stall
    gate.set()
    assert _wait(lambda: len(chunks) == 2)
    assert [line for line, _ in chunks[1][0]] == [b'2.0000', b'3.0000', b'4.0000']
    assert link.last_read_stamp == chunks[1][1]
    assert link.input_pending() == 0
    link.close()
    assert link.input_pending() == 0


def test_a_start_before_the_port_exists_opens_it_with_back_off(tmp_path: Path, pty) -> None:
    master, path = pty
    link_path = tmp_path / 'usb-gripper'
    errors: list[str] = []
    connected: list[str] = []
    lines: list[bytes] = []
    link = SerialLink(str(link_path), clock=time.monotonic,
                      on_line=lambda line, o, t: lines.append(line),
                      on_connected=lambda t, port: connected.append(port),
                      on_error=lambda t, message: errors.append(message),
                      reconnect=ReconnectParams(initial_delay=0.02, max_delay=0.05))
    link.start(open_retry=True)
    assert _wait(lambda: link.stats().connect_failures >= 3)
    assert str(link_path) in errors[0] and not connected
    link_path.symlink_to(path)  # the device appears
    assert _wait(lambda: bool(connected))
    time.sleep(0.1)  # several read timeouts (20 ms) of silence: at a line boundary
    os.write(master, b'1.0000\r\n2.0000\r\n')
    assert _wait(lambda: lines == [b'1.0000', b'2.0000'])  # quiet port: nothing dropped
    assert link.stats().reconnects == 0  # the first connection, not a reconnection
    link.close()


def test_resync_ends_once_the_port_was_quiet() -> None:
    reader = LineReader()
    reader.quiet()  # nothing arrived since the (re)connection: the next byte starts a line
    assert reader.feed(b'Voltage control\r\n1.0000\r\n') == [(b'Voltage control', False),
                                                           (b'1.0000', False)]
    reader.reset()
    reader.feed(b'16')  # the tail of a line was already arriving: still dropped
    reader.quiet()
    assert reader.feed(b'\r\n3.1416\r\n') == [(b'3.1416', False)]
