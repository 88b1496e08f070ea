# SPDX-License-Identifier: Apache-2.0
"""In-process closed-loop harness: a `SimCell` plus controller cores, no DDS (ROS-free).

The harness advances the cell in short chunks (default 1 ms of sim time) and hands every
sensor event, in time order, to a list of **agents** — the estimator and slip controllers of
``slip_control`` or any test code. An agent is any object with some of

    on_ft(harness, sample: FtSample)
    on_velocity(harness, sample: VelocitySample)
    on_telemetry(harness, sample: TelemetrySample)

and acts through the harness (``harness.command_force(...)``, ``harness.move(...)``). The chunk
plays the role of the transport latency: a command issued in a callback reaches the inner
loop at its next telemetry line after the chunk. Everything runs in sim time, deterministic
for a given seed and script, as fast as Python allows.

Wiring a ``slip_control`` controller (that package depends on this one, so the adapter lives
on its side)::

    class SlipAgent:
        def __init__(self, controller): self.ctrl, self.snap = controller, SensorSnapshot()
        def on_ft(self, h, s):
            if s.biased is not None:
                fx, fy, fz, _, _, tz = s.biased
                self.snap = self.snap.with_wrench(s.finger, WrenchSample(fx, fy, fz, tz, s.stamp))
        def on_velocity(self, h, s):
            self.snap = self.snap.with_twist(s.finger,
                                             TwistSample(s.vx, s.vy, s.omega, s.stamp, s.valid))
            if s.finger == 1:
                out = self.ctrl.step(self.snap, s.stamp)
                if out.force is not None:
                    h.command_force(out.force, timeout=out.timeout)

Scripted scenarios: `grasp_and_hold`, `estimation_exploration` (control_and_estimation §3.8)
and `open_loop_release`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, Optional, Sequence

from .sensors import FtSample, SimEvents, TelemetrySample, VelocitySample
from .sim_cell import SimCell, SimState

__all__ = [
    'ExplorationResult',
    'GraspResult',
    'Harness',
    'HarnessError',
    'Recorder',
    'ReleaseResult',
    'default_motion_time',
    'estimation_exploration',
    'grasp_and_hold',
    'open_loop_release',
]


class HarnessError(RuntimeError):
    """A scripted step was refused by the cell (the message says why) or timed out."""


def default_motion_time(distance: float, angle: float) -> float:
    """The runner's default motion time ``max(1 s, 4·(5·|Δp| + |Δangle|))`` (§5.2) [s]."""
    return max(1.0, 4.0 * (5.0 * abs(distance) + abs(angle)))


@dataclass
class Recorder:
    """Agent that samples the ground truth and the gripper loop every ``every`` telemetry
    lines (lists for cheap appends; SI units)."""

    every: int = 1
    t: list[float] = field(default_factory=list)
    x: list[float] = field(default_factory=list)
    y: list[float] = field(default_factory=list)
    theta: list[float] = field(default_factory=list)
    vx: list[float] = field(default_factory=list)
    vy: list[float] = field(default_factory=list)
    omega: list[float] = field(default_factory=list)
    normal_force: list[float] = field(default_factory=list)
    measured_force: list[float] = field(default_factory=list)
    voltage: list[float] = field(default_factory=list)
    object_x: list[float] = field(default_factory=list)
    object_y: list[float] = field(default_factory=list)
    object_theta: list[float] = field(default_factory=list)
    energy: list[float] = field(default_factory=list)
    in_grasp: list[bool] = field(default_factory=list)
    _count: int = 0

    def on_telemetry(self, harness: Harness, sample: TelemetrySample) -> None:
        """Record one row (decimated by ``every``)."""
        self._count += 1
        if self._count % self.every:
            return
        s = harness.cell.state()
        self.t.append(sample.stamp)
        self.x.append(s.x)
        self.y.append(s.y)
        self.theta.append(s.theta)
        self.vx.append(s.vx)
        self.vy.append(s.vy)
        self.omega.append(s.omega)
        self.normal_force.append(s.normal_force_1)
        self.measured_force.append(sample.measured_force)
        self.voltage.append(sample.voltage_cmd)
        self.object_x.append(s.object_x)
        self.object_y.append(s.object_y)
        self.object_theta.append(s.object_theta)
        self.energy.append(harness.cell.plant.mechanical_energy())
        self.in_grasp.append(s.in_grasp)

    def window(self, name: str, t0: float, t1: float) -> list[float]:
        """Values of series ``name`` with ``t0 ≤ t ≤ t1``."""
        series = getattr(self, name)
        return [v for t, v in zip(self.t, series) if t0 - 1e-12 <= t <= t1 + 1e-12]


