# SPDX-License-Identifier: Apache-2.0
"""One-degree-of-freedom slip plants for validating the controllers before the simulator.

Not a friction model of the cell (that is ``friction_models``); a deliberately small plant
with the features the controller gains depend on:

* **Linear**: an object of mass ``m`` held by two pads with normal force ``N`` each, loaded by
  gravity along a fixed ``gripper_middle`` direction ``ĝ``. Coulomb–viscous friction per pad
  ``(μ_c + μ_v·v)·N`` while sliding, sticking while ``m·g ≤ 2·μ_s·N``::

      m·dv/dt = m·g − 2·(μ_c + μ_v·v)·N,   v ≥ 0 (gravity only pulls one way)

* **Rotational**: the same object pivoting about the grasp axis under the gravity torque
  ``τ_g = m·g·d·sin(φ0 − φ)`` (it turns towards hanging vertical); per pad the torsional
  friction of the ellipsoidal limit surface with the tangential load ``f_t = m·g/2`` carried::

      τ_cap = μ·r·N·sqrt(1 − (f_t/(μ·N))²),   J·dω/dt = τ_g − 2·(τ_cap + μ_v·u·ω·N)

* **Actuator**: ``N`` follows the commanded grasp force with a first-order lag ``τ_a``.
* **Sensors** in the raw finger frames with the conventions of hardware_protocols §5:
  F/T = force on the pad (``Fz = −N``) plus Gaussian noise at 500 Hz; slip velocity of the
  object relative to the pad at ≈ 120 Hz, quantised like the optical chips by differencing
  integer counts of the integrated displacement (0.0079375 mm per count, ≈ 0.95 mm/s per
  count per sample) and of the angle (≈ 0.013 rad/s per count per sample).

The plant uses its own simulated time; nothing here reads a clock.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from slip_control.core.controllers import ControlOutput, SlipController
from slip_control.core.signals import SensorSnapshot, TwistSample, WrenchSample
from slip_cell_common.core.frames import FrameParams, planar_from_middle

#: Optical-chip displacement per count [m] (3200 counts per inch).
COUNT_M = 0.0254 / 3200.0


@dataclass(frozen=True)
class ToyPlantParams:
    """Parameters of the toy plants (SI)."""

    mass: float = 0.2                 # [kg]
    gravity: float = 9.81             # [m/s²]
    gravity_dir: tuple[float, float] = (0.0, -1.0)   # ĝ in gripper_middle xy
    mu_c: float = 0.40                # [-]
    mu_s: float = 0.44                # [-]
    mu_v: float = 2.0                 # [1/(m/s)]
    r: float = 0.005                  # [m] torsional radius
    u: float = 2.5e-5                 # [m²] torsional viscous term
    com_offset: float = 0.03          # [m] d, centre of mass from the grasp axis
    tilt0: float = math.radians(45.0)  # [rad] φ0, initial angle from hanging vertical
    inertia: float = 3e-4             # [kg·m²] about the grasp axis
    actuator_tau: float = 0.03        # [s]
    initial_force: float = 8.0        # [N] per pad
    ft_noise: float = 0.01            # [N] 1-σ
    torque_noise: float = 1e-4        # [N·m] 1-σ
    ft_period: float = 0.002          # [s]
    velocity_period: float = 1.0 / 120.0   # [s]
    angle_count: float = 0.013 / 120.0     # [rad] per count
    finger_2_delay: float = 0.001     # [s] finger-2 velocity sample after finger 1
    sim_dt: float = 2e-4              # [s]


@dataclass
class PlantState:
    """Mutable plant state (simulated time)."""

    t: float = 0.0
    pos: float = 0.0       # slip along ĝ [m]
    vel: float = 0.0       # [m/s]
    angle: float = 0.0     # rotation about +z [rad]
    rate: float = 0.0      # [rad/s]
    normal: float = 0.0    # N per pad [N]
    stuck_lin: bool = True
    stuck_rot: bool = True
    ft_load: float = 0.0   # tangential force on each pad, along ĝ [N]
    torque: float = 0.0    # torsional friction on each pad about +z [N·m]
    dropped: bool = False  # the tangential load exceeded μ·N during a rotational run


@dataclass
class ToyPlant:
    """Linear or rotational toy plant with its sensors.

    Args:
        params: Plant parameters.
        kind: ``'linear'`` or ``'rotational'``.
        frames: Frame constants used to express the signals in the raw finger frames.
        seed: Seed of the noise generator.
    """

    params: ToyPlantParams
    kind: str = 'linear'
    frames: FrameParams = field(default_factory=FrameParams)
    seed: int = 0
    state: PlantState = field(init=False)

    def __post_init__(self) -> None:
        if self.kind not in ('linear', 'rotational'):
            raise ValueError(f'kind must be linear or rotational, got {self.kind!r}')
        self._rng = np.random.default_rng(self.seed)
        p = self.params
        self.state = PlantState(normal=p.initial_force)
        self._counts = {1: (0, 0), 2: (0, 0)}
        self._angle_counts = {1: 0, 2: 0}
        self._update_loads()

    # physics ------------------------------------------------------------------------------

    def _update_loads(self) -> None:
        p, s = self.params, self.state
        w_half = 0.5 * p.mass * p.gravity
        if self.kind == 'linear':
            s.ft_load = w_half if s.stuck_lin else (p.mu_c + p.mu_v * s.vel) * s.normal
            s.torque = 0.0
            return
        s.ft_load = w_half
        tau_g_half = 0.5 * p.mass * p.gravity * p.com_offset * math.sin(p.tilt0 - s.angle)
        if s.stuck_rot:
            s.torque = tau_g_half
        else:
            s.torque = self._tau_cap(p.mu_c) + p.mu_v * p.u * s.rate * s.normal

    def _tau_cap(self, mu: float) -> float:
        p, s = self.params, self.state
        cap = mu * s.normal
        if cap <= s.ft_load:
            return 0.0
        return mu * p.r * s.normal * math.sqrt(1.0 - (s.ft_load / cap) ** 2)

    def step(self, force_cmd: float, dt: float) -> None:
        """Advance by ``dt`` [s] with the commanded per-pad grasp force [N]."""
        p, s = self.params, self.state
        s.normal += (max(force_cmd, 0.0) - s.normal) * (1.0 - math.exp(-dt / p.actuator_tau))
        if self.kind == 'linear':
            if s.stuck_lin and p.mass * p.gravity > 2.0 * p.mu_s * s.normal:
                s.stuck_lin = False
            if not s.stuck_lin:
                acc = p.gravity - 2.0 * (p.mu_c + p.mu_v * s.vel) * s.normal / p.mass
                v_new = s.vel + acc * dt
                if v_new <= 0.0:
                    s.pos += 0.5 * s.vel * dt
                    s.vel, s.stuck_lin = 0.0, True
                else:
                    s.pos += 0.5 * (s.vel + v_new) * dt
                    s.vel = v_new
        else:
            s.ft_load = 0.5 * p.mass * p.gravity
            if p.mu_c * s.normal < s.ft_load:
                s.dropped = True
            tau_g = p.mass * p.gravity * p.com_offset * math.sin(p.tilt0 - s.angle)
            if s.stuck_rot and tau_g > 2.0 * self._tau_cap(p.mu_s):
                s.stuck_rot = False
            if not s.stuck_rot:
                fric = 2.0 * (self._tau_cap(p.mu_c) + p.mu_v * p.u * s.rate * s.normal)
                w_new = s.rate + (tau_g - fric) / p.inertia * dt
                if w_new <= 0.0:
                    s.angle += 0.5 * s.rate * dt
                    s.rate, s.stuck_rot = 0.0, True
                else:
                    s.angle += 0.5 * (s.rate + w_new) * dt
                    s.rate = w_new
        s.t += dt
        self._update_loads()

    # sensors ------------------------------------------------------------------------------

    def wrench(self, finger: int, stamp: float) -> WrenchSample:
        """F/T sample of finger ``finger`` (force on the pad, raw frame, with noise)."""
        p, s = self.params, self.state
        gx, gy = p.gravity_dir
        fx, fy, tz = planar_from_middle(self.frames, finger, s.ft_load * gx, s.ft_load * gy,
                                        -s.torque)
        n = self._rng.normal(0.0, 1.0, 4)
        return WrenchSample(fx=fx + p.ft_noise * n[0], fy=fy + p.ft_noise * n[1],
                            fz=-s.normal + p.ft_noise * n[2], tz=tz + p.torque_noise * n[3],
                            stamp=stamp)

    def twist(self, finger: int, stamp: float, period: float) -> TwistSample:
        """Quantised slip-velocity sample of finger ``finger`` (object relative to pad)."""
        p, s = self.params, self.state
        gx, gy = p.gravity_dir
        x, y, _ = planar_from_middle(self.frames, finger, s.pos * gx, s.pos * gy, 0.0)
        cx, cy = math.floor(x / COUNT_M), math.floor(y / COUNT_M)
        px, py = self._counts[finger]
        self._counts[finger] = (cx, cy)
        vx, vy = (cx - px) * COUNT_M / period, (cy - py) * COUNT_M / period
        ca = math.floor(s.angle / p.angle_count)
        dca = ca - self._angle_counts[finger]
        self._angle_counts[finger] = ca
        omega = dca * p.angle_count / period
        if finger == 2:
            omega = -omega          # finger 2's z is flipped (hardware_protocols §5)
        return TwistSample(vx=vx, vy=vy, omega=omega, stamp=stamp)


@dataclass
class LoopLog:
    """Time series of a closed-loop run (lists for cheap appends)."""

    t: list[float] = field(default_factory=list)
    force_cmd: list[float] = field(default_factory=list)
    normal: list[float] = field(default_factory=list)
    pos: list[float] = field(default_factory=list)
    angle: list[float] = field(default_factory=list)
    safe_hold: list[bool] = field(default_factory=list)
    mode: list[int] = field(default_factory=list)


class ClosedLoop:
    """Closed loop of a controller and a `ToyPlant`, stepped like the node does.

    The controller is stepped on every finger-1 twist (at ``t = stamp``) and from a watchdog
    every ``watchdog_period``; ``next_controller`` outputs are swapped in; the last published
    force stays applied (the inner loop keeps the last target).

    Args:
        plant: The plant.
        watchdog_period: Period of the watchdog steps [s].
    """

    def __init__(self, plant: ToyPlant, watchdog_period: float = 0.01) -> None:
        self.plant = plant
        self.snapshot = SensorSnapshot()
        self.force = plant.state.normal
        self.watchdog_period = watchdog_period
        p, t = plant.params, plant.state.t
        self._next_ft = t
        self._next_v1 = t
        self._next_v2 = t + p.finger_2_delay
        self._next_wd = t

    def run(self, controller: SlipController, duration: float, *,
            velocity_dropout: tuple[float, float] | None = None,
            ft_dropout: tuple[float, float] | None = None,
            on_output: Callable[[float, ControlOutput], None] | None = None,
            ) -> tuple[SlipController, LoopLog]:
        """Run ``controller`` for ``duration`` [s] of simulated time.

        Args:
            controller: The controller in charge at the start.
            duration: Simulated time [s].
            velocity_dropout: ``(t0, t1)``: no twist samples in this interval.
            ft_dropout: ``(t0, t1)``: no wrench samples in this interval.
            on_output: Optional callable ``(t, output)`` called for every output.

        Returns:
            The controller in charge at the end and the log of this run.
        """
        plant = self.plant
        p, s = plant.params, plant.state
        ctrl = controller
        t_end = s.t + duration
        log = LoopLog()
        eps = 1e-12

        def in_(win: tuple[float, float] | None, t: float) -> bool:
            return win is not None and win[0] <= t < win[1]

        while s.t < t_end - eps:
            plant.step(self.force, p.sim_dt)
            t = s.t
            stepped = False
            snap = self.snapshot
            if t + eps >= self._next_ft:
                self._next_ft += p.ft_period
                if not in_(ft_dropout, t):
                    snap = snap.with_wrench(1, plant.wrench(1, t)).with_wrench(
                        2, plant.wrench(2, t))
            if t + eps >= self._next_v1:
                self._next_v1 += p.velocity_period
                if not in_(velocity_dropout, t):
                    snap = snap.with_twist(1, plant.twist(1, t, p.velocity_period))
                    stepped = True
            if t + eps >= self._next_v2:
                self._next_v2 += p.velocity_period
                if not in_(velocity_dropout, t):
                    snap = snap.with_twist(2, plant.twist(2, t, p.velocity_period))
            if t + eps >= self._next_wd:
                self._next_wd += self.watchdog_period
                stepped = True
            self.snapshot = snap
            if not stepped:
                continue
            out = ctrl.step(snap, t)
            if on_output is not None:
                on_output(t, out)
            if out.force is not None:
                self.force = out.force
            if out.next_controller is not None:
                ctrl = out.next_controller
            log.t.append(t)
            log.force_cmd.append(self.force)
            log.normal.append(s.normal)
            log.pos.append(s.pos)
            log.angle.append(s.angle)
            log.safe_hold.append(out.safe_hold)
            log.mode.append(int(out.mode))
        return ctrl, log
