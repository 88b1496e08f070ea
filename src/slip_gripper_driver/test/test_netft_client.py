# SPDX-License-Identifier: Apache-2.0
"""Net F/T UDP client against the RDT emulator on 127.0.0.1 (real sockets, bounded waits)."""
from __future__ import annotations

import socket
import threading
import time
from typing import Callable, Iterator

import pytest

from slip_cell_common.core.monitors import Level
from slip_gripper_driver.core.netft import (BiasAccumulator, BiasState, ForceTorqueScale,
                                            FtSample, NetFTClient, NetFTError,
                                            fetch_netft_config)
from slip_gripper_driver.core.netft_emulator import NetFTEmulator

SCALE = ForceTorqueScale(1_000_000, 1_000_000, 'N', 'N-m')


def wait_until(predicate: Callable[[], bool], timeout_s: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.005)
    return predicate()


class Collector:
    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.samples: list[FtSample] = []

    def __call__(self, sample: FtSample) -> None:
        with self.lock:
            self.samples.append(sample)

    def count(self) -> int:
        with self.lock:
            return len(self.samples)


@pytest.fixture
def box() -> Iterator[NetFTEmulator]:
    emu = NetFTEmulator(rate_hz=1000.0, scale=SCALE, serve_http=True,
                        force_source=lambda t: (0.1, -0.2, -3.0, 0.001, 0.002, -0.003),
                        offsets=(0.0, 0.0, 0.5, 0.0, 0.0, 0.0))
    emu.start()
    yield emu
    emu.stop()


@pytest.fixture
def client(box: NetFTEmulator) -> Iterator[tuple[NetFTClient, Collector]]:
    got = Collector()
    host, port = box.address
    cl = NetFTClient(host, port=port, scale=SCALE, clock=time.monotonic, on_sample=got,
                     start_wait_s=0.2)
    cl.open()
    yield cl, got
    cl.close()


def test_streams_and_converts_to_si(box: NetFTEmulator, client) -> None:
    cl, got = client
    cl.start()
    assert wait_until(lambda: got.count() >= 200)
    with got.lock:
        samples = list(got.samples)
    w = samples[-1].wrench
    assert w == pytest.approx((0.1, -0.2, -2.5, 0.001, 0.002, -0.003), abs=1e-6)
    seqs = [s.rdt_sequence for s in samples]
    assert seqs == sorted(seqs)
    stats = cl.stats()
    assert stats.streaming and stats.lost == 0 and stats.bad_datagrams == 0
    assert stats.status_level == Level.OK and stats.rate_hz > 100.0
    assert cl.latest() is not None


def test_stop_is_sent_on_close(box: NetFTEmulator) -> None:
    host, port = box.address
    cl = NetFTClient(host, port=port, scale=SCALE, clock=time.monotonic)
    cl.start()
    assert box.streaming
    cl.close()
    assert wait_until(lambda: box.stops == 1 and not box.streaming)


def test_dropped_duplicated_reordered_truncated_and_garbage(box: NetFTEmulator, client) -> None:
    cl, got = client
    cl.start()
    assert wait_until(lambda: got.count() >= 50)
    box.inject(drop=5)
    assert wait_until(lambda: cl.stats().lost >= 5)
    box.inject(duplicate=3)
    assert wait_until(lambda: cl.stats().duplicates >= 3)
    box.inject(reorder=2)
    assert wait_until(lambda: cl.stats().out_of_order >= 2)
    box.inject(truncate=4, garbage=3)
    assert wait_until(lambda: cl.stats().bad_datagrams >= 7)
    n = got.count()
    assert wait_until(lambda: got.count() >= n + 100)  # streaming continues
    stats = cl.stats()
    assert (stats.lost, stats.duplicates, stats.out_of_order) == (5 + 2 + 4, 3, 2)
    assert stats.bad_datagrams == 7 and stats.resyncs == 0
    with got.lock:
        seqs = [s.rdt_sequence for s in got.samples]
    assert all(b > a for a, b in zip(seqs, seqs[1:]))  # only newer records are handed on


def test_sequence_wrap_is_seamless() -> None:
    emu = NetFTEmulator(scale=SCALE, rdt_sequence_start=2**32 - 100,
                        ft_sequence_start=2**32 - 100)
    emu.start()
    got = Collector()
    cl = NetFTClient(emu.address[0], port=emu.address[1], scale=SCALE, clock=time.monotonic,
                     on_sample=got)
    try:
        cl.start()
        assert wait_until(lambda: got.count() >= 300)
        stats = cl.stats()
        assert stats.lost == 0 and stats.out_of_order == 0 and stats.ft_stalls == 0
        with got.lock:
            assert any(s.rdt_sequence < 100 for s in got.samples)
    finally:
        cl.close()
        emu.stop()


