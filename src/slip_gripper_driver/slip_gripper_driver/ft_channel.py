# SPDX-License-Identifier: Apache-2.0
"""One Net F/T box as the drivers use it: RDT client + host bias + decimated publishing.

Shared by ``gripper_driver`` (two channels, embedded) and ``netft_driver`` (one channel).
Samples arrive on the client's reader thread stamped with the node clock at datagram arrival;
every valid sample goes to the bias accumulator and to ``sink`` (the grasp-force loop), and
every ``decimation``-th one is published (rclpy publishing is thread-safe). The biased topic
carries only bias-removed wrenches: nothing is published on it before the first bias.

Records that are not measurements (hardware_protocols §4.5) — an error in the status word
(e.g. ``0x80020000``) or a value beyond the measuring range — are counted and reach neither
the sink nor ``finger_k/ft/wrench``; with ``publish_on_error`` they still go to
``finger_k/ft/raw``. After a box restart (§4.7) a bias that existed is reported lost and no
sample reaches the sink until a new bias succeeds: the loop falls back as for stale F/T.

`TopicFtInput` is the ``ft.mode: topic`` counterpart: ``finger_k/ft/wrench`` from a standalone
``netft_driver`` feeds the loop instead of a UDP client. The health travels as the *absence* of
samples, not as a separate status topic: ``WrenchStamped`` has no status field, and a status
topic would race with the wrench stream (a flagged wrench could be used before its flag
arrives, or the flag could be lost), whereas a sample that is never published can never be
used. The gripper driver's existing F/T staleness check therefore sees an erroring,
out-of-range or unbiased box as stale and falls back safely; the reason is in the
``netft_driver``'s diagnostics.
"""
from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass
from typing import Any
from collections.abc import Callable, Sequence

from slip_gripper_driver import gripper_msgs_conv
from slip_cell_common.core.monitors import AgeMonitor, FrequencyMonitor, Level, Report
from slip_gripper_driver.core.ft_bias import (BIAS_TIMEOUT_S, BiasAccumulator, BiasParams,
                                              BiasState, bias_outcome)
from slip_gripper_driver.core.ft_validity import (UNCHECKED, RangeLimits, RecordFlaw,
                                                  merge_limits, record_flaw)
from slip_gripper_driver.core.netft_client import FtSample, NetFTClient, NetFTError, NetFTStats
from slip_gripper_driver.core.netft_config import fetch_netft_config
from slip_gripper_driver.core.netft_params import FtStartParams, FtStreamParams
from slip_gripper_driver.ft_opener import EventSink, FtOpener

#: ``sink(finger, stamp [s], bias-removed wrench or None)`` — None while unbiased.
Sink = Callable[[int, float, 'Sequence[float] | None'], None]
#: ``publish(stamp [s], wrench)``.
Publish = Callable[[float, Sequence[float]], None]
Clock = Callable[[], float]

#: Stream supervision / bias timeout timer period of both drivers [s].
FT_SUPERVISE_PERIOD_S = 0.05
#: Bias message after a box restart (diagnostics and the bias services say this).
BIAS_LOST = 'bias lost after device restart'


@dataclass(frozen=True)
class FtHealth:
    """Validity counters of one channel (for diagnostics).

    Attributes:
        status_errors: Records dropped for an error in the status word.
        out_of_range: Records dropped for a value beyond ``limits``.
        last_flaw: Flaw of the newest record (NONE when it was a measurement).
        bias_lost: A bias existed and the box restarted since; no sample reaches the loop.
        device_restarts: Box restarts seen.
        limits: Measuring range in use [N, N·m] (0 = axis unchecked).
    """

    status_errors: int = 0
    out_of_range: int = 0
    last_flaw: RecordFlaw = RecordFlaw.NONE
    bias_lost: bool = False
    device_restarts: int = 0
    limits: RangeLimits = UNCHECKED


def wrench_publisher(pub: Any, frame_id: str) -> Publish:
    """A `Publish` function for ``pub`` (``geometry_msgs/WrenchStamped`` in ``frame_id``)."""
    def publish(stamp: float, wrench: Sequence[float]) -> None:
        pub.publish(gripper_msgs_conv.wrench_msg(stamp, frame_id, wrench))
    return publish


