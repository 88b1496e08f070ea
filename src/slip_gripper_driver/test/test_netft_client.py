# SPDX-License-Identifier: Apache-2.0
"""Net F/T UDP client against the RDT emulator on 127.0.0.1 (real sockets, bounded waits)."""
from __future__ import annotations

import socket
import threading
import time
from collections.abc import Callable, Iterator

import pytest

from slip_cell_common.core.monitors import Level
from slip_gripper_driver.core.ft_bias import BiasAccumulator, BiasState
from slip_gripper_driver.core.ft_scale import ForceTorqueScale
from slip_gripper_driver.core.netft_client import FtSample, NetFTClient, NetFTError
from slip_gripper_driver.core.netft_config import fetch_netft_config
from slip_gripper_driver.core.netft_emulator import NetFTEmulator
from slip_gripper_driver.ft_channel import FtChannel, run_bias

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
    # restart_after 0.25 s: a busy test host can stall the emulator's thread for more than
    # the 10 ms default, and a re-sent start (harmless) would split the stream in two.
    cl = NetFTClient(host, port=port, scale=SCALE, clock=time.monotonic, on_sample=got,
                     start_wait_s=0.2, restart_after_s=0.25)
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
                     on_sample=got, restart_after_s=0.25)
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


def test_a_rebooted_box_is_restarted_by_the_reader_and_the_restart_is_flagged(
        box: NetFTEmulator, client) -> None:
    """No timer needed: the reader thread re-sends the start request to a silent box, with
    back-off while it boots; the first record after the reboot says so."""
    cl, got = client
    cl.start()
    assert wait_until(lambda: got.count() >= 50)
    assert cl.supervise(time.monotonic())
    box.reboot(boot_time_s=0.3)  # silent, and deaf to start requests, for 0.3 s
    assert wait_until(lambda: not cl.supervise(time.monotonic(), receive_timeout_s=0.05))
    n = got.count()
    assert wait_until(lambda: got.count() > n + 50, timeout_s=10.0)  # resumed on its own
    with got.lock:
        after = got.samples[n:]
    assert after[0].device_restart and after[0].new_stream and after[0].rdt_sequence == 1
    assert not any(s.device_restart for s in after[1:])
    stats = cl.stats()
    assert stats.restarts >= 2 and box.ignored_requests >= 1  # back-off while booting
    assert stats.device_restarts == 1 and stats.new_streams == 1 and stats.resyncs == 0
    assert stats.out_of_order == 0


def test_stream_restarts_lose_no_record(box: NetFTEmulator, client) -> None:
    """Each start request opens a stream numbered from 1 (as on the box): every record the
    box sent reaches the callback (the old tracker dropped ~15 per restart as out of order)."""
    cl, got = client
    cl.start()
    for k in range(4):
        assert wait_until(lambda k=k: got.count() >= 100 * (k + 1))
        cl.set_device_bias()  # the box stops; the client re-sends the start request at once
        assert wait_until(lambda k=k: box.starts == k + 2)
    assert wait_until(lambda: got.count() >= 500)
    cl.stop()
    assert wait_until(lambda: not box.streaming)
    time.sleep(0.1)  # the last datagrams in flight
    stats = cl.stats()
    assert box.biases == 4 and stats.bias_restarts == 4 and stats.new_streams == 4
    assert stats.out_of_order == 0 and stats.lost == 0 and stats.resyncs == 0
    assert got.count() == box.records_sent == stats.accepted
    assert stats.device_restarts == 0  # ft_sequence kept counting across the streams


def test_a_stream_that_stops_is_restarted_without_a_timer(box: NetFTEmulator, client) -> None:
    """The box stops sending (as after a device bias whose start request got lost): the
    reader notices within restart_after and re-sends the start; supervise is never called."""
    cl, got = client
    cl.start()
    assert wait_until(lambda: got.count() >= 50)
    for _ in range(3):
        box.stop_stream()
        n = got.count()
        assert wait_until(lambda n=n: got.count() > n + 30)
    stats = cl.stats()
    assert stats.restarts >= 3 and stats.new_streams >= 3 and stats.out_of_order == 0


