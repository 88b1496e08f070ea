# SPDX-License-Identifier: Apache-2.0
"""HOLD with the ``model`` control law: the grasp force the measured load needs on the limit
surface, a slip observer, and a margin that learns from observed slip (issue 15 items 5, 6).

The thesis HOLD (`controllers.HoldController`, docs/control_and_estimation.md §4.4) doubles the
limit-surface force and never goes below 4 N: heavy loads on short torsional radii ask for up
to twice the gripper's 40 N, and light objects are squeezed 10–20× harder than they need. This
law holds with the force the object needs, bounded by it::

    need  = ‖(L̄x, L̄y, L̄τ/r)‖ / μ_c        L̄: load (F̄x, F̄y, τ̄) low-passed (load_filter_time)
    sus   = min(need over the last sustain_time)             (the load the object *kept*)
    mem   = sus, held at its recent peak (decays with memory_time)
    f_d   = (margin + a)·max(need, mem) + extra_force + slip_gain·max(need, min_force)·ŝ
    f_d  ≤ (max_margin + a)·mem + max_extra_force                          (the bound)
    out   = clamp(f_d, min_force, max_force); rises at once, falls with fall_time

* **The bound follows the sustained load.** A tap shorter than ``sustain_time`` (20 ms in the
  hold protocol) is over before the grasp-force loop could follow it; it does not raise the
  bound, so it cannot spike the force. A sustained load raises it ``sustain_time`` after it
  started; until then the force may rise by ``max_extra_force − extra_force`` and the
  observed-slip term.
* **The remembered need** keeps the force for the largest load of the last seconds: a
  disturbance that came once finds the grasp ready when it comes again.
* The **slip observer** (`twist_observer.TwistObserver`, a Kalman filter on the generalised
  slip twist ``(v̄x, v̄y, r·ω̄)``) gives the slip speed ``ŝ``; below its detection thresholds
  the slip term is zero (a lone quantisation count does not move the force), an incipient
  slip of a few counts raises the force in the next step.
* **Learned margin** ``a``: the slip path ``∫ŝ dt`` (decaying with ``adapt_decay``) beyond
  ``adapt_deadzone`` adds ``adapt_gain`` per metre, up to ``adapt_max``. A contact weaker than
  its estimate keeps slipping under a sustained load and lifts the bound; a tap beyond the
  margin that slips less than the dead zone teaches nothing.

Stale inputs follow the thesis HOLD (CE-3): F/T stale → hold the last output (raised to the law
on the last wrench if that is higher), velocity stale → slip term 0 and no decrease; both set
``safe_hold``. Timing: one step per new finger-1 twist; ``dt`` from its stamps.
"""
from __future__ import annotations

import math
from collections import deque

from slip_control.core.controllers import ControlContact, ControlOutput, SlipController, SlipMode
from slip_control.core.model_trajectory import MODEL_LAW
from slip_control.core.params import SlipControllerParams
from slip_control.core.signals import MiddleWrench, SensorSnapshot, combine_wrenches
from slip_control.core.twist_observer import SlipEstimate, TwistObserver, TwistObserverConfig


def observer_config(params: SlipControllerParams) -> TwistObserverConfig:
    """The slip observer's configuration from the ``twist_observer`` parameter group."""
    o = params.twist_observer
    return TwistObserverConfig(accel_std=o.accel_std, velocity_noise=o.velocity_noise,
                               detect_speed=o.detect_speed, detect_rate=o.detect_rate)


def first_order(previous: float, target: float, dt: float, time_constant: float) -> float:
    """One step of a first-order filter with time constant ``time_constant`` [s] over ``dt``."""
    if time_constant <= 0.0 or dt <= 0.0:
        return target if dt > 0.0 or time_constant <= 0.0 else previous
    a = math.exp(-dt / time_constant)
    return a * previous + (1.0 - a) * target