class FtChannel:
    """A Net F/T box with its host-side bias, for finger ``finger``.

    Args:
        finger: 1 or 2.
        address: Box IP.
        stream: Scale/rate/range/publishing settings (``read_config`` decides where the scale
            and the measuring range come from).
        bias: Bias settings.
        port: RDT UDP port of this box (0 = ``stream.port``).
        http_port: HTTP port of its ``netftapi2.xml`` (0 = ``stream.http_port``).
        start: Stream start retries and wait.
        clock: Node clock [s].
        sink: Receives every accepted sample (bias-removed or None).
        restart_initial_s: First stream-restart delay [s].
        restart_max_s: Largest stream-restart delay [s].
        thread_setup: Called first on the client's reader thread (`realtime.ThreadTuning`).
    """

    def __init__(self, finger: int, address: str, stream: FtStreamParams, bias: BiasParams, *,
                 port: int = 0, http_port: int = 0, start: FtStartParams = FtStartParams(),
                 clock: Clock, sink: Sink | None = None, restart_initial_s: float = 0.5,
                 restart_max_s: float = 5.0,
                 thread_setup: Callable[[], object] | None = None) -> None:
        self.finger = finger
        self._thread_setup = thread_setup
        self.address = address
        self.port = port or stream.port
        self.http_port = http_port or stream.http_port
        self._clock = clock
        self._sink = sink
        self._stream = stream
        self._start = start
        self._restart = (restart_initial_s, restart_max_s)
        self.bias_params = bias
        self.accumulator = bias.accumulator(BIAS_TIMEOUT_S)
        self.client: NetFTClient | None = None
        self.publish_wrench: Publish | None = None
        self.publish_raw: Publish | None = None
        self.publishing = False
        self.decimation = stream.publish_decimation
        self.raw_enabled = stream.publish_raw
        self.publish_on_error = stream.publish_on_error
        self.limits: RangeLimits = merge_limits(stream.measuring_range.limits(), None)
        self._count = 0
        self._bias_done = threading.Event()
        self._status_errors = 0
        self._out_of_range = 0
        self._last_flaw = RecordFlaw.NONE
        self._bias_lost = False
        self._device_restarts = 0
        self._latest_biased: tuple[float, float] | None = None  # (stamp [s], Fz [N])
        self._opener: FtOpener | None = None
        self._client_lock = threading.Lock()
        self._closed = False  # `close` was called: no attempt may publish a client any more

    @property
    def name(self) -> str:
        """``address:port`` of the box."""
        return f'{self.address}:{self.port}'

    def open(self) -> None:
        """Read the box configuration (if asked), open the socket and start streaming.

        Raises:
            NetFTError: The box cannot be read or sends no data (the message names it).
        """
        stream = self._stream
        if stream.read_config:
            config = fetch_netft_config(self.address, http_port=self.http_port)
            scale = config.scale
            self.limits = merge_limits(stream.measuring_range.limits(), config.measuring_range)
        else:
            scale = stream.scale()
            self.limits = merge_limits(stream.measuring_range.limits(), None)
        client = NetFTClient(
            self.address, scale=scale, clock=self._clock, on_sample=self.on_sample,
            port=self.port, start_retries=self._start.start_retries,
            start_wait_s=self._start.start_wait, restart_after_s=stream.restart_after,
            expected_rate_hz=stream.expected_rate,
            restart_initial_s=self._restart[0], restart_max_s=self._restart[1],
            thread_setup=self._thread_setup)
        try:
            client.open()
            client.start()
        except NetFTError:
            client.close()
            raise
        with self._client_lock:  # an attempt of the opener thread may end after `close`
            if not self._closed:
                self.client = client
                return
        client.close()
        raise NetFTError(f'{self.name}: the channel was closed while the box was opened')

    def input_pending(self) -> int:
        """Bytes of records waiting unread at this box's socket (0 when not open)."""
        client = self.client
        return client.input_pending() if client is not None else 0

    def keep_opening(self, first_error: str, on_event: EventSink | None = None) -> None:
        """`open` failed with ``first_error``: retry it on a thread with the restart back-off
        until it succeeds or `close` (see `ft_opener`)."""
        if self._opener is None:
            self._opener = FtOpener(self, first_error, self._restart[0], self._restart[1],
                                    on_event)

    def close(self) -> None:
        """Stop open attempts and streaming (0x0000), end the reader thread, close the socket."""
        self.publishing = False
        with self._client_lock:
            self._closed = True
        opener, self._opener = self._opener, None
        if opener is not None:
            opener.stop()
        with self._client_lock:
            client, self.client = self.client, None
        if client is not None:
            client.close()

    def supervise(self, now: float, receive_timeout_s: float) -> None:
        """Re-request a silent stream (with back-off) and fail a starved bias window."""
        client = self.client
        if client is not None:
            client.supervise(now, receive_timeout_s)
        acc = self.accumulator
        if acc.poll(now) != BiasState.COLLECTING:
            self._check_tare(acc)
            self._bias_done.set()

    def finish_bias_window(self) -> None:
        """End the current window now with what it collected (samples stopped)."""
        acc = self.accumulator
        acc.poll(math.inf)
        self._check_tare(acc)

    def _check_tare(self, acc: BiasAccumulator) -> None:
        """A failed window after a device bias dropped the offsets: the bias is lost (F/T
        kept from the loop until a bias succeeds), as after a box restart."""
        if acc.tare_lost and not acc.biased and not self._bias_lost:
            self._bias_lost = True

    def apply(self, stream: FtStreamParams, bias: BiasParams) -> None:
        """Adopt run-time changes (decimation, raw and error publishing, rates, bias)."""
        self._stream = stream
        self.bias_params = bias
        self.decimation = stream.publish_decimation
        self.raw_enabled = stream.publish_raw
        self.publish_on_error = stream.publish_on_error

    # ------------------------------------------------------------------ bias
    def sample_age(self, now: float) -> float:
        """Seconds since the newest accepted sample (inf without one)."""
        latest = self.client.latest() if self.client is not None else None
        return math.inf if latest is None else now - latest.stamp

    def start_bias(self, t: float) -> None:
        """Begin a bias window at ``t`` [s] (device mode first sends command 0x0042).

        In device mode the box subtracts its own bias; the host window that follows averages
        the residual (≈ 0) so the result is still checked against ``min_samples``. That window
        opens with the first record of the stream the box starts after the bias command:
        records still arriving from the old stream carry the old tare (on a loaded host many
        can wait in the socket) and would shift the offsets.
        """
        b = self.bias_params
        acc = self.accumulator
        if (acc.duration_s, acc.min_samples, acc.settle_samples) != \
                (b.duration, b.min_samples, b.settle_samples):
            fresh = b.accumulator(BIAS_TIMEOUT_S)
            fresh.offsets, fresh.message = acc.offsets, acc.message  # keep the valid bias
            self.accumulator = acc = fresh
        client = self.client
        device = b.mode == 'device' and client is not None
        acc.start(t, after_device_bias=device)
        self._bias_done.clear()  # after start(): a sample in between cannot end the wait
        if client is not None and device:
            client.set_device_bias()  # and the start request: a new stream follows

    def wait_bias(self, timeout_s: float) -> bool:
        """Block until the current window closed or ``timeout_s`` [s] passed."""
        return self._bias_done.wait(timeout_s)

    def normal_force(self, now: float, max_age_s: float) -> float | None:
        """Bias-removed Fz [N] of the newest valid sample no older than ``max_age_s`` [s] at
        ``now``, or None (not biased, bias lost, or no fresh sample)."""
        latest = self._latest_biased
        if latest is None or not self.accumulator.biased or self._bias_lost or \
                now - latest[0] > max_age_s:
            return None
        return latest[1]

    @property
    def biased(self) -> bool:
        """Valid offsets exist."""
        return self.accumulator.biased

    @property
    def bias_lost(self) -> bool:
        """The box restarted after a bias; nothing reaches the loop until a new bias."""
        return self._bias_lost

    @property
    def bias_lost_reason(self) -> str:
        """Why the bias is lost: a box restart, or a failed device bias."""
        acc = self.accumulator
        return acc.message if acc.tare_lost else BIAS_LOST

    def health(self) -> FtHealth:
        """Validity counters (diagnostics)."""
        return FtHealth(self._status_errors, self._out_of_range, self._last_flaw,
                        self._bias_lost, self._device_restarts, self.limits)

    # ------------------------------------------------------------------ samples
    def on_sample(self, sample: FtSample) -> None:
        """One accepted record (the client's reader thread): validity, bias path, loop sink,
        publishing."""
        if sample.device_restart:
            self._on_device_restart()
        flaw = record_flaw(sample.status, sample.wrench, self.limits)
        self._last_flaw = flaw
        self._count += 1
        publish = self.publishing and self._count % self.decimation == 0
        if flaw != RecordFlaw.NONE:
            # Not a measurement: never averaged into a bias, never fed to the loop, never on
            # finger_k/ft/wrench (topic mode would feed it to the loop).
            if flaw == RecordFlaw.STATUS_ERROR:
                self._status_errors += 1
            else:
                self._out_of_range += 1
            if publish and self.publish_on_error and self.raw_enabled and \
                    self.publish_raw is not None:
                self.publish_raw(sample.stamp, sample.wrench)
            return
        acc = self.accumulator
        biased = acc.add(sample.stamp, sample.wrench, sample.new_stream)
        self._check_tare(acc)
        if acc.state != BiasState.COLLECTING and not self._bias_done.is_set():
            self._bias_done.set()
        if self._bias_lost and acc.biased:
            self._bias_lost = False  # a new bias succeeded after the restart
        if biased is not None and not self._bias_lost:
            self._latest_biased = (sample.stamp, biased[2])
        if self._sink is not None and not self._bias_lost:
            self._sink(self.finger, sample.stamp, biased)
        if not publish:
            return
        if biased is not None and self.publish_wrench is not None:
            self.publish_wrench(sample.stamp, biased)
        if self.raw_enabled and self.publish_raw is not None:
            self.publish_raw(sample.stamp, sample.wrench)

    def _on_device_restart(self) -> None:
        """The box restarted: its device bias is gone (and a host bias was taken on top of
        whatever the box subtracted), so a bias that existed — or was being taken — is lost.
        Re-biasing needs unloaded pads, which this channel cannot know: it reports instead."""
        self._device_restarts += 1
        acc = self.accumulator
        if acc.biased or acc.state == BiasState.COLLECTING:
            self._bias_lost = True
            acc.clear(BIAS_LOST)
            self._bias_done.set()

    # ------------------------------------------------------------------ diagnostics
    def stats(self, now: float) -> NetFTStats | None:
        """Client counters (None when not open)."""
        return self.client.stats(now) if self.client is not None else None

    def report(self, now: float, stale_after_s: float) -> Report:
        """Diagnostic report: rate vs expected, records, status word, bias, sample age."""
        s = self.stats(now)
        if s is None:
            opener = self._opener
            if opener is not None:
                o = opener.status()
                return Report(Level.ERROR, (
                    f'{self.name}: not open after {o.attempts} attempts ({o.last_error}); '
                    f'next attempt in {o.retry_in_s:.1f} s; the loop runs without this F/T'),
                    (('address', self.name), ('open_attempts', str(o.attempts)),
                     ('last_error', o.last_error)))
            return Report(Level.STALE, f'{self.name}: not open')
        return ft_report(s, now, self._stream.expected_rate, self._stream.rate_tolerance,
                         stale_after_s, self.accumulator, self.health())