def test_device_bias_stops_the_stream_and_the_start_request_follows_at_once(
        box: NetFTEmulator) -> None:
    """The box stops after 0x0042; the client does not wait for its silence detection
    (made 1 s here) nor for a receive timeout: the start request follows the bias."""
    got = Collector()
    cl = NetFTClient(box.address[0], port=box.address[1], scale=SCALE, clock=time.monotonic,
                     on_sample=got, restart_after_s=1.0)
    try:
        cl.start()
        assert wait_until(lambda: got.count() >= 50)
        cl.set_device_bias()
        n = got.count()
        assert wait_until(lambda: got.count() > n + 50, timeout_s=0.9)
        stats = cl.stats()
        assert box.biases == 1 and box.starts == 2 and stats.restarts == 0
        assert stats.new_streams == 1 and stats.out_of_order == 0
    finally:
        cl.close()


def test_device_bias_on_a_box_that_keeps_streaming(box: NetFTEmulator, client) -> None:
    cl, got = client
    box.stop_on_bias = False
    cl.start()
    assert wait_until(lambda: got.count() >= 50)
    cl.set_device_bias()
    n = got.count()
    assert wait_until(lambda: got.count() > n + 50)
    stats = cl.stats()
    assert stats.bias_restarts == 1 and stats.out_of_order == 0 and stats.resyncs == 0


def test_a_latched_monitor_bit_cleared_without_a_reset_means_a_restart(
        box: NetFTEmulator, client) -> None:
    cl, got = client
    cl.start()
    box.set_status(0x80010000)
    assert wait_until(lambda: cl.stats().status == 0x80010000)
    cl.reset_latch()  # asked for: not a restart
    assert wait_until(lambda: cl.stats().status == 0)
    n = got.count()
    assert wait_until(lambda: got.count() > n + 20)
    assert cl.stats().device_restarts == 0
    box.set_status(0x80010000)
    assert wait_until(lambda: cl.stats().status == 0x80010000)
    box.set_status(0)  # what a reboot looks like from the status word alone
    assert wait_until(lambda: cl.stats().device_restarts == 1)