class Harness:
    """Steps a `SimCell` and feeds its events to agents (module docstring).

    Args:
        cell: The simulated cell.
        agents: Objects with optional ``on_ft`` / ``on_velocity`` / ``on_telemetry``.
        chunk: Sim time advanced between event dispatches [s] (≥ the physics step).
    """

    def __init__(self, cell: SimCell, agents: Sequence[Any] = (), chunk: float = 1e-3) -> None:
        if not (math.isfinite(chunk) and chunk >= cell.params.physics_dt):
            raise ValueError(f'chunk {chunk!r} s must be finite and >= physics_dt '
                             f'{cell.params.physics_dt} s')
        self.cell = cell
        self.chunk = chunk
        self._ft: list[Callable[[Harness, FtSample], None]] = []
        self._vel: list[Callable[[Harness, VelocitySample], None]] = []
        self._tel: list[Callable[[Harness, TelemetrySample], None]] = []
        self.agents: list[Any] = []
        for agent in agents:
            self.add_agent(agent)

    # ------------------------------------------------------------------ agents
    def add_agent(self, agent: Any) -> None:
        """Register an agent (its existing ``on_*`` methods are called from now on)."""
        self.agents.append(agent)
        if callable(getattr(agent, 'on_ft', None)):
            self._ft.append(agent.on_ft)
        if callable(getattr(agent, 'on_velocity', None)):
            self._vel.append(agent.on_velocity)
        if callable(getattr(agent, 'on_telemetry', None)):
            self._tel.append(agent.on_telemetry)

    # ------------------------------------------------------------------ time
    @property
    def t(self) -> float:
        """Current sim time [s]."""
        return self.cell.t

    def run_for(self, seconds: float) -> None:
        """Advance ``seconds`` of sim time, dispatching events after every chunk."""
        if not (math.isfinite(seconds) and seconds >= 0.0):
            raise ValueError(f'seconds {seconds!r} must be finite and >= 0')
        self.run_until_time(self.cell.t + seconds)

    def run_until_time(self, t_end: float) -> None:
        """Advance to the last physics step at or before sim time ``t_end`` [s]."""
        cell = self.cell
        last = cell.step_index(t_end)
        while cell.steps < last:
            self._dispatch(cell.advance(min(cell.t + self.chunk, t_end)))

    def run_until(self, predicate: Callable[[Harness], bool], timeout: float) -> bool:
        """Advance until ``predicate(self)`` holds (checked after every chunk) or ``timeout``
        [s] of sim time passed; returns whether it held."""
        cell = self.cell
        t_end = cell.t + timeout
        last = cell.step_index(t_end)
        while not predicate(self):
            if cell.steps >= last:
                return False
            self._dispatch(cell.advance(min(cell.t + self.chunk, t_end)))
        return True

    def _dispatch(self, events: SimEvents) -> None:
        if not (self._ft or self._vel or self._tel):
            return
        if self._ft and not (self._vel or self._tel):
            for ft in events.ft:
                for f_ft in self._ft:
                    f_ft(self, ft)
            return
        if self._tel and not (self._ft or self._vel):
            for tel in events.telemetry:
                for f_tel in self._tel:
                    f_tel(self, tel)
            return
        for e in events:
            if isinstance(e, FtSample):
                for f_ft in self._ft:
                    f_ft(self, e)
            elif isinstance(e, VelocitySample):
                for f_vel in self._vel:
                    f_vel(self, e)
            else:
                for f_tel in self._tel:
                    f_tel(self, e)

    # ------------------------------------------------------------------ commands
    def command_force(self, force: float, timeout: float = 0.0) -> None:
        """Command a grasp force [N] stamped now (raises `HarnessError` if refused)."""
        ok, message = self.cell.command_grasp_force(force, self.cell.t, timeout)
        if not ok:
            raise HarnessError(f'grasp-force command refused: {message}')

    def move(self, lift: float = 0.0, lateral: float = 0.0, rotation: float = 0.0,
             duration: Optional[float] = None, wait: bool = True) -> float:
        """Move the gripper (see `SimCell.move_gripper`); waits for the end by default.

        Args:
            lift: World +Y [m].
            lateral: World X [m].
            rotation: About the grasp axis [rad].
            duration: Motion time [s]; default `default_motion_time`.
            wait: Run until the move ends.

        Returns:
            The end time of the move [s].
        """
        if duration is None:
            duration = default_motion_time(math.hypot(lift, lateral), rotation)
        ok, message, end = self.cell.move_gripper(lift, lateral, rotation, duration)
        if not ok:
            raise HarnessError(f'arm move refused: {message}')
        if wait:
            self.run_until_time(end)
        return end

    def bias(self, wait: bool = True) -> None:
        """Bias both F/T sensors (host side) and, by default, wait until it completes."""
        ok, message = self.cell.bias_ft()
        if not ok:
            raise HarnessError(f'bias refused: {message}')
        if wait and not self.run_until(lambda h: not h.cell.bias_in_progress, 2.0):
            raise HarnessError('bias did not complete within 2 s')

    def home(self, timeout: float = 30.0) -> None:
        """Home the gripper and wait for the result (instant or sequence)."""
        ok, message = self.cell.home()
        if not ok:
            raise HarnessError(f'homing refused: {message}')
        if not self.run_until(lambda h: h.cell.homed, timeout):
            raise HarnessError(f'homing did not finish within {timeout} s')

    def stop(self) -> None:
        """0 V now, target cleared."""
        self.cell.stop()

    def release(self, force: float = -8.0, wait: float = 1.0, rebias: bool = True) -> None:
        """The runner's release: command ``force`` (opening), wait, re-bias (§5.3)."""
        self.command_force(force)
        self.run_for(wait)
        if rebias:
            self.bias()

    def disturb(self, fx: float, fy: float, torque: float, duration: float) -> None:
        """External load on the object (see `SimCell.apply_disturbance`)."""
        ok, message = self.cell.apply_disturbance(fx, fy, torque, duration)
        if not ok:
            raise HarnessError(f'disturbance refused: {message}')

    def reset(self, preset: Optional[str] = None, object_on_table: bool = True) -> None:
        """Reset the scene (see `SimCell.reset`)."""
        ok, message = self.cell.reset(preset, object_on_table)
        if not ok:
            raise HarnessError(f'reset refused: {message}')

    def state(self) -> SimState:
        """Ground truth now."""
        return self.cell.state()