def ft_report(s: NetFTStats, now: float, expected_hz: float, tolerance: float,
              stale_after_s: float, acc: BiasAccumulator,
              health: FtHealth = FtHealth()) -> Report:
    """ROS-free diagnostic report of one box (levels per ros_interfaces §8)."""
    age = now - s.last_stamp if math.isfinite(s.last_stamp) else math.inf
    values = (
        ('address', s.address), ('rate_hz', f'{s.rate_hz:.1f}'),
        ('expected_hz', f'{expected_hz:.1f}'), ('age_s', f'{age:.4f}'),
        ('records', str(s.accepted)), ('lost', str(s.lost)),
        ('duplicates', str(s.duplicates)), ('out_of_order', str(s.out_of_order)),
        ('bad_datagrams', str(s.bad_datagrams)), ('ft_stalls', str(s.ft_stalls)),
        ('ft_restarts', str(s.ft_restarts)), ('stream_restarts', str(s.restarts)),
        ('new_streams', str(s.new_streams)), ('bias_restarts', str(s.bias_restarts)),
        ('device_restarts', str(health.device_restarts)),
        ('status_errors', str(health.status_errors)), ('out_of_range', str(health.out_of_range)),
        ('measuring_range', ' '.join(f'{v:g}' for v in health.limits)),
        ('socket_errors', str(s.socket_errors)),
        ('arrival_stamps', 'kernel' if s.arrival_stamps else 'read time'),
        ('longest_wait_s', f'{s.longest_wait_s:.4f}'), ('status', f'0x{s.status:08X}'),
        ('status_text', s.status_text), ('latched_status', f'0x{s.latched_status:08X}'),
        ('biased', str(acc.biased).lower()), ('bias', acc.message),
        ('last_error', s.last_error))
    if not math.isfinite(age):
        return Report(Level.ERROR, f'{s.address}: no data', values)
    if age > stale_after_s:
        return Report(Level.ERROR, f'{s.address}: no data for {age:.3f} s', values)
    if health.bias_lost:
        reason = acc.message if acc.tare_lost else BIAS_LOST
        return Report(Level.ERROR, f'{s.address}: {reason}; F/T withheld from the loop '
                      'until biased again (pads unloaded)', values)
    if s.status_level == Level.ERROR:
        return Report(Level.ERROR, f'{s.address}: {s.status_text}; records dropped', values)
    if health.last_flaw == RecordFlaw.OUT_OF_RANGE:
        return Report(Level.ERROR, f'{s.address}: beyond the measuring range; records dropped',
                      values)
    problems = []
    if abs(s.rate_hz - expected_hz) > tolerance * expected_hz:
        problems.append(f'rate {s.rate_hz:.0f} Hz outside {expected_hz:.0f} Hz '
                        f'±{100 * tolerance:.0f} %')
    if s.status_level == Level.WARN:
        problems.append(s.status_text)
    if not acc.biased:
        # The bias-removed wrench topic publishes nothing until then: say so where users look.
        problems.append('not biased: the wrench topic stays silent until gripper/bias_ft')
    if problems:
        return Report(Level.WARN, f'{s.address}: ' + '; '.join(problems), values)
    return Report(Level.OK, f'{s.address}: streaming, biased', values)


