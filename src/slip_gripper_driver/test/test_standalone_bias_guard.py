# SPDX-License-Identifier: Apache-2.0
"""The standalone netft_driver's bias load check (pure core, no ROS)."""
from __future__ import annotations

import math

import pytest

from slip_gripper_driver.core.standalone_bias_guard import (GripperLoadView,
                                                             StandaloneBiasGuardParams,
                                                             standalone_bias_verdict)

P = StandaloneBiasGuardParams()


def idle_gripper(received: float = 10.0, **changes: object) -> GripperLoadView:
    values: dict[str, object] = dict(received=received, force_target=0.0, force_cmd=0.0,
                                     armed=True, safe_state=False,
                                     measured_grasp_force=math.nan)
    values.update(changes)
    return GripperLoadView(**values)  # type: ignore[arg-type]


def test_unloaded_box_and_idle_gripper_may_be_biased() -> None:
    verdict = standalone_bias_verdict(10.1, P, 1, 0.05, idle_gripper())
    assert verdict.refusal is None and verdict.note == ''


@pytest.mark.parametrize('own, gripper, words', [
    (-3.2, None, 'finger 2 F/T measures 3.2 N of normal force'),
    (-3.2, idle_gripper(), 'finger 2 F/T measures 3.2 N of normal force'),
    (None, idle_gripper(force_target=10.0, force_cmd=10.0),
     'squeezing target of 10.0 N'),
    (None, idle_gripper(force_cmd=4.0), 'commanded to squeeze with 4.0 N'),
    (None, idle_gripper(measured_grasp_force=2.0), 'measures 2.0 N of grasp force'),
])
def test_a_loaded_pad_is_refused_with_the_reason(own: float | None,
                                                  gripper: GripperLoadView | None,
                                                  words: str) -> None:
    verdict = standalone_bias_verdict(10.1, P, 2, own, gripper)
    assert verdict.refusal is not None and words in verdict.refusal
    assert 'open the gripper' in verdict.refusal


def test_a_target_of_a_disarmed_or_safe_gripper_does_not_squeeze() -> None:
    disarmed = idle_gripper(force_target=10.0, armed=False)
    safe = idle_gripper(force_target=10.0, force_cmd=10.0, safe_state=True)
    assert standalone_bias_verdict(10.1, P, 1, 0.0, disarmed).refusal is None
    assert standalone_bias_verdict(10.1, P, 1, 0.0, safe).refusal is None


def test_an_opening_command_and_tension_are_not_a_load() -> None:
    """Compression is −Fz (as the bridge reads it): a drift towards tension or a pulling
    gripper reading does not block the re-bias that would cure it."""
    opening = idle_gripper(force_target=-8.0, force_cmd=-8.0, measured_grasp_force=-1.5)
    assert standalone_bias_verdict(10.1, P, 1, 0.1, opening).refusal is None
    assert standalone_bias_verdict(10.1, P, 1, 1.5, opening).refusal is None


def test_an_old_gripper_status_is_ignored_and_the_reply_says_so() -> None:
    old = idle_gripper(received=1.0, force_target=10.0, force_cmd=10.0,
                       measured_grasp_force=5.0)
    verdict = standalone_bias_verdict(10.0, P, 1, 0.1, old)
    assert verdict.refusal is None
    assert 'no recent gripper status (newest 9.0 s old): only this box' in verdict.note
    none = standalone_bias_verdict(10.0, P, 1, None, None)
    assert none.refusal is None and 'nothing was checked for load' in none.note
    # ... but the box's own reading still counts without a gripper.
    assert standalone_bias_verdict(10.0, P, 1, -0.6, None).refusal is not None


def test_threshold_is_the_parameter_and_nan_readings_are_no_evidence() -> None:
    strict = StandaloneBiasGuardParams(contact_threshold=0.1)
    assert standalone_bias_verdict(10.1, strict, 1, -0.2, idle_gripper()).refusal is not None
    assert standalone_bias_verdict(10.1, P, 1, -0.2, idle_gripper()).refusal is None
    assert standalone_bias_verdict(10.1, P, 1, math.nan,
                                   idle_gripper(force_cmd=math.nan)).refusal is None
