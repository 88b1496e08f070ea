# SPDX-License-Identifier: Apache-2.0
"""Sensor session: stamped device lines in, validated SI samples and diagnostics out (ROS-free).

`SensorSession` is the core the lifecycle node wraps. The reader thread hands it bytes or lines
with their **acquisition** stamp (node clock when the bytes arrived, requirement HW-11); it
returns one `Sample` per velocity line and keeps everything the diagnostics need.

Validity (requirement HW-10):

* Fused mode (``c0``): vx, vy [m/s], ω [rad/s] in the sensor frame, all valid.
* Single-chip mode (``c1..c3``): the line carries chip k's **uncalibrated** vx, vy in the
  **chip frame** and a stale fused ω. The sample therefore has ``valid = False``, NaN twist
  and ω, and the chip reading in `Sample.chip_vx` / `Sample.chip_vy` (for the chips topic).
* For ``chip_mode_settle`` seconds after a mode command the mode of arriving lines is unknown:
  invalid. Likewise after a boot banner (device restarted: calibration lost, until the node
  re-initialises) and after a different name showed up on the port.
* Chip re-sync: from a ``resynch`` notice on, the firmware's lines carry no (or partial)
  motion although they look like valid zeros. Samples stay invalid until a velocity line
  follows a full serial period without a new notice (`resync.ResyncTracker`); there is no
  end-of-re-sync line and no timeout that would declare the chip healthy. The ``chips``
  diagnostics report the re-sync (WARN, ERROR once it lasts longer than ``resync_timeout``,
  naming the chip that does not answer) and return to OK when the notices stop.

Pose integration (host side, sensor frame, like the reference): every valid fused line adds
``v · period`` over its own firmware period, estimated from acquisition stamps; lines read
together after a reader stall share the stall's time instead of losing it
(`pose_integration.PoseIntegrator`; ``max_integration_dt`` bounds what a gap without lines
adds, 1/``expected_rate`` is the nominal period).
"""
from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field

from slip_cell_common.core.monitors import AgeMonitor, FrequencyMonitor, Level, Report
from slip_velocity_sensor.core import protocol
from slip_velocity_sensor.core.pose_integration import PoseIntegrator
from slip_velocity_sensor.core.protocol import (BadLine, BootLine, LineParser, LineSplitter,
                                                NameLine, ParsedLine, ParserCounters,
                                                ProductIdLine, ProtocolLimits, ResyncLine,
                                                TextLine, VelocityLine)
from slip_velocity_sensor.core.resync import ResyncTracker, describe_product_ids

NAN = math.nan


@dataclass(frozen=True)
class SessionParams:
    """Host processing settings of one sensor (SI)."""

    stale_after: float = field(default=0.050, metadata={
        'unit': 's', 'range': (0.001, 10.0),
        'description': 'a valid sample older than this is stale for the slip controllers'})
    expected_rate: float = field(default=146.0, metadata={
        'unit': 'Hz', 'range': (1.0, 10000.0),
        'description': 'centre of the line-rate window; 1/expected_rate is the nominal period'})
    rate_tolerance: float = field(default=0.15, metadata={
        'unit': '-', 'range': (0.0, 1.0),
        'description': 'allowed relative rate deviation (146 Hz ±15 %: 124-168 Hz)'})
    integrate_pose: bool = field(default=True, metadata={
        'description': 'integrate x, y, theta from valid fused samples'})
    max_integration_dt: float = field(default=0.050, metadata={
        'unit': 's', 'range': (0.001, 1.0),
        'description': 'most time one line covers after a gap without lines'})
    chip_mode_settle: float = field(default=0.025, metadata={
        'unit': 's', 'range': (0.0, 1.0),
        'description': 'samples are invalid this long after a chip-mode command'})
    resync_timeout: float = field(default=0.2, metadata={
        'unit': 's', 'range': (0.0, 10.0),
        'description': 'a chip re-sync lasting longer than this is an ERROR (chip missing)'})


