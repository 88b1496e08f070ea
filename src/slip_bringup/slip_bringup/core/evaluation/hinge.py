# SPDX-License-Identifier: Apache-2.0
"""HINGE on the simulated cell (§5.3 ``go_to_hinge_pose`` + ``hinge_mode``), judged by the truth."""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from slip_bringup.core.evaluation.poses import hinge_start_turn
from slip_bringup.core.evaluation.scene import controlled_scene
from slip_bringup.core.evaluation.settings import EvalSettings
from slip_bringup.core.evaluation.truth import centre_point_displacement
from slip_control.core.contact import ContactProperties
from slip_control.core.controllers import SlipMode
from slip_control.core.mode_switch import ModeRequest

_NAN = math.nan


@dataclass(frozen=True)
class HingeOutcome:
    """Outcome of `hinge` (truth).

    Attributes:
        preset: Object preset.
        gripper_turn: Turn of the gripper under HINGE [rad].
        swing: Relative rotation while HINGE settles at the hinge pose, before the turn [rad].
        relative_rotation: Rotation of the object relative to the pads from the start of the
            turn to the end of the wait [rad]; ``−gripper_turn`` for an ideal hinge (the object
            keeps its orientation in the world while the gripper turns about it).
        object_turn: Turn of the object in the world over the same window [rad] (ideal 0).
        translation_peak: Largest grasp-point displacement relative to the pads from HINGE on
            to the end [m] (ideal 0: HINGE stops translation).
        translation_turn: Grasp-point displacement from the start of the turn to the end of
            the wait [m].
        force_min: Smallest commanded force under HINGE [N].
        force_max: Largest commanded force under HINGE [N].
        dropped: The object fell.
    """

    preset: str
    gripper_turn: float
    swing: float
    relative_rotation: float
    object_turn: float
    translation_peak: float
    translation_turn: float
    force_min: float
    force_max: float
    dropped: bool

    @property
    def rotation_error(self) -> float:
        """``|gripper_turn| − |relative_rotation|`` [rad]: how much the object followed."""
        return abs(self.gripper_turn) - abs(self.relative_rotation)


def hinge(preset: str, turn: float = math.radians(60.0), settings: EvalSettings = EvalSettings(),
          properties: ContactProperties | None = None, start_angle: float = math.radians(60.0),
          settle: float = 1.0, wait: float = 2.0,
          hinge_com: Sequence[float] | None = None) -> HingeOutcome:
    """§5.3 ``go_to_hinge_pose`` + ``hinge_mode`` on an object held in the air.

    HOLD while the gripper turns to the hinge pose (``start_angle``), HINGE on, ``settle``
    [s] (the object swings towards hanging; this pause is ours, so the turn is measured on its
    own), the gripper turns another ``turn`` (runner's motion time), ``wait``, HOLD on.

    ``hinge_com`` (CoM offset from the grasp point, object frame [m]), when given, replaces
    ``start_angle`` and the sign of ``turn``: the hinge pose puts the object ``|turn|`` from
    hanging (`poses.hinge_start_turn`, from the object's rotation in the pads after the
    pick-up), and the gripper then turns on the same way.
    """
    h, ctl, probe = controlled_scene(preset, settings, properties)
    if hinge_com is not None:
        s = h.state()
        start_angle, sign = hinge_start_turn(hinge_com, abs(turn), s.theta)
        start_angle -= s.arm_angle
        turn = sign * abs(turn)
    h.move(rotation=start_angle)
    h.run_for(0.3)
    ctl.require_mode(h, ModeRequest(int(SlipMode.HINGE)))
    t_on = h.t
    s_on = h.state()
    h.run_for(settle)
    s1 = h.state()
    h.move(rotation=turn)
    h.run_for(wait)
    t_end = h.t
    s2 = h.state()
    forces = ctl.forces_between(t_on, t_end) or [_NAN]
    ctl.require_mode(h, ModeRequest(int(SlipMode.HOLD)))
    h.run_for(0.5)
    s3 = h.state()
    return HingeOutcome(
        preset=preset, gripper_turn=turn, swing=s1.theta - s_on.theta,
        relative_rotation=s2.theta - s1.theta, object_turn=s2.object_theta - s1.object_theta,
        translation_peak=probe.peak_displacement(t_on, h.t, s_on.x, s_on.y, s_on.theta),
        translation_turn=math.hypot(*centre_point_displacement(
            s1.x, s1.y, s1.theta, s2.x, s2.y, s2.theta)), force_min=min(forces),
        force_max=max(forces), dropped=s3.dropped)
