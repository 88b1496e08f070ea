# SPDX-License-Identifier: Apache-2.0
"""One Net F/T box as the drivers use it: RDT client + host bias + decimated publishing.

Shared by ``gripper_driver`` (two channels, embedded) and ``netft_driver`` (one channel).
Samples arrive on the client's reader thread stamped with the node clock at datagram arrival;
every accepted sample goes to the bias accumulator and to ``sink`` (the grasp-force loop), and
every ``decimation``-th one is published (rclpy publishing is thread-safe). The biased topic
carries only bias-removed wrenches: nothing is published on it before the first bias.

`TopicFtInput` is the ``ft.mode: topic`` counterpart: ``finger_k/ft/wrench`` from a standalone
``netft_driver`` feeds the loop instead of a UDP client.
"""
from __future__ import annotations

import math
import threading
import time
from typing import Any, Callable, Sequence

from slip_gripper_driver import ros_conv
from slip_cell_common.core.monitors import AgeMonitor, FrequencyMonitor, Level, Report
from slip_gripper_driver.core.netft import (BiasAccumulator, BiasParams, BiasState, FtParams,
                                            FtSample, NetFTClient, NetFTError, NetFTStats,
                                            fetch_netft_config)

#: ``sink(finger, stamp [s], bias-removed wrench or None)`` — None while unbiased.
Sink = Callable[[int, float, 'Sequence[float] | None'], None]
#: ``publish(stamp [s], wrench)``.
Publish = Callable[[float, Sequence[float]], None]
Clock = Callable[[], float]

#: Stream supervision / bias timeout timer period of both drivers [s].
FT_SUPERVISE_PERIOD_S = 0.05
#: Extra time for the bias window to close after ``bias.duration`` [s].
BIAS_TIMEOUT_S = 0.5


def wrench_publisher(pub: Any, frame_id: str) -> Publish:
    """A `Publish` function for ``pub`` (``geometry_msgs/WrenchStamped`` in ``frame_id``)."""
    def publish(stamp: float, wrench: Sequence[float]) -> None:
        pub.publish(ros_conv.wrench_msg(stamp, frame_id, wrench))
    return publish


