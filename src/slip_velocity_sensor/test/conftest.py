# SPDX-License-Identifier: Apache-2.0
"""Shared fixtures of the slip_velocity_sensor core tests (no ROS needed)."""
from __future__ import annotations

from collections.abc import Callable

import pytest

from slip_velocity_sensor.core.emulator import EmulatorStream, FirmwareEmulator
from slip_velocity_sensor.core.handshake import Handshake
from slip_velocity_sensor.core.protocol import LineParser, LineSplitter


class FakeClock:
    """Virtual time: ``clock()`` reads it, ``clock.sleep(dt)`` advances it."""

    def __init__(self, t: float = 100.0) -> None:
        self.t = t

    def __call__(self) -> float:
        return self.t

    def sleep(self, dt: float) -> None:
        self.t += max(dt, 0.0)


@pytest.fixture
def clock() -> FakeClock:
    """A fresh virtual clock (starts at 100 s so that stamps are clearly not zero)."""
    return FakeClock()


@pytest.fixture
def virtual_stream(clock: FakeClock) -> Callable[[FirmwareEmulator], EmulatorStream]:
    """Factory: an in-process stream over an emulator, running in the fixture's virtual time."""
    def make(emulator: FirmwareEmulator, timeout: float = 0.02) -> EmulatorStream:
        return EmulatorStream(emulator, clock=clock, sleep=clock.sleep, timeout=timeout)
    return make


@pytest.fixture
def drive_handshake(clock: FakeClock) -> Callable[..., list[tuple[float, bytes]]]:
    """Factory: run a `Handshake` against a stream in virtual time; returns what was written.

    The loop mirrors a real driver: write due commands, read with the stream's timeout, feed
    parsed lines; it stops when the handshake is done or after ``max_time`` virtual seconds.
    """
    def drive(hs: Handshake, stream: EmulatorStream, max_time: float = 60.0,
              parser: LineParser | None = None) -> list[tuple[float, bytes]]:
        parser = parser if parser is not None else LineParser()
        splitter = LineSplitter()
        written: list[tuple[float, bytes]] = []
        end = clock() + max_time
        hs.start(clock())
        while not hs.done and clock() < end:
            for command in hs.poll(clock()):
                stream.write(command)
                written.append((clock(), command))
            for line, overflow in splitter.feed(stream.read(4096)):
                hs.on_line(clock(), parser.parse(line, overflow))
        return written
    return drive