@dataclass(frozen=True, slots=True)
class Sample:
    """One velocity sample (one ``v`` line), SI.

    Attributes:
        stamp: Acquisition time of the line [s].
        vx: Surface velocity relative to the pad, sensor frame [m/s]; NaN unless fused & valid.
        vy: [m/s]; NaN unless fused and valid.
        omega: Angular rate [rad/s]; NaN unless fused and valid.
        x: Integrated displacement since the last pose reset, sensor frame [m].
        y: [m].
        theta: Integrated angle [rad].
        chip_mode: 0 fused, 1..3 single chip (-1 while a mode switch settles).
        valid: True when vx, vy, omega are a valid sensor-frame twist.
        chip_vx: Single-chip mode: chip k's raw tangential speed [m/s] (chip frame, not
            calibrated); NaN in fused mode.
        chip_vy: Single-chip mode: raw radial speed [m/s]; NaN in fused mode.
        excluded_chip: Chip dropped by outlier rejection, -1 for none or unknown (the current
            firmware does not report it).
        residual_ratio: Fusion residual ratio, NaN unless reported.
    """

    stamp: float
    vx: float
    vy: float
    omega: float
    x: float
    y: float
    theta: float
    chip_mode: int
    valid: bool
    chip_vx: float = NAN
    chip_vy: float = NAN
    excluded_chip: int = -1
    residual_ratio: float = NAN


@dataclass(frozen=True)
class SessionDiagnostics:
    """Snapshot of everything the diagnostics report (SI, times in s)."""

    port: str
    name: str
    initialised: bool
    calibration_source: str
    calibration_uploaded: bool
    speed_term: str
    chip_mode: int
    rate_hz: float
    age: float
    stale: bool
    samples: int
    valid_samples: int
    counters: ParserCounters
    resync_active: bool
    resyncs: int
    resync_duration: float
    product_ids: tuple[int, ...]
    device_restarts: int
    name_conflicts: int
    dt_skipped: int
    dt_capped: int
    clock_jumps: int
    last_bad_reason: str
    last_text: str
    link_error: str


