# SPDX-License-Identifier: Apache-2.0
"""Kernel arrival stamps of UDP datagrams (`udp_arrival`), on real loopback sockets."""
from __future__ import annotations

import socket
import time
from collections.abc import Iterator

import pytest

from slip_gripper_driver.core import udp_arrival


@pytest.fixture
def pair() -> Iterator[tuple[socket.socket, socket.socket]]:
    receiver = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    receiver.bind(('127.0.0.1', 0))
    receiver.setblocking(False)
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sender.connect(receiver.getsockname())
    yield receiver, sender
    receiver.close()
    sender.close()


@pytest.fixture
def stamped_pair(pair) -> tuple[socket.socket, socket.socket]:
    """`pair` with arrival stamps on and already in effect.

    The kernel turns arrival stamping on for the host with a deferred work item: until it has,
    datagrams carry the read time. Wait (at most 5 s) for one that shows its wait."""
    if not udp_arrival.supported():
        pytest.skip('no kernel arrival stamps here')
    receiver, sender = pair
    assert udp_arrival.enable(receiver)
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline:
        sender.send(b'warm-up')
        time.sleep(0.02)
        _, age = udp_arrival.receive(receiver, 1024, time.time)
        if age is not None and age >= 0.015:
            return pair
    pytest.fail('the kernel never stamped a datagram with its arrival time')


def test_a_datagram_read_late_reports_how_long_it_waited(stamped_pair) -> None:
    receiver, sender = stamped_pair
    sender.send(b'first')
    time.sleep(0.060)
    sender.send(b'second')
    first, first_age = udp_arrival.receive(receiver, 1024, time.time)
    second, second_age = udp_arrival.receive(receiver, 1024, time.time)
    assert (first, second) == (b'first', b'second')
    assert first_age is not None and second_age is not None
    assert 0.055 <= first_age < 1.0
    assert 0.0 <= second_age < first_age - 0.050


def test_a_stepped_wall_clock_makes_the_age_unknown_not_negative(stamped_pair) -> None:
    receiver, sender = stamped_pair
    sender.send(b'x')
    time.sleep(0.005)
    _, age = udp_arrival.receive(receiver, 1024, lambda: time.time() - 3600.0)
    assert age is None
    sender.send(b'y')
    time.sleep(0.005)
    _, age = udp_arrival.receive(receiver, 1024, lambda: time.time() + 3600.0)
    assert age is None


def test_without_the_option_there_is_no_age(pair) -> None:
    receiver, sender = pair
    sender.send(b'x')
    time.sleep(0.005)
    data, age = udp_arrival.receive(receiver, 1024, time.time)
    assert data == b'x' and age is None


def test_an_empty_socket_raises_blocking_io(pair) -> None:
    receiver, _ = pair
    udp_arrival.enable(receiver)
    with pytest.raises(BlockingIOError):
        udp_arrival.receive(receiver, 1024, time.time)