class FtChannel:
    """A Net F/T box with its host-side bias, for finger ``finger``.

    Args:
        finger: 1 or 2.
        address: Box IP.
        ft: Scale/rate/publishing settings (``read_config`` decides where the scale comes from).
        bias: Bias settings.
        clock: Node clock [s].
        sink: Receives every accepted sample (bias-removed or None).
        restart_initial_s: First stream-restart delay [s].
        restart_max_s: Largest stream-restart delay [s].
        thread_setup: Called first on the client's reader thread (`realtime.ThreadTuning`).
    """

    def __init__(self, finger: int, address: str, ft: FtParams, bias: BiasParams, *,
                 clock: Clock, sink: Sink | None = None, restart_initial_s: float = 0.5,
                 restart_max_s: float = 5.0,
                 thread_setup: Callable[[], object] | None = None) -> None:
        self.finger = finger
        self._thread_setup = thread_setup
        self.address = address
        self.port = ft.port
        self._clock = clock
        self._sink = sink
        self._ft = ft
        self._restart = (restart_initial_s, restart_max_s)
        self.bias_params = bias
        self.accumulator = bias.accumulator(BIAS_TIMEOUT_S)
        self.client: NetFTClient | None = None
        self.publish_wrench: Publish | None = None
        self.publish_raw: Publish | None = None
        self.publishing = False
        self.decimation = ft.publish_decimation
        self.raw_enabled = ft.publish_raw
        self._count = 0
        self._bias_done = threading.Event()

    @property
    def name(self) -> str:
        """``address:port`` of the box."""
        return f'{self.address}:{self.port}'

    def open(self) -> None:
        """Read the box configuration (if asked), open the socket and start streaming.

        Raises:
            NetFTError: The box cannot be read or sends no data (the message names it).
        """
        ft = self._ft
        if ft.read_config:
            scale = fetch_netft_config(self.address).scale
        else:
            scale = ft.scale()
        self.client = NetFTClient(
            self.address, scale=scale, clock=self._clock, on_sample=self._on_sample,
            port=ft.port, start_retries=ft.start_retries, start_wait_s=ft.start_wait,
            restart_initial_s=self._restart[0], restart_max_s=self._restart[1],
            thread_setup=self._thread_setup)
        try:
            self.client.open()
            self.client.start()
        except NetFTError:
            self.client.close()
            self.client = None
            raise

    def close(self) -> None:
        """Stop streaming (0x0000), end the reader thread and close the socket."""
        self.publishing = False
        if self.client is not None:
            self.client.close()
            self.client = None

    def supervise(self, now: float, receive_timeout_s: float) -> None:
        """Re-request a silent stream (with back-off) and fail a starved bias window."""
        if self.client is not None:
            self.client.supervise(now, receive_timeout_s)
        if self.accumulator.poll(now) != BiasState.COLLECTING:
            self._bias_done.set()

    def apply(self, ft: FtParams, bias: BiasParams) -> None:
        """Adopt run-time changes (decimation, raw publishing, rates, bias settings)."""
        self._ft = ft
        self.bias_params = bias
        self.decimation = ft.publish_decimation
        self.raw_enabled = ft.publish_raw

    # ------------------------------------------------------------------ bias
    def sample_age(self, now: float) -> float:
        """Seconds since the newest accepted sample (inf without one)."""
        latest = self.client.latest() if self.client is not None else None
        return math.inf if latest is None else now - latest.stamp

    def start_bias(self, t: float) -> None:
        """Begin a bias window at ``t`` [s] (device mode first sends command 0x0042).

        In device mode the box subtracts its own bias; the host window that follows averages
        the residual (≈ 0) so the result is still checked against ``min_samples``.
        """
        b = self.bias_params
        acc = self.accumulator
        if (acc.duration_s, acc.min_samples, acc.settle_samples) != \
                (b.duration, b.min_samples, b.settle_samples):
            fresh = b.accumulator(BIAS_TIMEOUT_S)
            fresh.offsets, fresh.message = acc.offsets, acc.message  # keep the valid bias
            self.accumulator = acc = fresh
        if b.mode == 'device' and self.client is not None:
            self.client.set_device_bias()
        acc.start(t)
        self._bias_done.clear()  # after start(): a sample in between cannot end the wait

    def wait_bias(self, timeout_s: float) -> bool:
        """Block until the current window closed or ``timeout_s`` [s] passed."""
        return self._bias_done.wait(timeout_s)

    @property
    def biased(self) -> bool:
        """Valid offsets exist."""
        return self.accumulator.biased

    # ------------------------------------------------------------------ samples
    def _on_sample(self, sample: FtSample) -> None:
        acc = self.accumulator
        biased = acc.add(sample.stamp, sample.wrench)
        if acc.state != BiasState.COLLECTING and not self._bias_done.is_set():
            self._bias_done.set()
        if self._sink is not None:
            self._sink(self.finger, sample.stamp, biased)
        self._count += 1
        if not self.publishing or self._count % self.decimation:
            return
        if biased is not None and self.publish_wrench is not None:
            self.publish_wrench(sample.stamp, biased)
        if self.raw_enabled and self.publish_raw is not None:
            self.publish_raw(sample.stamp, sample.wrench)

    # ------------------------------------------------------------------ diagnostics
    def stats(self, now: float) -> NetFTStats | None:
        """Client counters (None when not open)."""
        return self.client.stats(now) if self.client is not None else None

    def report(self, now: float, stale_after_s: float) -> Report:
        """Diagnostic report: rate vs expected, records, status word, bias, sample age."""
        s = self.stats(now)
        if s is None:
            return Report(Level.STALE, f'{self.name}: not open')
        return ft_report(s, now, self._ft.expected_rate, self._ft.rate_tolerance,
                         stale_after_s, self.accumulator)


