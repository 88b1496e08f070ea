# SPDX-License-Identifier: Apache-2.0
"""The host of the slip controllers: everything the ``slip_controller`` node does, minus ROS.

One `ControllerHost` owns the controller in charge and what it runs on
(control_and_estimation §4.1, CE-2, CE-3, CE-8):

* **inputs** — per-finger wrench and twist samples replace one immutable `SensorSnapshot`
  (`on_wrench`, `on_twist`; the travel of every twist is integrated), the latest contact
  properties (`set_properties`) and parameter snapshots (`set_params`: swapped in between
  steps; a running trajectory keeps its own and its HOLD successor gets the new one);
* **control step** (`step`) — one per finger-1 twist (`on_twist` says when) and one per
  watchdog tick of the caller (`WATCHDOG_PERIOD_S`); the controller in charge is stepped
  and its HOLD successor swapped in when a trajectory ends;
* **stale inputs** — staleness is judged from stamps against the caller's clock ``t``
  (`assess_inputs`), and acted on through `StaleDebounce`: once the other stream delivered
  a few samples while the stale one delivered none, or after ``stale_confirm`` in the
  clock domain of ``t`` (simulated time under ``use_sim_time``: a host too slow for real
  time slows the simulation, and a verdict waits for simulated time to pass, so a slow host
  cannot end a slip as "velocity stale"). On that clock a stale stream that still delivers
  newer samples (its older finger's stamp advanced since the last step) is being drained
  from a queue behind a clock that ran ahead, not stopped: the verdict starts over. Only a
  caller on the system clock (hardware) passes ``steady``, a monotonic clock to confirm on,
  since its ``t`` may jump; there the former rule holds unchanged;
* **mode switching** (`switch`, `cancel`) — validate completely, build, swap in with one
  assignment (`mode_switch.build_controller`), hand a preempted trajectory's result back;
* **state and diagnostics** — the ``slip_control/state`` content when it changes
  (`state_update`) and the ``inputs``/``contact`` diagnostics reports.

The host reads no clock: every time is an argument (``t`` [s] on the stamps' clock,
optionally ``steady`` [s] on a monotonic clock). What the caller sends (grasp-force commands
with their expiry, tracking rows, goal results, state messages) is returned, never sent from
here; the ``slip_controller`` node turns it into messages and the in-process evaluation into
calls on the simulated cell, so both run this one implementation.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from slip_cell_common.core.monitors import Level, Report
from slip_control.core.contact import ContactProperties, ContactSource
from slip_control.core.controllers import (ControlOutput, OffController, SlipController,
                                           SlipMode, SlipResult)
from slip_control.core.mode_switch import (ModeRequest, SwitchOutcome, build_controller,
                                           check_contact, hold_successor, with_params)
from slip_control.core.params import SlipControllerParams
from slip_control.core.signals import (InputStatus, SensorSnapshot, StaleDebounce, TwistSample,
                                       WrenchSample, assess_inputs)

#: Watchdog period [s, caller's clock]: stale inputs are acted on at most this late after
#: ``velocity_stale_after`` + ``stale_confirm`` (node: a timer; evaluation: telemetry lines).
WATCHDOG_PERIOD_S = 0.01

#: The finger whose twist triggers a control step (its stream paces the controller).
TRIGGER_FINGER = 1

#: ``log(level, text)`` with level ``'info'`` or ``'warn'``: what the host has to say.
HostLog = Callable[[str, str], None]


def _quiet(level: str, text: str) -> None:
    del level, text


def _oldest_stamps(snap: SensorSnapshot) -> tuple[float, float]:
    """``(twist, wrench)``: the older finger's latest stamp of each stream [s] (what its
    staleness is judged by), ``-inf`` until both fingers delivered."""
    def oldest(a: TwistSample | WrenchSample | None, b: TwistSample | WrenchSample | None
               ) -> float:
        return -math.inf if a is None or b is None else min(a.stamp, b.stamp)
    return oldest(snap.twist_1, snap.twist_2), oldest(snap.wrench_1, snap.wrench_2)


@dataclass(frozen=True, slots=True)
class ControllerState:
    """Content of one ``slip_control/state`` message.

    Attributes:
        mode: Mode in charge.
        goal_active: A LINEAR or ROTATIONAL trajectory runs.
        contact_valid: The latest properties allow HOLD.
        velocity_fresh: Twists fresh at the last step.
        ft_fresh: Wrenches fresh at the last step.
        safe_hold: The last step held on stale inputs.
        reason: Why the state was (re)published.
    """

    mode: SlipMode
    goal_active: bool
    contact_valid: bool
    velocity_fresh: bool
    ft_fresh: bool
    safe_hold: bool
    reason: str

    def key(self) -> tuple[int, bool, bool, bool, bool, bool]:
        """The fields whose change republishes the state (``reason`` excluded)."""
        return (int(self.mode), self.goal_active, self.contact_valid, self.velocity_fresh,
                self.ft_fresh, self.safe_hold)


class ControllerHost:
    """The slip controllers' host logic (module docstring); ROS-free, clock-free.

    Args:
        params: Validated controller parameters.
        properties: Initial contact properties (``None``: none received yet).
        log: Receives the host's log lines (default: dropped).
    """

    def __init__(self, params: SlipControllerParams,
                 properties: ContactProperties | None = None, log: HostLog = _quiet) -> None:
        self._params = params
        self._params_pending = False
        self._props = properties
        self._log = log
        self._controller: SlipController = OffController(params)
        self._snap = SensorSnapshot()
        self._last_t: float | None = None
        self._status: InputStatus | None = None
        self._safe_hold = False
        self._preset_in_use = False
        self._reason = 'started'
        self._state_key: tuple[int, bool, bool, bool, bool, bool] | None = None
        self._stale_gate = StaleDebounce(params.stale_confirm)
        self._twists_received = 0
        self._wrenches_received = 0
        self._marks = (-math.inf, -math.inf)  # oldest finger's twist / wrench stamp, last step

    # -- views -----------------------------------------------------------------------------

    @property
    def params(self) -> SlipControllerParams:
        """The latest parameter snapshot (the controller in charge may still run an older one
        until its trajectory ends)."""
        return self._params

    @property
    def properties(self) -> ContactProperties | None:
        """The latest contact properties (``None`` until some arrive)."""
        return self._props

    @property
    def snapshot(self) -> SensorSnapshot:
        """Latest samples of both fingers."""
        return self._snap

    @property
    def controller(self) -> SlipController:
        """The controller in charge."""
        return self._controller

    @property
    def mode(self) -> SlipMode:
        """Mode of the controller in charge."""
        return self._controller.mode

    @property
    def safe_hold(self) -> bool:
        """The last step held on stale inputs."""
        return self._safe_hold

    @property
    def preset_in_use(self) -> bool:
        """The controller in charge runs on PRESET properties."""
        return self._preset_in_use

    @property
    def reason(self) -> str:
        """The latest state reason."""
        return self._reason

    @property
    def steps_deferred(self) -> int:
        """Control steps held back while a stale verdict was being confirmed."""
        return self._stale_gate.deferred

    # -- inputs ----------------------------------------------------------------------------

    def on_wrench(self, finger: int, sample: WrenchSample) -> None:
        """Take finger ``finger``'s bias-removed wrench (``ft_sensor_k``)."""
        self._snap = self._snap.with_wrench(finger, sample)
        self._wrenches_received += 1

    def on_twist(self, finger: int, sample: TwistSample) -> bool:
        """Take finger ``finger``'s slip twist (``vel_sensor_k``).

        Returns:
            ``True`` when this sample triggers a control step (`TRIGGER_FINGER`): call `step`.
        """
        self._snap = self._snap.with_twist(finger, sample)
        self._twists_received += 1
        return finger == TRIGGER_FINGER

    def set_properties(self, props: ContactProperties) -> str:
        """Take new contact properties (used from the next mode request).

        Returns:
            The state reason to publish (forced).
        """
        self._props = props
        self._log('info', f'contact properties received: {props.describe()} '
                          '(used from the next mode request)')
        return f'contact properties: {props.source.name}, valid={props.valid}'

    def set_params(self, params: SlipControllerParams) -> None:
        """Take a validated parameter snapshot; swapped in now or after a running trajectory."""
        self._params = params
        self._stale_gate.confirm_s = params.stale_confirm
        self._params_pending = True
        self._apply_params()

    def observe_time(self, t: float) -> float:
        """Note the caller's clock ``t`` [s]; on a backwards jump forget the stamp history.

        Returns:
            How far the clock jumped back [s] (0 when it did not).
        """
        last, self._last_t = self._last_t, t
        if last is None or t >= last:
            return 0.0
        self._log('warn', f'clock jumped backwards by {last - t:.3f} s: '
                          'resetting the controller timing')
        self._controller.reset(t)
        # A verdict pending from before the jump would wait until t passed its old start.
        gate = StaleDebounce(self._params.stale_confirm)
        gate.deferred = self._stale_gate.deferred
        self._stale_gate = gate
        return last - t

    # -- control ---------------------------------------------------------------------------

    def step(self, t: float, steady: float | None = None) -> ControlOutput | None:
        """One control step at ``t`` [s] (stamps' clock).

        Args:
            t: Current time [s] on the stamps' clock (the node clock: simulated time under
                ``use_sim_time``).
            steady: Monotonic time [s] to confirm stale verdicts on instead of ``t``; only
                for a caller on the system clock (hardware). ``None`` (simulated time, the
                in-process evaluation): confirmed on ``t``, so a verdict needs
                ``stale_confirm`` of *simulated* time without the stale stream.

        Returns:
            The controller's output (its HOLD successor already swapped in), or ``None``
            while a stale verdict is being confirmed (the last command stays in force: it
            carries ``command_timeout``).
        """
        self._apply_params()
        status = self.input_status(t)
        stale_v, stale_f = not status.velocity_fresh, not status.ft_fresh
        marks = _oldest_stamps(self._snap)
        if steady is None and ((stale_v and marks[0] > self._marks[0]) or
                               (stale_f and marks[1] > self._marks[1])):
            # Node-clock time: the stale stream's oldest finger delivered a newer sample since
            # the last step, so it is being drained (a backlog behind a clock that ran ahead),
            # not stopped: the verdict starts over.
            self._stale_gate.defer(False, False, t, self._twists_received,
                                   self._wrenches_received)
        self._marks = marks
        confirm_clock = t if steady is None else steady
        if self._stale_gate.defer(stale_v, stale_f, confirm_clock, self._twists_received,
                                  self._wrenches_received):
            return None
        out = self._controller.step(self._snap, t)
        if out.next_controller is not None:
            self._controller = out.next_controller
        if out.result is not None:
            self._log_result(out.result)
        self._status = out.status
        self._safe_hold = out.safe_hold
        return out

    def switch(self, request: ModeRequest, t: float, origin: str = 'set_mode'
               ) -> SwitchOutcome:
        """Validate, build and swap in the controller for ``request`` at ``t`` [s] (CE-2).

        On success the caller sends ``outcome.final_force`` (if any) with expiry 0 (valid until
        replaced) and answers the goal of ``outcome.preempted`` (if any). A refusal changes
        nothing.

        Args:
            request: The request (SI).
            t: Request time [s]; a trajectory starts here.
            origin: Names the request in the log (``set_mode``, ``execute``).
        """
        self._apply_params()
        outcome = build_controller(request, self._props, self._params, t,
                                   previous=self._controller, inputs=self._snap)
        if not outcome.ok:
            self._log('warn', f'{origin} refused: {outcome.message}')
            return outcome
        if outcome.preempted is not None:
            self._log_result(outcome.preempted)
        assert outcome.controller is not None
        self._controller = outcome.controller
        self._safe_hold = False
        self._preset_in_use = outcome.preset_in_use
        self._log('info', f'{origin}: {outcome.message}')
        return outcome

    def cancel(self, message: str, t: float) -> SlipResult | None:
        """End the controller in charge with ``message`` and hand over to HOLD at ``t`` [s].

        Returns:
            The aborted trajectory's result, or ``None`` when none was running.
        """
        hold, result = hold_successor(self._controller, message, t)
        self._controller = hold
        if result is not None:
            self._log_result(result)
        return result

    # -- state and diagnostics -------------------------------------------------------------

    def input_status(self, t: float) -> InputStatus:
        """Freshness of the inputs at ``t`` [s] (CE-3)."""
        p = self._params
        return assess_inputs(self._snap, t, velocity_stale_after=p.velocity_stale_after,
                             ft_stale_after=p.ft_stale_after, sync_tolerance=p.sync_tolerance)

    def contact_check(self) -> tuple[bool, str]:
        """Whether the latest properties allow HOLD, and why not."""
        return check_contact(SlipMode.HOLD, self._props, self._params)

    def state_update(self, t: float, reason: str, *, force: bool = False
                     ) -> ControllerState | None:
        """The state to publish at ``t`` [s], or ``None`` when nothing changed.

        Args:
            t: Current time [s] (judges freshness before the first step).
            reason: Why (kept as the state's reason; '' keeps the previous one).
            force: Publish even if unchanged (mode requests, properties).
        """
        st = self._status if self._status is not None else self.input_status(t)
        c = self._controller
        state = ControllerState(c.mode, c.goal_active, self.contact_check()[0],
                                st.velocity_fresh, st.ft_fresh, self._safe_hold,
                                reason or self._reason)
        if not force and state.key() == self._state_key:
            return None
        self._state_key = state.key()
        self._reason = state.reason
        return state

    def inputs_report(self, t: float) -> Report:
        """The ``inputs`` diagnostics task at ``t`` [s]."""
        st = self.input_status(t)
        values = (('velocity_age_s', f'{st.velocity_age:.4f}'), ('ft_age_s', f'{st.ft_age:.4f}'),
                  ('velocity_fresh', str(st.velocity_fresh)), ('ft_fresh', str(st.ft_fresh)),
                  ('synchronised', str(st.synced)), ('safe_hold', str(self._safe_hold)),
                  ('steps_deferred_stale', str(self._stale_gate.deferred)))
        if st.all_fresh:
            return Report(Level.OK, 'inputs fresh', values)
        stale = ', '.join(n for n, ok in (('velocity', st.velocity_fresh), ('F/T', st.ft_fresh),
                                          ('finger sync', st.synced)) if not ok)
        if self._controller.mode != SlipMode.OFF:
            if self._safe_hold:
                return Report(Level.ERROR, f'stale inputs while controlling ({stale}): safe '
                              'hold', values)
            return Report(Level.WARN, f'inputs late while controlling ({stale}): not acted on '
                          '(yet); a stale verdict waits for confirmation', values)
        return Report(Level.WARN, f'inputs not fresh ({stale}); not controlling', values)

    def contact_report(self) -> Report:
        """The ``contact`` diagnostics task."""
        p = self._props
        if p is None:
            return Report(Level.WARN, 'no contact properties received: slip modes refused')
        values = (('source', p.source.name), ('preset', p.preset_name), ('valid', str(p.valid)),
                  ('mu_c', f'{p.mean_mu_c():.4f}'), ('r_m', f'{p.mean_r():.5f}'),
                  ('allow_preset_properties', str(self._params.allow_preset_properties)))
        ok, why = self.contact_check()
        if p.source == ContactSource.PRESET and ok:
            return Report(Level.WARN, f'preset {p.preset_name!r} in use', values)
        if not ok:
            return Report(Level.WARN, why, values)
        return Report(Level.OK, f'{p.source.name} properties valid', values)

    # -- internals -------------------------------------------------------------------------

    def _apply_params(self) -> None:
        if not self._params_pending:
            return
        new = with_params(self._controller, self._params)
        if new is None:
            return                         # a trajectory runs: retry after it ends
        self._controller = new
        self._params_pending = False
        self._log('info', f'parameters updated ({new.mode.name} rebuilt)')

    def _log_result(self, result: SlipResult) -> None:
        text = (f'{result.mode.name} trajectory ended: {result.message} (progress '
                f'{result.final_pos:.4f}, error {result.final_error:.4f}, '
                f'{result.elapsed:.2f} s)')
        self._log('info' if result.success else 'warn', text)