def run_bias(channels: Sequence[FtChannel], now: Clock,
             fresh_within_s: float) -> tuple[bool, str]:
    """Bias every channel over one window and wait for the result (blocks ≤ duration + 0.6 s).

    Fails at once unless every box has produced a sample within ``fresh_within_s`` [s] and
    its newest record is a valid measurement (no error status, within the measuring range).

    Returns:
        ``(success, message)``; the message names each box.
    """
    t = now()
    silent = [c.name for c in channels if c.sample_age(t) > fresh_within_s]
    if silent:
        return False, f'no recent F/T data from {", ".join(silent)}; bias refused'
    flawed = [f'{c.name} ({c.health().last_flaw.name.lower().replace("_", " ")})'
              for c in channels if c.health().last_flaw != RecordFlaw.NONE]
    if flawed:
        return False, f'F/T records not valid from {", ".join(flawed)}; bias refused'
    for channel in channels:
        channel.start_bias(t)
    deadline = time.monotonic() + max(c.bias_params.duration for c in channels) + \
        BIAS_TIMEOUT_S + 0.1
    for channel in channels:
        if not channel.wait_bias(max(0.0, deadline - time.monotonic())):
            # The window never closed (samples stopped): end it now with what it collected.
            channel.finish_bias_window()
    return bias_outcome([(c.name, c.accumulator) for c in channels])


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
            # netft_driver withholds error, out-of-range and unbiased samples: silence is
            # how the box's health reaches this node (see the module docstring).
            return Report(Level.ERROR, f'{self.topic}: no data for {age:.3f} s (box silent, '
                          'erroring, out of range or unbiased: see the netft_driver '
                          'diagnostics)', values)
        return Report(rate.level, f'{self.topic}: {rate.message}', values)