class SinkLog:
    """The grasp loop's side of an `FtChannel` (embedded mode): every sample it gets."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.items: list[tuple[float, tuple | None]] = []

    def __call__(self, finger: int, stamp: float, wrench) -> None:
        with self.lock:
            self.items.append((stamp, None if wrench is None else tuple(wrench)))

    def count(self) -> int:
        with self.lock:
            return len(self.items)


def open_channel(box: NetFTEmulator, sink: SinkLog, **stream: object) -> FtChannel:
    from slip_gripper_driver.core.ft_bias import BiasParams
    from slip_gripper_driver.core.netft_params import FtStreamParams
    host, port = box.address
    values: dict = {'read_config': False, 'counts_per_force': 1e6, 'counts_per_torque': 1e6,
                    'publish_decimation': 1}
    values.update(stream)
    mode = str(values.pop('bias_mode', 'host'))
    channel = FtChannel(1, host, FtStreamParams(**values), BiasParams(mode=mode), port=port,
                        clock=time.monotonic, sink=sink)
    channel.open()
    return channel


def test_error_status_records_never_reach_the_loop_nor_the_wrench_topic(
        box: NetFTEmulator) -> None:
    """Direct (embedded) F/T mode: a box streaming 0x80020000 keeps the loop without F/T."""
    sink = SinkLog()
    channel = open_channel(box, sink, publish_raw=True, publish_on_error=True)
    published: dict[str, list] = {'wrench': [], 'raw': []}
    channel.publish_wrench = lambda t, w: published['wrench'].append(w)
    channel.publish_raw = lambda t, w: published['raw'].append(w)
    channel.publishing = True
    try:
        ok, message = run_bias([channel], time.monotonic, 0.5)
        assert ok, message
        assert wait_until(lambda: sink.count() > 50)
        box.set_status(0x80020000)  # saturation / A-D error; the box keeps streaming
        assert wait_until(lambda: channel.health().status_errors >= 1)
        n_sink, n_wrench = sink.count(), len(published['wrench'])
        raw_before = len(published['raw'])
        assert wait_until(lambda: channel.health().status_errors >= 300)
        assert sink.count() == n_sink and len(published['wrench']) == n_wrench
        assert len(published['raw']) >= raw_before + 290  # publish_on_error: raw only
        report = channel.report(time.monotonic(), 0.5)
        assert report.level == Level.ERROR and 'records dropped' in report.message
        assert dict(report.values)['status_errors'] != '0'
        ok, message = run_bias([channel], time.monotonic, 0.5)
        assert not ok and 'status error' in message and 'bias refused' in message
        box.set_status(0)
        assert wait_until(lambda: sink.count() > n_sink + 50)  # healthy again
        report = channel.report(time.monotonic(), 0.5)
        assert report.level != Level.ERROR, report  # (the rate may WARN on a busy host)
    finally:
        channel.close()


def test_out_of_range_records_never_reach_the_loop(box: NetFTEmulator) -> None:
    """The range comes from the box (cfgmr in netftapi2.xml, on its own HTTP port)."""
    sink = SinkLog()
    channel = open_channel(box, sink, read_config=True, http_port=box.http_port)
    try:
        assert channel.limits == (40.0, 40.0, 120.0, 2.0, 2.0, 2.0)
        ok, message = run_bias([channel], time.monotonic, 0.5)
        assert ok, message
        box.inject(out_of_range=100)  # Fz = 180 N on a 120 N axis
        assert wait_until(lambda: channel.health().out_of_range == 100)
        n = sink.count()
        assert wait_until(lambda: sink.count() > n + 50)
        with sink.lock:
            biased = [w for _, w in sink.items if w is not None]
        assert len(biased) > 50 and all(abs(w[2]) < 120.0 for w in biased)
        assert channel.client is not None and channel.client.stats().status == 0
    finally:
        channel.close()


@pytest.mark.parametrize('mode', ['device', 'host'])
def test_box_reboot_loses_the_bias_until_biased_again(box: NetFTEmulator, mode: str) -> None:
    """After a reboot the box's device bias is gone (and a host bias was taken on top of it):
    reported as lost, no sample reaches the loop until a new bias."""
    sink = SinkLog()
    channel = open_channel(box, sink, bias_mode=mode)
    try:
        ok, message = run_bias([channel], time.monotonic, 0.5)
        assert ok, message
        assert box.biases == (1 if mode == 'device' else 0)
        assert wait_until(lambda: sink.count() > 50)
        with sink.lock:
            assert sink.items[-1][1] == pytest.approx((0.0,) * 6, abs=1e-5)
        box.reboot()
        assert wait_until(lambda: channel.bias_lost)
        n = sink.count()
        records = channel.client.stats().accepted
        assert wait_until(lambda: channel.client.stats().accepted > records + 200)
        assert sink.count() == n  # the +0.5 N the box no longer removes never reaches it
        report = channel.report(time.monotonic(), 0.5)
        assert report.level == Level.ERROR and 'bias lost after device restart' in report.message
        assert not channel.biased
        ok, message = run_bias([channel], time.monotonic, 0.5)
        assert ok, message
        assert not channel.bias_lost and wait_until(lambda: sink.count() > n + 50)
        with sink.lock:
            assert sink.items[-1][1] == pytest.approx((0.0,) * 6, abs=1e-5)
    finally:
        channel.close()


def test_device_bias_ignores_untared_records_still_queued_from_the_old_stream(
        box: NetFTEmulator) -> None:
    """A busy host: the reader is held up while the box streams, so records sent before the
    bias command (0x0042) are read after it. They carry the old tare and must stay out of the
    host window, which opens with the box's new stream: the result reads zero unloaded."""
    hold = threading.Event()
    held = threading.Event()
    sink = SinkLog()

    def busy_host_sink(finger: int, stamp: float, wrench) -> None:
        if hold.is_set():
            hold.clear()
            held.set()
            time.sleep(0.15)  # the reader thread is descheduled; the box keeps sending
        sink(finger, stamp, wrench)

    channel = open_channel(box, busy_host_sink, bias_mode='device')  # type: ignore[arg-type]
    try:
        assert wait_until(lambda: sink.count() > 50)  # streaming, not tared (−2.5 N on Fz)
        hold.set()
        assert held.wait(2.0)
        time.sleep(0.08)  # ≈ 80 untared records of the old stream queue up in the socket
        ok, message = run_bias([channel], time.monotonic, 1.0)
        assert ok, message
        assert box.biases == 1
        n = sink.count()
        assert wait_until(lambda: sink.count() > n + 50)
        with sink.lock:
            latest = sink.items[-1][1]
        assert latest == pytest.approx((0.0,) * 6, abs=1e-3), latest
    finally:
        channel.close()


def test_records_waiting_unread_are_seen_at_the_socket_while_the_reader_is_held_up(
        box: NetFTEmulator) -> None:
    """`FtChannel.input_pending`: the box keeps sending while the reader is held up (records
    wait in the socket), and nothing waits once the reader has caught up."""
    hold = threading.Event()
    held = threading.Event()
    release = threading.Event()

    def busy_host_sink(finger: int, stamp: float, wrench) -> None:
        if hold.is_set():
            hold.clear()
            held.set()
            release.wait(2.0)

    channel = open_channel(box, busy_host_sink)  # type: ignore[arg-type]
    try:
        assert wait_until(lambda: channel.sample_age(time.monotonic()) < 0.05)
        hold.set()
        assert held.wait(2.0)
        assert wait_until(lambda: channel.input_pending() > 0, 1.0)
        release.set()
        assert wait_until(lambda: channel.input_pending() == 0, 2.0)
    finally:
        release.set()
        channel.close()
    assert channel.input_pending() == 0  # closed