def ft_report(s: NetFTStats, now: float, expected_hz: float, tolerance: float,
              stale_after_s: float, acc: BiasAccumulator) -> Report:
    """ROS-free diagnostic report of one box (levels per ros_interfaces §8)."""
    age = now - s.last_stamp if math.isfinite(s.last_stamp) else math.inf
    values = (
        ('address', s.address), ('rate_hz', f'{s.rate_hz:.1f}'),
        ('expected_hz', f'{expected_hz:.1f}'), ('age_s', f'{age:.4f}'),
        ('records', str(s.accepted)), ('lost', str(s.lost)),
        ('duplicates', str(s.duplicates)), ('out_of_order', str(s.out_of_order)),
        ('bad_datagrams', str(s.bad_datagrams)), ('ft_stalls', str(s.ft_stalls)),
        ('ft_restarts', str(s.ft_restarts)), ('stream_restarts', str(s.restarts)),
        ('socket_errors', str(s.socket_errors)), ('status', f'0x{s.status:08X}'),
        ('status_text', s.status_text), ('latched_status', f'0x{s.latched_status:08X}'),
        ('biased', str(acc.biased).lower()), ('bias', acc.message),
        ('last_error', s.last_error))
    if not math.isfinite(age):
        return Report(Level.ERROR, f'{s.address}: no data', values)
    if age > stale_after_s:
        return Report(Level.ERROR, f'{s.address}: no data for {age:.3f} s', values)
    if s.status_level == Level.ERROR:
        return Report(Level.ERROR, f'{s.address}: {s.status_text}', values)
    problems = []
    if abs(s.rate_hz - expected_hz) > tolerance * expected_hz:
        problems.append(f'rate {s.rate_hz:.0f} Hz outside {expected_hz:.0f} Hz '
                        f'±{100 * tolerance:.0f} %')
    if s.status_level == Level.WARN:
        problems.append(s.status_text)
    if not acc.biased:
        problems.append('not biased')
    if problems:
        return Report(Level.WARN, f'{s.address}: ' + '; '.join(problems), values)
    return Report(Level.OK, f'{s.address}: streaming, biased', values)


def run_bias(channels: Sequence[FtChannel], now: Clock,
             fresh_within_s: float) -> tuple[bool, str]:
    """Bias every channel over one window and wait for the result (blocks ≤ duration + 0.6 s).

    Fails at once unless every box has produced a sample within ``fresh_within_s`` [s].

    Returns:
        ``(success, message)``; the message names each box.
    """
    t = now()
    silent = [c.name for c in channels if c.sample_age(t) > fresh_within_s]
    if silent:
        return False, f'no recent F/T data from {", ".join(silent)}; bias refused'
    for channel in channels:
        channel.start_bias(t)
    deadline = time.monotonic() + max(c.bias_params.duration for c in channels) + \
        BIAS_TIMEOUT_S + 0.1
    for channel in channels:
        if not channel.wait_bias(max(0.0, deadline - time.monotonic())):
            # The window never closed (samples stopped): end it now with what it collected.
            channel.accumulator.poll(math.inf)
    ok = all(c.accumulator.state == BiasState.DONE for c in channels)
    return ok, '; '.join(f'{c.name}: {c.accumulator.message}' for c in channels)


class TopicFtInput:
    """``finger_k/ft/wrench`` consumed from a topic (``ft.mode: topic``).

    Args:
        finger: 1 or 2.
        topic: Topic name (for reports).
        expected_hz: Expected message rate [Hz].
        tolerance: Relative rate tolerance.
        sink: Receives every sample (already bias-removed by the publisher).
    """

    def __init__(self, finger: int, topic: str, expected_hz: float, tolerance: float,
                 sink: Sink) -> None:
        self.finger = finger
        self.topic = topic
        self._sink = sink
        self._lock = threading.Lock()
        self._rate = FrequencyMonitor(expected_hz, tolerance)
        self._age = AgeMonitor(1.0)
        self.count = 0

    def on_wrench(self, stamp: float, wrench: Sequence[float]) -> None:
        """One bias-removed wrench stamped ``stamp`` [s]."""
        with self._lock:
            self._rate.tick(stamp)
            self._age.tick(stamp)
            self.count += 1
        self._sink(self.finger, stamp, wrench)

    def report(self, now: float, stale_after_s: float) -> Report:
        """Rate and age of the subscription."""
        with self._lock:
            rate = self._rate.report(now)
            age = self._age.age(now)
        values = (('topic', self.topic), *rate.values, ('age_s', f'{age:.4f}'),
                  ('messages', str(self.count)))
        if age > stale_after_s:
            return Report(Level.ERROR, f'{self.topic}: no data for {age:.3f} s', values)
        return Report(rate.level, f'{self.topic}: {rate.message}', values)