# ---------------------------------------------------------------------------- scenarios
@dataclass(frozen=True)
class GraspResult:
    """Outcome of `grasp_and_hold` (SI).

    Attributes:
        t_grasp: Time of the grasp command [s].
        t_hold: Start of the hold window [s].
        t_end: End of the hold window [s].
        measured_force: Mean bias-removed grasp force over the last 0.5 s of the hold [N].
        true_force: Mean true normal force over the same window [N].
        slip: Largest displacement of the grasp point relative to the pads during the hold [m].
        rotation: Largest rotation relative to the pads during the hold [rad].
        dropped: The object fell.
    """

    t_grasp: float
    t_hold: float
    t_end: float
    measured_force: float
    true_force: float
    slip: float
    rotation: float
    dropped: bool


def _prepare(h: Harness) -> None:
    """Open, empty gripper: home if needed and bias (as the runner's release does)."""
    if not h.cell.homed:
        h.home()
    h.bias()


def grasp_and_hold(h: Harness, force: float = 10.0, settle: float = 2.0, lift: float = 0.0,
                   hold: float = 2.0, prepare: bool = True) -> GraspResult:
    """Grasp the object standing on the table, optionally lift it, then hold.

    Args:
        h: Harness (scene at the pick-up pose, fingers open).
        force: Grasp force [N].
        settle: Wait after the command [s].
        lift: Lift after settling [m] (0: stay on the table).
        hold: Hold window [s] over which slip is measured.
        prepare: Home (if needed) and bias the F/T first.
    """
    if prepare:
        _prepare(h)
    t_grasp = h.t
    h.command_force(force)
    h.run_for(settle)
    if lift:
        h.move(lift=lift)
        h.run_for(0.2)
    t_hold = h.t
    s0 = h.state()
    slip = rot = 0.0
    meas: list[float] = []
    true: list[float] = []
    t_end = t_hold + hold
    while h.t < t_end - 1e-9:
        h.run_for(min(0.01, t_end - h.t))
        s = h.state()
        slip = max(slip, math.hypot(s.x - s0.x, s.y - s0.y))
        rot = max(rot, abs(s.theta - s0.theta))
        if h.t >= t_end - 0.5:
            meas.append(h.cell.status().measured_grasp_force)
            true.append(s.normal_force_1)
    return GraspResult(t_grasp, t_hold, h.t, sum(meas) / max(len(meas), 1),
                       sum(true) / max(len(true), 1), slip, rot, h.state().dropped)