def test_status_word_is_decoded_and_latched(box: NetFTEmulator, client) -> None:
    cl, got = client
    cl.start()
    box.set_status(0x80020000)
    assert wait_until(lambda: cl.stats().status_level == Level.ERROR)
    assert 'saturation' in cl.stats().status_text
    box.set_status(0)
    assert wait_until(lambda: cl.stats().status_level == Level.OK)
    assert cl.stats().latched_status == 0x80020000
    cl.reset_latch()
    assert cl.stats().latched_status == 0 and wait_until(lambda: box.latch_resets == 1)


def test_buffered_mode_delivers_every_record(box: NetFTEmulator) -> None:
    got = Collector()
    cl = NetFTClient(box.address[0], port=box.address[1], scale=SCALE, clock=time.monotonic,
                     on_sample=got, buffered=True)
    try:
        cl.start()
        assert wait_until(lambda: got.count() >= 200)
        stats = cl.stats()
        assert stats.records >= 4 * stats.datagrams - 4 and stats.lost == 0
    finally:
        cl.close()


def test_device_bias_command(box: NetFTEmulator, client) -> None:
    cl, got = client
    cl.start()
    cl.set_device_bias()
    assert wait_until(lambda: box.biases == 1)
    n = got.count()
    assert wait_until(lambda: got.count() > n + 20)
    assert cl.latest().wrench == pytest.approx((0.0,) * 6, abs=1e-6)


def test_host_bias_from_streamed_samples(box: NetFTEmulator) -> None:
    acc = BiasAccumulator(duration_s=0.1, min_samples=50, settle_samples=2)
    biased: list[tuple] = []

    def on_sample(sample: FtSample) -> None:
        out = acc.add(sample.stamp, sample.wrench)
        if out is not None:
            biased.append(out)

    cl = NetFTClient(box.address[0], port=box.address[1], scale=SCALE, clock=time.monotonic,
                     on_sample=on_sample)
    try:
        cl.start()
        acc.start(time.monotonic())
        assert wait_until(lambda: acc.state != BiasState.COLLECTING)
        assert acc.state == BiasState.DONE
        assert wait_until(lambda: len(biased) > 10)
        assert biased[-1] == pytest.approx((0.0,) * 6, abs=1e-6)
    finally:
        cl.close()


def test_no_box_listening_fails_start_naming_the_address() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(('127.0.0.1', 0))
        port = probe.getsockname()[1]
    cl = NetFTClient('127.0.0.1', port=port, scale=SCALE, clock=time.monotonic,
                     start_retries=3, start_wait_s=0.05)
    try:
        with pytest.raises(NetFTError, match=f'127.0.0.1:{port}'):
            cl.start()
    finally:
        cl.close()


def test_unresolvable_address_fails_open_naming_it() -> None:
    cl = NetFTClient('netft-box.invalid', scale=SCALE, clock=time.monotonic)
    with pytest.raises(NetFTError, match='netft-box.invalid'):
        cl.open()


def test_config_read_over_http(box: NetFTEmulator) -> None:
    cfg = fetch_netft_config(box.address[0], http_port=box.http_port)
    assert cfg.scale == SCALE and cfg.rdt_rate_hz == 1000.0
    with pytest.raises(NetFTError, match='127.0.0.1'):
        fetch_netft_config('127.0.0.1', http_port=1, timeout_s=0.5)


def test_supervise_restarts_the_stream_after_a_box_reboot(box: NetFTEmulator, client) -> None:
    cl, got = client
    cl.start()
    assert wait_until(lambda: got.count() >= 50)
    assert cl.supervise(time.monotonic())
    box.reboot()
    assert wait_until(lambda: not cl.supervise(time.monotonic(), receive_timeout_s=0.05))
    n = got.count()
    assert wait_until(lambda: cl.supervise(time.monotonic(), receive_timeout_s=0.05),
                      timeout_s=10.0)
    assert wait_until(lambda: got.count() > n + 50)
    stats = cl.stats()
    assert stats.restarts >= 1 and stats.resyncs == 1 and box.starts >= 2
