# SPDX-License-Identifier: Apache-2.0
"""When a standalone ``netft_driver`` must refuse ``finger_<k>/ft/bias`` (ROS-free).

The complete load check lives in the gripper bridge (`GripperBridge.bias_refusal`, behind
``gripper/bias_ft``). A ``netft_driver`` in a cell with ``ft.mode: topic`` serves its own bias
service as well, which anyone can call directly. A bias taken while the pads squeeze an object
absorbs that load (every later force reads low by it and the loop squeezes harder), so this
service checks what one box can know:

* its own bias-removed normal force, when it has a bias and a fresh sample (compression,
  ``−Fz``, as the gripper bridge reads it);
* the newest ``gripper/status`` of the gripper driver, when one arrived within
  ``status_timeout``: an armed squeezing target, a squeezing motor command, or a measured
  grasp force.

Without a recent gripper status only the box's own reading is checked, and the service says
so in its reply (the motor may still hold its last voltage: the firmware has no watchdog).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from slip_cell_common.core.validation import validate_fields


@dataclass(frozen=True)
class StandaloneBiasGuardParams:
    """Load check of the ``netft_driver`` bias service (parameter group ``bias_guard``)."""

    contact_threshold: float = field(default=0.5, metadata={
        'unit': 'N', 'range': (0.0, 1000.0),
        'description': 'bias refused while this box measures at least this compression '
                       '(-Fz, bias removed), or the gripper status reports a squeezing '
                       'target, command or measured grasp force of this size'})
    status_timeout: float = field(default=0.5, metadata={
        'unit': 's', 'range': (0.01, 60.0),
        'description': 'a gripper/status older than this is not considered (no gripper '
                       'driver running): only this box\'s own reading is checked'})

    def validate(self) -> None:
        """Raise `ParameterError` listing every invalid field."""
        validate_fields(self)


@dataclass(frozen=True)
class GripperLoadView:
    """What one ``gripper/status`` says about the pads' load (node clock, SI).

    Attributes:
        received: Node-clock time the status arrived [s].
        force_target: Grasp-force target in use [N] (> 0 squeezes).
        force_cmd: Last inner-loop force command [N].
        armed: Force commands are applied.
        safe_state: The safe voltage is applied (fault or stop).
        measured_grasp_force: The gripper's bias-removed grasp force [N] (NaN: unknown).
    """

    received: float
    force_target: float
    force_cmd: float
    armed: bool
    safe_state: bool
    measured_grasp_force: float


@dataclass(frozen=True)
class BiasGuardVerdict:
    """Outcome of the check: ``refusal`` (None: allowed) and a note for the reply."""

    refusal: str | None
    note: str = ''


def standalone_bias_verdict(now: float, params: StandaloneBiasGuardParams, finger: int,
                            own_normal_force: float | None,
                            gripper: GripperLoadView | None) -> BiasGuardVerdict:
    """Whether finger ``finger``'s box may be biased at ``now`` [s].

    Args:
        now: Node-clock time [s].
        params: Thresholds.
        finger: Finger number (for the message).
        own_normal_force: This box's bias-removed Fz of a fresh sample [N] (compression is
            negative), or None when it has no bias yet or no fresh sample.
        gripper: Newest gripper status, or None when none arrived.
    """
    threshold = params.contact_threshold
    reasons: list[str] = []
    own_checked = own_normal_force is not None and math.isfinite(own_normal_force)
    if own_checked and own_normal_force is not None and -own_normal_force >= threshold:
        reasons.append(f'finger {finger} F/T measures {-own_normal_force:.1f} N of normal '
                       'force')
    recent = gripper is not None and now - gripper.received <= params.status_timeout
    if gripper is not None and recent:
        squeezing_target = gripper.armed and not gripper.safe_state and \
            gripper.force_target > 0.0
        if squeezing_target:
            reasons.append(f'the gripper holds a squeezing target of {gripper.force_target:.1f} '
                           'N')
        if math.isfinite(gripper.force_cmd) and gripper.force_cmd >= threshold and \
                not gripper.safe_state:
            reasons.append(f'the gripper motor is commanded to squeeze with '
                           f'{gripper.force_cmd:.1f} N')
        grasp = gripper.measured_grasp_force
        if math.isfinite(grasp) and grasp >= threshold:
            reasons.append(f'the gripper measures {grasp:.1f} N of grasp force')
    if reasons:
        return BiasGuardVerdict('the pads may be loaded: ' + '; '.join(reasons)
                                + ' (open the gripper with a negative grasp force, then bias)')
    if not recent:
        age = '' if gripper is None else f' (newest {now - gripper.received:.1f} s old)'
        if not own_checked:
            return BiasGuardVerdict(None, f'no recent gripper status{age} and no biased '
                                          'reading of this box: nothing was checked for load')
        return BiasGuardVerdict(None, f'no recent gripper status{age}: only this box\'s own '
                                      'reading was checked for load')
    return BiasGuardVerdict(None)