@dataclass(frozen=True)
class ExplorationResult:
    """Outcome of `estimation_exploration` (ground truth, SI).

    Attributes:
        linear_window: ``(t0, t1)`` of the 1 s linear phase [s].
        rotational_window: ``(t0, t1)`` of the 1 s rotational phase [s].
        push_window: ``(t0, t1)`` of the 0.8 s push-down [s].
        slide: Grasp-point displacement relative to the pads over the push, ``gripper_middle``
            (x, y) [m] (the object slides up: y > 0).
        slide_speed: Mean relative speed over the push [m/s] (≈ 12.5 mm/s).
        object_drop: Largest change of the object's world height during the push [m].
        twist_peak: Largest relative rotation of the object w.r.t. the pads during the twist
            [rad] (≈ −0.1745: the pads turn on the object).
        twist_final: Relative rotation at the end of the twist-back [rad].
        object_turn: Largest change of the object's world angle during the twist [rad].
        dropped: The object fell.
    """

    linear_window: tuple[float, float]
    rotational_window: tuple[float, float]
    push_window: tuple[float, float]
    slide: tuple[float, float]
    slide_speed: float
    object_drop: float
    twist_peak: float
    twist_final: float
    object_turn: float
    dropped: bool


PhaseHook = Callable[[str, float, float], None]