class SensorSession:
    """Host-side state of one velocity sensor; see the module docstring.

    Thread-safe: the reader thread feeds lines while service callbacks reset the pose or switch
    the chip mode and a timer reads diagnostics (one short lock per call).

    Args:
        params: Processing settings.
        port: Port path or URL (diagnostics and errors).
        expected_name: Name the sensor must answer (a different name on the port invalidates).
        limits: Parser plausibility limits.
    """

    def __init__(self, params: SessionParams | None = None, *, port: str = '',
                 expected_name: str = '', limits: ProtocolLimits | None = None) -> None:
        self.params = params if params is not None else SessionParams()
        self.port = port
        self.expected_name = expected_name
        self.parser = LineParser(limits)
        self.splitter = LineSplitter(self.parser.limits.max_line_bytes)
        self._rate = FrequencyMonitor(self.params.expected_rate, self.params.rate_tolerance)
        self._age = AgeMonitor(self.params.stale_after)
        self._initialised = False
        self._calibration_source = ''
        self._calibration_uploaded = False
        self._speed_term = ''
        self._chip_mode = 0
        self._pending_mode: int | None = None
        self._mode_settled_at = -math.inf
        self._resync = ResyncTracker()
        self._device_restarts = 0
        self._booting = False
        self._identity_ok = True
        self._name_conflicts = 0
        self._last_bad_reason = ''
        self._last_text = ''
        self._link_error = ''
        self._samples = 0
        self._valid_samples = 0
        self._pose = PoseIntegrator(1.0 / self.params.expected_rate,
                                    self.params.max_integration_dt)
        self._latest: Sample | None = None
        self._lock = threading.RLock()

    # ---------------------------------------------------------------- lifecycle hooks

    def mark_initialised(self, *, calibration_source: str, calibration_uploaded: bool,
                         speed_term: str, chip_mode: int = 0) -> None:
        """Record a successful handshake + upload (call after every (re)connect).

        Clears the device-restart, name-conflict and link-error conditions.

        Args:
            calibration_source: Where the uploaded calibration came from (file path, ...).
            calibration_uploaded: Whether the upload commands were sent.
            speed_term: The ``calibration.speed_term`` in use.
            chip_mode: Chip mode the initialisation left the device in.
        """
        with self._lock:
            self._initialised = True
            self._identity_ok = True
            self._calibration_source = calibration_source
            self._calibration_uploaded = calibration_uploaded
            self._speed_term = speed_term
            self._chip_mode = chip_mode
            self._pending_mode = None
            self._link_error = ''
            self._pose.reanchor()

    def link_lost(self, message: str) -> None:
        """Record a link failure (port named in ``message``); samples stop until re-init."""
        with self._lock:
            self._link_error = message
            self._initialised = False
            self._pose.reanchor()
            self.splitter.clear()

    def update_params(self, params: SessionParams) -> None:
        """Apply new processing settings at run time (monitors keep their history)."""
        with self._lock:
            self.params = params
            self._rate.expected_hz = params.expected_rate
            self._rate.tolerance = params.rate_tolerance
            self._age.stale_after_s = params.stale_after
            self._pose.configure(1.0 / params.expected_rate, params.max_integration_dt)

    def chip_mode_sent(self, mode: int, t: float) -> None:
        """Record that ``c<mode>`` was written at ``t`` [s] (see `protocol.chip_mode_command`).

        Lines arriving within ``chip_mode_settle`` are invalid; later lines are in ``mode``.
        """
        protocol.chip_mode_command(mode)  # validates
        with self._lock:
            self._pending_mode = mode
            self._mode_settled_at = t + self.params.chip_mode_settle
            self._pose.reanchor()

    def reset_pose(self) -> None:
        """Zero the integrated x, y, θ (the time anchor is kept)."""
        with self._lock:
            self._pose.reset_pose()

    def reset(self) -> None:
        """Forget all time-dependent state (call when the clock jumped backwards).

        Pose, latest sample, rate and age monitors are reset; counters are kept, and so is an
        open chip re-sync (it ends by the device's lines, not by time).
        """
        with self._lock:
            self._pose.reset_pose()
            self._pose.reanchor()
            self._latest = None
            self._rate = FrequencyMonitor(self.params.expected_rate, self.params.rate_tolerance)
            self._age = AgeMonitor(self.params.stale_after)
            self._resync.forget_times()
            if self._pending_mode is not None:
                self._mode_settled_at = -math.inf

    # ---------------------------------------------------------------- data path

    def feed(self, t: float, data: bytes) -> list[Sample]:
        """Process bytes that arrived at ``t`` [s]; returns the samples of complete lines."""
        out = []
        for line, overflow in self.splitter.feed(data):
            sample = self.handle_line(t, line, overflow)
            if sample is not None:
                out.append(sample)
        return out

    def handle_line(self, t: float, line: bytes, overflow: bool = False) -> Sample | None:
        """Process one line (without terminator) that arrived at ``t`` [s].

        Args:
            t: Acquisition stamp [s].
            line: Line bytes (a trailing ``\\r`` is ignored).
            overflow: The line reader truncated the line (counted as bad).
        """
        return self.handle_parsed(t, self.parser.parse(line, overflow))

    def handle_parsed(self, t: float, parsed: ParsedLine) -> Sample | None:
        """Process one already parsed line; returns a sample for velocity lines."""
        with self._lock:
            return self._handle(t, parsed)

    def _handle(self, t: float, parsed: ParsedLine) -> Sample | None:
        if isinstance(parsed, VelocityLine):
            return self._on_velocity(t, parsed)
        if isinstance(parsed, BadLine):
            self._last_bad_reason = parsed.reason
        elif isinstance(parsed, ResyncLine):
            self._resync.on_notice(t)
        elif isinstance(parsed, ProductIdLine):
            self._resync.on_product_ids(parsed.ids)
        elif isinstance(parsed, BootLine):
            if not self._booting:  # a banner has several lines: count the restart once
                self._device_restarts += 1
            self._booting = True
            self._initialised = False
            self._chip_mode = 0  # firmware default after a restart
            self._pending_mode = None
            self._pose.reanchor()
        elif isinstance(parsed, NameLine):
            if self.expected_name and parsed.name != self.expected_name:
                self._name_conflicts += 1
                self._identity_ok = False
                self._pose.reanchor()
        elif isinstance(parsed, TextLine):
            self._last_text = parsed.text
        return None

    def _on_velocity(self, t: float, line: VelocityLine) -> Sample:
        p = self.params
        self._booting = False
        self._samples += 1
        self._rate.tick(t)
        if self._pending_mode is not None and t >= self._mode_settled_at:
            self._chip_mode, self._pending_mode = self._pending_mode, None
        resync_free = self._resync.on_velocity_line(t)
        usable = (self._initialised and self._identity_ok and self._pending_mode is None
                  and resync_free)
        mode = -1 if self._pending_mode is not None else self._chip_mode
        if not usable or mode != 0:
            self._pose.reanchor()
            chip_vx = line.vx if usable and mode > 0 else NAN
            chip_vy = line.vy if usable and mode > 0 else NAN
            pose = self._pose
            sample = Sample(t, NAN, NAN, NAN, pose.x, pose.y, pose.theta, mode, False,
                            chip_vx, chip_vy)
            self._latest = sample
            return sample
        pose = self._pose
        if p.integrate_pose:
            pose.add(t, line.vx, line.vy, line.omega)
        self._valid_samples += 1
        self._age.tick(t)
        sample = Sample(t, line.vx, line.vy, line.omega, pose.x, pose.y, pose.theta, 0, True)
        self._latest = sample
        return sample

    def stale_marker(self, t: float) -> Sample | None:
        """An invalid sample stamped ``t`` when the stream went stale; None otherwise.

        Returned once per stale period: when the newest sample is valid but older than
        ``stale_after`` at ``t`` [s] (link lost, device silent). The marker carries NaN
        velocities, the integrated pose and ``valid = False``, so a consumer that looks only at
        the newest message sees the loss; no old sample is ever re-issued as new. It becomes
        the newest sample, so the next marker needs a new valid sample first.
        """
        with self._lock:
            latest = self._latest
            if latest is None or not latest.valid or t - latest.stamp <= self.params.stale_after:
                return None
            pose = self._pose
            marker = Sample(t, NAN, NAN, NAN, pose.x, pose.y, pose.theta, self.chip_mode, False)
            self._latest = marker
            return marker

    # ---------------------------------------------------------------- queries

    @property
    def latest(self) -> Sample | None:
        """The newest sample (valid or not), or None."""
        return self._latest

    @property
    def chip_mode(self) -> int:
        """Chip mode of the device as far as the host knows (-1 while a switch settles)."""
        return -1 if self._pending_mode is not None else self._chip_mode

    @property
    def target_chip_mode(self) -> int:
        """The mode the device is in or is switching to (never -1)."""
        return self._pending_mode if self._pending_mode is not None else self._chip_mode

    @property
    def initialised(self) -> bool:
        """True after `mark_initialised` until a link loss or device restart."""
        return self._initialised

    @property
    def needs_reinitialisation(self) -> bool:
        """True when the device restarted or another name appeared: redo the handshake."""
        return not self._initialised or not self._identity_ok

    def age(self, t: float) -> float:
        """Seconds since the newest *valid* sample at time ``t`` (inf when none)."""
        with self._lock:
            return self._age.age(t)

    def is_stale(self, t: float) -> bool:
        """True when no valid sample arrived within ``stale_after`` before ``t``."""
        with self._lock:
            return not self._age.fresh(t)

    def rate_hz(self, t: float) -> float:
        """Velocity lines per second over the last second before ``t`` [Hz]."""
        with self._lock:
            return self._rate.rate(t)

    def diagnostics(self, t: float) -> SessionDiagnostics:
        """Snapshot at time ``t`` [s]."""
        with self._lock:
            return self._diagnostics(t)

    def _diagnostics(self, t: float) -> SessionDiagnostics:
        return SessionDiagnostics(
            port=self.port, name=self.expected_name, initialised=self._initialised,
            calibration_source=self._calibration_source,
            calibration_uploaded=self._calibration_uploaded, speed_term=self._speed_term,
            chip_mode=self.chip_mode, rate_hz=self.rate_hz(t), age=self.age(t),
            stale=self.is_stale(t), samples=self._samples, valid_samples=self._valid_samples,
            counters=self.parser.counters, resync_active=self._resync.active,
            resyncs=self._resync.episodes, resync_duration=self._resync.duration(t),
            product_ids=self._resync.product_ids, device_restarts=self._device_restarts,
            name_conflicts=self._name_conflicts, dt_skipped=self._pose.skipped,
            dt_capped=self._pose.capped, clock_jumps=self._pose.clock_jumps,
            last_bad_reason=self._last_bad_reason, last_text=self._last_text,
            link_error=self._link_error)

    def reports(self, t: float) -> dict[str, Report]:
        """Diagnostic tasks ``link``, ``rate``, ``chips``, ``calibration`` (ros_interfaces §8)."""
        with self._lock:
            return self._reports(t)

    def _reports(self, t: float) -> dict[str, Report]:
        d = self._diagnostics(t)
        c = d.counters
        link_values = (('port', d.port), ('name', d.name), ('lines_good', str(c.good)),
                       ('lines_bad', str(c.bad)), ('lines_unknown', str(c.unknown)),
                       ('last_bad_reason', d.last_bad_reason),
                       ('device_restarts', str(d.device_restarts)),
                       ('name_conflicts', str(d.name_conflicts)))
        if d.link_error:
            link = Report(Level.ERROR, d.link_error, link_values)
        elif self._name_conflicts and not self._identity_ok:
            link = Report(Level.ERROR, f'{d.port}: another sensor name appeared on the port',
                          link_values)
        elif not d.initialised:
            msg = 'device restarted, calibration lost' if d.device_restarts else 'not initialised'
            link = Report(Level.ERROR, f'{d.port}: {msg}', link_values)
        else:
            link = Report(Level.OK, f'{d.port}: {d.name}', link_values)

        rate = self._rate.report(t)
        rate_values = rate.values + (('age_s', f'{d.age:.3f}'), ('stale', str(d.stale)),
                                     ('dt_skipped', str(d.dt_skipped)),
                                     ('dt_capped', str(d.dt_capped)))
        rate = Report(rate.level, rate.message, rate_values)

        chip_values = (('chip_mode', str(d.chip_mode)), ('resyncs', str(d.resyncs)),
                       ('resync_notices', str(c.resync)),
                       ('resync_active', str(d.resync_active)),
                       ('resync_duration_s', f'{d.resync_duration:.3f}'),
                       ('product_ids', ' '.join(str(i) for i in d.product_ids)))
        if d.resync_active:
            failed = describe_product_ids(d.product_ids, protocol.EXPECTED_PRODUCT_ID)
            if d.resync_duration > self.params.resync_timeout:
                chips = Report(Level.ERROR, f'chip re-sync for {d.resync_duration:.1f} s: '
                               f'{failed}; twist invalid (chip missing or dirty?)', chip_values)
            else:
                chips = Report(Level.WARN, f'chip re-sync in progress: {failed}; twist invalid',
                               chip_values)
        elif d.chip_mode != 0:
            chips = Report(Level.WARN, f'single-chip mode {d.chip_mode}: twist invalid',
                           chip_values)
        else:
            chips = Report(Level.OK, 'fused', chip_values)

        cal_values = (('source', d.calibration_source), ('uploaded', str(d.calibration_uploaded)),
                      ('speed_term', d.speed_term))
        if not d.calibration_uploaded:
            cal = Report(Level.ERROR, 'calibration not uploaded', cal_values)
        elif 'identity' in d.calibration_source:
            cal = Report(Level.WARN, 'identity calibration (uncalibrated chips)', cal_values)
        else:
            cal = Report(Level.OK, 'uploaded', cal_values)
        return {'link': link, 'rate': rate, 'chips': chips, 'calibration': cal}
