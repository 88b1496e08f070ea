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

Scripted scenarios: `grasp_and_hold` and `open_loop_release`. The exploration of
control_and_estimation §3.8 is the experiment runner's own (`slip_control.core.exploration`),
played on this harness by the evaluation (`slip_bringup.core.evaluation.sim_runner_cell`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any
from collections.abc import Callable, Sequence

from .sensors import FtSample, SimEvents, TelemetrySample, VelocitySample
from .sim_cell import SimCell, SimState

__all__ = [
    'GraspResult',
    'Harness',
    'HarnessError',
    'Recorder',
    'ReleaseResult',
    'default_motion_time',
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
        status = sample.status
        self.measured_force.append(status.measured_grasp_force if status is not None else math.nan)
        self.voltage.append(status.voltage_cmd if status is not None else math.nan)
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
             duration: float | None = None, wait: bool = True) -> float:
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
            if self.cell.arm_moving:   # the end falls just after the last step boundary
                self.run_for(self.cell.params.physics_dt)
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

    def reset(self, preset: str | None = None, object_on_table: bool = True) -> None:
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