class LoadFilter:
    """First-order low-pass [time constant ``time_constant``, s] of the two-finger mean load
    ``(F̄x, F̄y, τ̄)``: sensor noise and taps shorter than the grasp-force loop can follow do
    not reach the force command; sustained loads do, within a few time constants."""

    def __init__(self, time_constant: float) -> None:
        self._tc = time_constant
        self._state: tuple[float, float, float] | None = None

    def update(self, w: MiddleWrench, dt: float | None) -> tuple[float, float, float]:
        """Filtered ``(F̄x, F̄y, τ̄)`` [N, N, N·m] after sample ``w`` (``dt`` [s], None = first
        sample or a gap: the state is kept, or set to ``w`` when there is none)."""
        if self._state is None:
            self._state = (w.fx, w.fy, w.tz)
        elif dt is not None and dt > 0.0:
            a, b, c = self._state
            tc = self._tc
            self._state = (first_order(a, w.fx, dt, tc), first_order(b, w.fy, dt, tc),
                           first_order(c, w.tz, dt, tc))
        return self._state

    def load(self, w: MiddleWrench, dt: float | None, r: float | None) -> float:
        """Limit-surface load ``D`` [N] of the filtered wrench (``r`` None: ``ft`` only)."""
        fx, fy, tz = self.update(w, dt)
        if r is None:
            return math.hypot(fx, fy)
        return math.sqrt(fx * fx + fy * fy + (tz / r) ** 2)


class SustainedLevel:
    """The smallest value over the last ``window`` seconds: the level a load has *kept*.

    A tap shorter than ``window`` does not raise it; a sustained step raises it ``window``
    after its start.
    """

    def __init__(self, window: float) -> None:
        self._window = window
        self._samples: deque[tuple[float, float]] = deque()

    def update(self, t: float, value: float) -> float:
        """Take ``value`` at time ``t`` [s]; returns the minimum over ``[t − window, t]``."""
        buf = self._samples
        if buf and t < buf[-1][0]:
            buf.clear()                      # clock jumped back: start again
        buf.append((t, value))
        while len(buf) > 1 and buf[1][0] <= t - self._window:
            buf.popleft()
        return min(v for _, v in buf)