def estimation_exploration(h: Harness, on_phase: Optional[PhaseHook] = None,
                           prepare: bool = True, grasp_force: float = 10.0,
                           explore_force: float = 5.0, release: bool = True
                           ) -> ExplorationResult:
    """The contact-estimation exploration of control_and_estimation §3.8.

    Object on the table between the open fingers, gripper at the pick-up pose. Grasp with
    10 N for 2 s, command 5 N, push the gripper 0.01 m down in 0.8 s (the table holds the
    object, which slides up between the pads), wait 0.2 s, twist +0.1745 rad in 0.5 s and back
    in 0.5 s (the table stops the object turning, so the pads twist on it), then release
    (−8 N, 1 s, re-bias).

    Args:
        h: Harness.
        on_phase: Called as ``on_phase('linear' | 'rotational', t_start, duration)`` when an
            estimator phase should start (e.g. ``ContactEstimator.start``).
        prepare: Home (if needed) and bias first.
        grasp_force: Grasp force [N].
        explore_force: Force during the exploration [N].
        release: Release and re-bias at the end.
    """
    if prepare:
        _prepare(h)
    h.command_force(grasp_force)
    h.run_for(2.0)
    h.command_force(explore_force)
    # Linear phase: 1 s, with the push-down in the first 0.8 s.
    t_lin = h.t
    if on_phase is not None:
        on_phase('linear', t_lin, 1.0)
    s0 = h.state()
    y_obj = [s0.object_y]

    def track(hh: Harness) -> bool:
        y_obj.append(hh.state().object_y)
        return False

    h.move(lift=-0.01, duration=0.8, wait=False)
    h.run_until(track, 0.8)
    s1 = h.state()
    t_push_end = h.t
    h.run_for(0.2)
    # Rotational phase: 1 s, +0.1745 rad in 0.5 s and back.
    t_rot = h.t
    if on_phase is not None:
        on_phase('rotational', t_rot, 1.0)
    r0 = h.state()
    rel = [0.0]
    turn = [0.0]

    def track_rot(hh: Harness) -> bool:
        s = hh.state()
        rel.append(s.theta - r0.theta)
        turn.append(s.object_theta - r0.object_theta)
        return False

    h.move(rotation=math.radians(10.0), duration=0.5, wait=False)
    h.run_until(track_rot, 0.5)
    h.move(rotation=-math.radians(10.0), duration=0.5, wait=False)
    h.run_until(track_rot, 0.5)
    twist_final = h.state().theta - r0.theta
    dropped = h.state().dropped
    if release:
        h.release()
    slide = (s1.x - s0.x, s1.y - s0.y)
    return ExplorationResult(
        linear_window=(t_lin, t_lin + 1.0), rotational_window=(t_rot, t_rot + 1.0),
        push_window=(t_lin, t_push_end), slide=slide,
        slide_speed=math.hypot(*slide) / (t_push_end - t_lin),
        object_drop=max(abs(y - s0.object_y) for y in y_obj),
        twist_peak=min(rel, key=lambda v: -abs(v)), twist_final=twist_final,
        object_turn=max(abs(v) for v in turn), dropped=dropped)


@dataclass(frozen=True)
class ReleaseResult:
    """Outcome of `open_loop_release` (SI).

    Attributes:
        t: Sample times [s] (every physics-step chunk).
        energy: Mechanical energy of the object incl. stored contact energy [J].
        max_rise: Largest increase of the energy between consecutive samples [J].
        fall: Height lost by the object [m].
        dropped: The object left the grasp.
    """

    t: list[float]
    energy: list[float]
    max_rise: float
    fall: float
    dropped: bool


def open_loop_release(h: Harness, hold_force: float = 10.0, lift: float = 0.1,
                      mode: str = 'stop', duration: float = 1.0,
                      prepare: bool = True) -> ReleaseResult:
    """Hold the object in the air, then release it open loop and watch it fall.

    Args:
        h: Harness (object on the table at the pick-up pose).
        hold_force: Grasp force while holding [N].
        lift: Lift before the release [m].
        mode: ``'stop'`` (0 V: the fingers are pushed open passively) or ``'open'``
            (command −8 N: the motor opens them).
        duration: Observation after the release [s].
        prepare: Home (if needed) and bias first.
    """
    if mode not in ('stop', 'open'):
        raise ValueError(f"mode must be 'stop' or 'open', got {mode!r}")
    grasp_and_hold(h, force=hold_force, settle=1.5, lift=lift, hold=0.3, prepare=prepare)
    y0 = h.state().object_y
    if mode == 'stop':
        h.stop()
    else:
        h.command_force(-8.0)
    times: list[float] = [h.t]
    energy: list[float] = [h.cell.plant.mechanical_energy()]
    t_end = h.t + duration
    while h.t < t_end - 1e-9:
        h.run_for(h.cell.params.physics_dt)
        times.append(h.t)
        energy.append(h.cell.plant.mechanical_energy())
    rise = max((b - a for a, b in zip(energy, energy[1:])), default=0.0)
    return ReleaseResult(times, energy, rise, y0 - h.state().object_y, h.state().dropped)