def test_two_boxes_on_one_host_on_their_own_ports() -> None:
    """Per-box UDP and HTTP ports: two emulators on 127.0.0.1, read through their configs."""
    boxes = [NetFTEmulator(scale=SCALE, serve_http=True, offsets=(0.0, 0.0, fz, 0.0, 0.0, 0.0))
             for fz in (1.0, -2.0)]
    sinks = [SinkLog(), SinkLog()]
    channels: list[FtChannel] = []
    try:
        for emu in boxes:
            emu.start()
        from slip_gripper_driver.core.ft_bias import BiasParams
        from slip_gripper_driver.core.netft_params import (FtFinger1Params, FtFinger2Params,
                                                           FtParams)
        ft = FtParams(finger_1=FtFinger1Params('127.0.0.1', boxes[0].address[1],
                                               boxes[0].http_port),
                      finger_2=FtFinger2Params('127.0.0.1', boxes[1].address[1],
                                               boxes[1].http_port))
        ft.validate()
        for (finger, address, port, http_port), sink in zip(ft.boxes(), sinks):
            channel = FtChannel(finger, address, ft.stream, BiasParams(), port=port,
                                http_port=http_port, clock=time.monotonic, sink=sink)
            channel.open()
            channels.append(channel)
        assert all(wait_until(lambda c=c: c.sample_age(time.monotonic()) < 0.1)
                   for c in channels)
        raw = [c.client.latest().wrench[2] for c in channels]
        assert raw == pytest.approx([1.0, -2.0], abs=1e-6)  # each channel hears its own box
        assert [emu.starts for emu in boxes] == [1, 1]
    finally:
        for channel in channels:
            channel.close()
        for emu in boxes:
            emu.stop()


def test_emulator_command_line_reboots_and_error_status(capsys: pytest.CaptureFixture) -> None:
    from slip_gripper_driver.core import netft_emulator
    assert netft_emulator.main(['--port', '0', '--duration', '0.35', '--reboot-every', '0.1',
                                '--status', '0x80020000', '--no-stop-on-bias']) == 0
    out = capsys.readouterr().out
    assert 1 <= int(out.rsplit('reboots: ', 1)[1].split()[0]) <= 3


def test_records_queued_behind_a_held_up_reader_keep_the_time_they_arrived(
        box: NetFTEmulator) -> None:
    """A reader the host held up for 80 ms finds ~80 records queued: each is stamped when it
    reached the host (kernel arrival stamp), not when it was read, so the loop sees how old
    they are (read-time stamps made an 80 ms old record look fresh)."""
    hold = threading.Event()
    held = threading.Event()
    delivered: list[tuple[float, FtSample]] = []

    def sink(sample: FtSample) -> None:
        delivered.append((time.monotonic(), sample))
        if hold.is_set():
            hold.clear()
            held.set()
            time.sleep(0.080)  # the reader thread is held up; the box keeps sending

    host, port = box.address
    cl = NetFTClient(host, port=port, scale=SCALE, clock=time.monotonic, on_sample=sink,
                     start_wait_s=0.2, restart_after_s=0.25)
    cl.open()
    try:
        cl.start()
        assert cl.stats().arrival_stamps, 'this Linux host should give kernel arrival stamps'
        assert wait_until(lambda: len(delivered) > 20)
        hold.set()
        assert held.wait(2.0)
        first_after = len(delivered)
        assert wait_until(lambda: len(delivered) > first_after + 60, 3.0)
        waited = cl.stats().longest_wait_s
    finally:
        cl.close()
    read_t, first = delivered[first_after]
    assert read_t - first.stamp >= 0.050, f'queued record stamped only {read_t - first.stamp} s old'
    stamps = [s.stamp for _, s in delivered[first_after:first_after + 60]]
    assert all(b >= a - 1e-4 for a, b in zip(stamps, stamps[1:]))  # in arrival order
    assert stamps[-1] - stamps[0] >= 0.030  # spread over the hold, not bunched at the read
    assert waited >= 0.050
