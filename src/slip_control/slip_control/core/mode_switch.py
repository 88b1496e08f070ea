# SPDX-License-Identifier: Apache-2.0
"""Mode-request validation and atomic controller construction (control_and_estimation §4.1).

CE-2: a request is validated completely before anything changes; then a complete new
controller object (trajectory, integrators, gains snapshot, contact properties) is built and
returned, so the node swaps it in with one assignment on the executor that runs the control
step::

    outcome = build_controller(request, properties, params, t=now, previous=self._controller)
    if outcome.ok:
        if outcome.preempted is not None: ...          # abort the running ExecuteSlip goal
        if outcome.final_force is not None: ...        # OFF: publish once with timeout 0
        self._controller = outcome.controller          # the one assignment

Rules (SI arguments; CE-1, CE-4):

* every numeric field must be finite (NaN and ±inf are rejected whatever the mode);
* LINEAR: ``min_duration ≤ duration ≤ max_duration``, ``0 < distance ≤ max_linear_distance``;
  a zero ``direction`` (xy) or ``latch_direction`` latches the direction from the first
  motion;
* ROTATIONAL: the same duration rule, ``0 < |angle| ≤ max_angle``;
* control law: ``request.control_law`` names the law family (`CONTROL_LAWS`: ``thesis``, the
  reference laws of control_and_estimation §4; ``model``, the model-based laws of
  docs/model_slip_control.md §1); empty means the parameter ``default_control_law``, and a mode
  without that law then uses ``thesis``. An explicit law the mode does not have is refused.
  The controller is built by the factory registered for ``(mode, law)`` in `CONTROLLERS`; a
  factory may refuse a request it cannot carry out (`RequestRefused`, e.g. a slip the measured
  load cannot produce), with the reason, before anything changes;
* contact properties: HOLD and ROTATIONAL need valid ``μ_c`` and ``r`` (both fingers
  ``linear_valid`` and ``rotational_valid``), LINEAR and HINGE need valid ``μ_c`` (both fingers
  ``linear_valid``). DEFAULT sets are never accepted. A PRESET set is accepted only with
  ``allow_preset_properties`` (the message then says so, for a diagnostics WARN), and its
  flags must still cover what the mode needs. ESTIMATED and GROUND_TRUTH sets are judged by
  their flags.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from types import MappingProxyType

from slip_control.core.contact import ContactProperties, ContactSource
from slip_control.core.controllers import (ControlContact, HingeController, HoldController,
                                           LinearController, OffController,
                                           RotationalController, SlipController, SlipMode,
                                           SlipResult)
from slip_control.core.model_hinge import ModelHingeController, static_ratio
from slip_control.core.model_hold import ModelHoldController
from slip_control.core.model_linear import ModelLinearController
from slip_control.core.model_rotational import ModelRotationalController
from slip_control.core.model_trajectory import RequestRefused
from slip_control.core.params import CONTROL_LAWS, SlipControllerParams
from slip_control.core.signals import SensorSnapshot

_MODE_NAMES = ', '.join(f'{m.value} {m.name}' for m in SlipMode)


@dataclass(frozen=True, slots=True)
class ModeRequest:
    """A ``SetSlipMode`` / ``ExecuteSlip`` request in SI units.

    Attributes:
        mode: Requested mode (``SlipMode`` value; any int is accepted here and validated).
        duration: Trajectory time ``T`` [s] (ROTATIONAL, LINEAR).
        distance: Slip distance [m] (LINEAR).
        angle: Signed slip angle about ``gripper_middle`` +z [rad] (ROTATIONAL).
        direction: LINEAR slip direction in ``gripper_middle`` (xy used; zero = latch).
        latch_direction: Take the direction (LINEAR) or sign (ROTATIONAL) from the first
            motion (the model laws take it from the measured load instead).
        control_law: Law family (`CONTROL_LAWS`); '' = the ``default_control_law`` parameter.
    """

    mode: int
    duration: float = 0.0
    distance: float = 0.0
    angle: float = 0.0
    direction: tuple[float, float, float] = (0.0, 0.0, 0.0)
    latch_direction: bool = False
    control_law: str = ''


@dataclass(frozen=True, slots=True)
class SwitchOutcome:
    """Result of `build_controller`.

    Attributes:
        ok: The request was accepted and ``controller`` is ready to swap in.
        message: Why it was rejected, or what was accepted (mentions a preset in use).
        controller: The new controller (``None`` when rejected).
        final_force: OFF only: the previous controller's last force [N], to publish once with
            ``timeout = 0`` (valid until replaced); ``None`` if there is nothing to hand over.
        preempted: Result of a trajectory that the new request aborted ("preempted").
        preset_in_use: The accepted properties are a preset (diagnostics WARN).
        control_law: Law family of the new controller ('' when rejected or OFF).
    """

    ok: bool
    message: str
    controller: SlipController | None = None
    final_force: float | None = None
    preempted: SlipResult | None = None
    preset_in_use: bool = False
    control_law: str = ''


@dataclass(frozen=True, slots=True)
class BuildContext:
    """What a controller factory gets: a request that passed `validate_request`.

    Attributes:
        request: The request (SI).
        mode: Its mode.
        props: The contact properties it was validated against.
        contact: Their two-finger means (``r`` left out where the mode allows it).
        params: Controller parameters (snapshotted into the controller).
        t: Request time [s]: a trajectory starts here.
        last_force: Last force of the controller in charge [N] (hand-over), or ``None``.
        inputs: Latest sensor samples (the model laws measure the load from them), or
            ``None`` when the caller has none.
    """

    request: ModeRequest
    mode: SlipMode
    props: ContactProperties
    contact: ControlContact
    params: SlipControllerParams
    t: float
    last_force: float | None
    inputs: SensorSnapshot | None


#: ``factory(context) -> controller``; raises `RequestRefused` with the reason to refuse.
ControllerFactory = Callable[[BuildContext], SlipController]


def _thesis_hold(c: BuildContext) -> SlipController:
    return HoldController(c.params, c.contact, initial_force=c.last_force)


def _thesis_hinge(c: BuildContext) -> SlipController:
    return HingeController(c.params, c.contact, initial_force=c.last_force)


def _latched_direction(request: ModeRequest) -> tuple[float, float] | None:
    """The LINEAR direction (xy) of a request, or ``None`` to latch it."""
    dx, dy = request.direction[0], request.direction[1]
    return None if request.latch_direction or not math.hypot(dx, dy) > 0.0 else (dx, dy)


def _thesis_linear(c: BuildContext) -> SlipController:
    r = c.request
    return LinearController(c.params, c.contact, r.distance, r.duration, c.t,
                            direction=_latched_direction(r))


def _thesis_rotational(c: BuildContext) -> SlipController:
    r = c.request
    return RotationalController(c.params, c.contact, r.angle, r.duration, c.t,
                                latch=r.latch_direction)


def _model_linear(c: BuildContext) -> SlipController:
    r = c.request
    return ModelLinearController.for_request(c.params, c.props, c.contact, r.distance,
                                             r.duration, c.t, _latched_direction(r), c.inputs,
                                             initial_force=c.last_force)


def _model_rotational(c: BuildContext) -> SlipController:
    r = c.request
    return ModelRotationalController.for_request(c.params, c.props, c.contact, r.angle,
                                                 r.duration, c.t, r.latch_direction, c.inputs,
                                                 initial_force=c.last_force)


def _model_hold(c: BuildContext) -> SlipController:
    return ModelHoldController(c.params, c.contact, initial_force=c.last_force)


def _model_hinge(c: BuildContext) -> SlipController:
    return ModelHingeController.for_request(c.params, c.contact, c.inputs,
                                            initial_force=c.last_force,
                                            static_ratio=static_ratio(c.props))


#: The controller factory of each ``(mode, control law)``; OFF needs none. A mode missing a
#: law here refuses that law when it is requested explicitly (a default falls back to thesis).
CONTROLLERS: Mapping[tuple[SlipMode, str], ControllerFactory] = MappingProxyType({
    (SlipMode.HOLD, 'thesis'): _thesis_hold,
    (SlipMode.HINGE, 'thesis'): _thesis_hinge,
    (SlipMode.LINEAR, 'thesis'): _thesis_linear,
    (SlipMode.ROTATIONAL, 'thesis'): _thesis_rotational,
    (SlipMode.LINEAR, 'model'): _model_linear,
    (SlipMode.ROTATIONAL, 'model'): _model_rotational,
    (SlipMode.HOLD, 'model'): _model_hold,
    (SlipMode.HINGE, 'model'): _model_hinge,
})


def resolve_control_law(request: ModeRequest, params: SlipControllerParams
                        ) -> tuple[str, str]:
    """The law a request runs with: ``(law, '')``, or ``('', why not)``.

    Args:
        request: The request (its mode must be a valid `SlipMode`).
        params: Controller parameters (``default_control_law``).
    """
    law = request.control_law or params.default_control_law
    if law not in CONTROL_LAWS:
        return '', (f'unknown control_law {request.control_law!r} (expected '
                    f'{", ".join(CONTROL_LAWS)}, or empty for the default)')
    mode = SlipMode(request.mode)
    if mode == SlipMode.OFF or (mode, law) in CONTROLLERS:
        return law, ''
    if not request.control_law:
        return 'thesis', ''
    have = ', '.join(sorted(k[1] for k in CONTROLLERS if k[0] == mode))
    return '', f'{mode.name} has no {law!r} control law (available: {have})'


def _finite(*values: float) -> bool:
    return all(isinstance(v, (int, float)) and math.isfinite(v) for v in values)


def check_contact(mode: SlipMode, props: ContactProperties | None,
                  params: SlipControllerParams) -> tuple[bool, str]:
    """Whether ``props`` are good enough for ``mode`` (§4.1, CE-4).

    Args:
        mode: Requested mode.
        props: Latest contact properties (``None`` if none were received).
        params: Controller parameters (``allow_preset_properties``).

    Returns:
        ``(ok, message)``.
    """
    if mode == SlipMode.OFF:
        return True, ''
    needs_r = mode in (SlipMode.HOLD, SlipMode.ROTATIONAL)
    need = 'valid mu_c and r' if needs_r else 'valid mu_c'
    if props is None:
        return False, f'{mode.name} needs {need}: no contact properties received'
    if props.source == ContactSource.DEFAULT:
        return False, (f'{mode.name} needs {need}: only DEFAULT (placeholder) properties are '
                       'loaded; run the estimation or load a preset')
    if props.source == ContactSource.PRESET and not params.allow_preset_properties:
        return False, (f'{mode.name} needs {need}: preset {props.preset_name!r} is loaded but '
                       'allow_preset_properties is false')
    bad = []
    for k in (1, 2):
        f = props.finger(k)
        if not (f.linear_valid and _finite(f.mu_c) and f.mu_c > 0.0):
            bad.append(f'finger {k} mu_c')
        if needs_r and not (f.rotational_valid and _finite(f.r) and f.r > 0.0):
            bad.append(f'finger {k} r')
    if bad:
        return False, (f'{mode.name} needs {need}; invalid in the {props.source.name} '
                       f'properties: {", ".join(bad)}')
    return True, ''


def validate_request(request: ModeRequest, props: ContactProperties | None,
                     params: SlipControllerParams) -> tuple[bool, str]:
    """Validate a mode request completely, without side effects.

    Args:
        request: The request (SI).
        props: Latest contact properties (refreshed by the caller, §4.1).
        params: Controller parameters.

    Returns:
        ``(ok, message)``; the message names the offending field and value.
    """
    try:
        mode = SlipMode(request.mode)
    except ValueError:
        return False, f'unknown mode {request.mode!r} (expected {_MODE_NAMES})'
    fields = {'duration': request.duration, 'distance': request.distance,
              'angle': request.angle, 'direction.x': request.direction[0],
              'direction.y': request.direction[1], 'direction.z': request.direction[2]}
    for name, value in fields.items():
        if not _finite(value):
            return False, f'{name} = {value!r} is not a finite number'
    p = params
    if mode in (SlipMode.LINEAR, SlipMode.ROTATIONAL) and not (
            p.min_duration <= request.duration <= p.max_duration):
        return False, (f'duration = {request.duration!r} s outside '
                       f'[{p.min_duration}, {p.max_duration}] s')
    if mode == SlipMode.LINEAR:
        if not request.distance > 0.0:
            return False, f'distance = {request.distance!r} m must be > 0'
        if request.distance > p.max_linear_distance:
            return False, (f'distance = {request.distance!r} m is beyond the grasp '
                           f'(max_linear_distance = {p.max_linear_distance} m)')
    _, why = resolve_control_law(request, params)
    if why:
        return False, why
    if mode == SlipMode.ROTATIONAL:
        if not abs(request.angle) > 0.0:
            return False, f'angle = {request.angle!r} rad must be non-zero'
        if abs(request.angle) > p.max_angle:
            return False, (f'|angle| = {abs(request.angle)!r} rad exceeds '
                           f'max_angle = {p.max_angle} rad')
    return check_contact(mode, props, params)


def build_controller(request: ModeRequest, props: ContactProperties | None,
                     params: SlipControllerParams, t: float,
                     previous: SlipController | None = None,
                     inputs: SensorSnapshot | None = None) -> SwitchOutcome:
    """Validate ``request`` and build the complete controller for it (CE-2).

    Nothing is mutated when the request is rejected (by validation or by the law's factory).
    When it is accepted, a running trajectory of ``previous`` is aborted with "preempted"
    (reported in ``preempted``).

    Args:
        request: The request (SI).
        props: Latest contact properties.
        params: Controller parameters (snapshotted into the new controller).
        t: Request time [s] on the stamps' clock: the trajectory starts here.
        previous: Controller currently in charge (for hand-over force and preemption).
        inputs: Latest sensor samples (the model laws measure the load at the request).

    Returns:
        The outcome; swap ``outcome.controller`` in when ``outcome.ok``.
    """
    ok, message = validate_request(request, props, params)
    if not ok:
        return SwitchOutcome(False, message)
    mode = SlipMode(request.mode)
    last = previous.last_force if previous is not None else None
    if mode == SlipMode.OFF:
        preempted = previous.abort('preempted', t) if previous is not None else None
        return SwitchOutcome(True, 'OFF', OffController(params), final_force=last,
                             preempted=preempted)
    assert props is not None
    law, _ = resolve_control_law(request, params)
    contact = ControlContact.from_properties(
        props, use_r=mode in (SlipMode.HOLD, SlipMode.ROTATIONAL) or props.valid)
    context = BuildContext(request, mode, props, contact, params, t, last, inputs)
    try:
        controller = CONTROLLERS[(mode, law)](context)
    except RequestRefused as exc:
        return SwitchOutcome(False, f'{mode.name} ({law} law) refused: {exc}')
    text = _describe(request, mode)
    if law != 'thesis':
        text += f' ({law} law)'
    preempted = previous.abort('preempted', t) if previous is not None else None
    preset = contact.source == ContactSource.PRESET
    if preset:
        text += f' (WARN: preset {contact.preset_name!r} in use)'
    return SwitchOutcome(True, text, controller, preempted=preempted, preset_in_use=preset,
                         control_law=law)


def _describe(request: ModeRequest, mode: SlipMode) -> str:
    """One line for the outcome message and the log."""
    if mode == SlipMode.LINEAR:
        d = _latched_direction(request)
        how = 'latched' if d is None else f'({d[0]:.3f}, {d[1]:.3f})'
        return (f'LINEAR {request.distance:.4f} m in {request.duration:.3f} s, '
                f'direction {how}')
    if mode == SlipMode.ROTATIONAL:
        return (f'ROTATIONAL {request.angle:.4f} rad in {request.duration:.3f} s'
                f'{", sign latched" if request.latch_direction else ""}')
    return mode.name


def with_params(controller: SlipController,
                params: SlipControllerParams) -> SlipController | None:
    """The same mode rebuilt on a new parameter snapshot (live tuning between steps).

    OFF, HOLD and HINGE carry no state beyond their last output, so they are rebuilt at once
    (the last output is handed on, so the force never drops in one step). A running LINEAR or
    ROTATIONAL trajectory keeps its snapshot: ``None`` tells the caller to retry after it ends
    (its HOLD successor is then rebuilt). A finished trajectory becomes its HOLD successor.

    Args:
        controller: Controller currently in charge.
        params: New validated parameters.

    Returns:
        The controller to swap in, or ``None`` to defer.
    """
    if controller.goal_active:
        return None
    last = controller.last_force
    if isinstance(controller, OffController):
        return OffController(params, controller.contact)
    if isinstance(controller, HingeController):
        return HingeController(params, controller.contact, initial_force=last)
    # The model HOLD and HINGE keep their law (what they learned online starts again).
    if isinstance(controller, ModelHingeController):
        return ModelHingeController(params, controller.contact, initial_force=last,
                                    static_ratio=controller.mu_s_ratio)
    if isinstance(controller, ModelHoldController):
        return ModelHoldController(params, controller.contact, initial_force=last)
    return HoldController(params, controller.contact, initial_force=last)


def hold_successor(controller: SlipController, message: str,
                   t: float) -> tuple[HoldController, SlipResult | None]:
    """End ``controller`` (e.g. an ``ExecuteSlip`` cancel) and build its HOLD successor.

    Same hand-over as a finished trajectory (§4.1): the HOLD controller starts from the last
    output, with the contact of the ended controller (``D = ft`` when its ``r`` is unknown).

    Args:
        controller: Controller currently in charge.
        message: Result message of an aborted trajectory ("canceled", ...).
        t: Time of the hand-over [s].

    Returns:
        ``(hold, result)``; ``result`` is ``None`` when no trajectory was running.
    """
    result = controller.abort(message, t)
    return HoldController(controller.params, controller.contact,
                          initial_force=controller.last_force), result