class ModelHoldController(SlipController):
    """HOLD (mode 4), ``model`` law (module docstring).

    Args:
        params: Controller parameters (``hold_model``, ``twist_observer``, ``model``).
        contact: Contact properties; without a valid ``r`` (safe-hold successor of a mode
            that needs only ``μ_c``) the load is ``ft`` and the observer uses 1 mm.
        initial_force: The previous controller's last force [N]: the output starts there and
            falls with ``fall_time``, so a hand-over never drops the force in one step.
    """

    mode = SlipMode.HOLD
    control_law = MODEL_LAW

    def __init__(self, params: SlipControllerParams, contact: ControlContact,
                 initial_force: float | None = None) -> None:
        super().__init__(params, contact)
        h = params.hold_model
        self._out = initial_force
        self._observer = TwistObserver(observer_config(params),
                                       contact.r_guarded if contact.r_valid else 1e-3)
        self._load = LoadFilter(h.load_filter_time)
        self._sustained = SustainedLevel(h.sustain_time)
        self._path = 0.0             # slip path in the learning memory [m]
        self._need = 0.0             # need of the current load [N]
        self._memory: float | None = None   # remembered sustained need [N]

    @property
    def observer(self) -> TwistObserver:
        """The slip observer (for diagnostics and tests)."""
        return self._observer

    @property
    def learned_margin(self) -> float:
        """The learned extra margin ``a`` [-]."""
        h = self._p.hold_model
        return min(h.adapt_gain * max(0.0, self._path - h.adapt_deadzone), h.adapt_max)

    @property
    def needed_force(self) -> float:
        """``need`` of the last step: limit-surface force of the current load [N]."""
        return self._need

    @property
    def remembered_need(self) -> float:
        """``need_mem`` of the last step [N] (0 before the first)."""
        return self._memory if self._memory is not None else 0.0

    def reset(self, t: float) -> None:
        super().reset(t)
        self._observer.reset_time()

    def hold_force(self, need: float, memory: float, slip: SlipEstimate | None) -> float:
        """Unshaped ``model`` HOLD law ``f_d`` [N], clamped to the bound and the gripper range.

        Args:
            need: Limit-surface force of the current load [N].
            memory: Remembered sustained need [N] (sets the level and the bound).
            slip: Observer estimate (None: slip term 0).
        """
        h = self._p.hold_model
        m = self._p.model
        a = self.learned_margin
        f = (h.margin + a) * max(need, memory) + h.extra_force
        if slip is not None and slip.slipping:
            f += h.slip_gain * max(need, m.min_force) * slip.speed
        f = min(f, (h.max_margin + a) * memory + h.max_extra_force)
        return min(max(f, m.min_force), m.max_force)

    def _raw_need(self, w: MiddleWrench) -> float:
        return self._c.load(w) / self._c.mu_c

    def _stale_hold(self, inputs: SensorSnapshot) -> None:
        """Raise (never lower) the output to the law on the last wrench, if there is one."""
        w1, w2 = inputs.wrench_1, inputs.wrench_2
        if w1 is None or w2 is None or not (w1.finite() and w2.finite()):
            return
        need = self._raw_need(combine_wrenches(self._p.frames, w1, w2))
        memory = max(need, self.remembered_need)
        f = self.hold_force(need, memory, None)
        self._out = f if self._out is None else max(self._out, f)

    def step(self, inputs: SensorSnapshot, t: float) -> ControlOutput:
        """One ``model`` HOLD step with the thesis stale rules."""
        st = self._assess(inputs, t)
        h = self._p.hold_model
        if not st.ft_fresh:
            self._stale_hold(inputs)
            return self._emit(self._out, st, 'F/T stale: holding, never decreasing',
                              safe_hold=True)
        if not st.velocity_fresh:
            self._stale_hold(inputs)
            return self._emit(self._out, st, 'velocity stale: slip term 0, no decrease',
                              safe_hold=True)
        sample = self._next_sample(inputs, st)
        if isinstance(sample, ControlOutput):
            return sample
        dt = self._advance_stamp(sample.stamp)
        w, v = sample.wrench, sample.twist
        slip = self._observer.update(v, sample.stamp)
        self._learn(slip, dt)
        r = self._c.r_guarded if self._c.r_valid else None
        self._need = self._load.load(w, dt, r) / self._c.mu_c
        sustained = self._sustained.update(sample.stamp, self._need)
        memory = self._remember(sustained, dt)
        f_d = self.hold_force(self._need, memory, slip)
        out = self._out
        if out is None or f_d >= out or dt is None:
            out = f_d if out is None or f_d >= out else out
        else:
            out = first_order(out, f_d, dt, h.fall_time)
        self._out = out
        reason = 'slip observed' if slip.slipping else ''
        return self._emit(out, st, reason)

    def _remember(self, sustained: float, dt: float | None) -> float:
        """``need_mem``: the sustained need, held at its recent peak (decay ``memory_time``)."""
        mem = self._memory
        if mem is None or sustained >= mem:
            mem = sustained
        elif dt is not None:
            mem = first_order(mem, sustained, dt, self._p.hold_model.memory_time)
        self._memory = mem
        return mem

    def _learn(self, slip: SlipEstimate, dt: float | None) -> None:
        """Accumulate the observed slip path ``ŝ·dt`` (decays with ``adapt_decay``)."""
        h = self._p.hold_model
        if dt is None:
            return
        if slip.slipping:
            self._path += slip.speed * dt
        if h.adapt_decay > 0.0:
            self._path *= math.exp(-dt / h.adapt_decay)
