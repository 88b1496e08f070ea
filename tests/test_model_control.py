# SPDX-License-Identifier: Apache-2.0
"""The model-based slip laws on drawn objects of the simulated cell, judged by its truth.

Objects of population seed 11 (`friction_models.core.population.draw_object`) that can slide
and turn (`slip_bringup.population.feasibility`), with the simulator's true contact properties.
The targets of issue 15: LINEAR 20 mm / ROTATIONAL 20° in 2 s, true final error ≤ 1 mm / 1°,
true tracking RMS over the trajectory ≤ 1 mm / 1°, ended "done" within ±10 % of the duration.
"""
from __future__ import annotations

import math

import pytest

from friction_models.core.population import draw_object
from slip_bringup.core.evaluation.poses import lever_horizontal_turn
from slip_bringup.core.evaluation.settings import EvalSettings
from slip_bringup.core.evaluation.trajectories import linear_slip, rotational_slip
from slip_bringup.population.feasibility import assess

pytestmark = pytest.mark.slow

SEED = 11
DEG = math.pi / 180.0


def _settings(index: int) -> tuple[str, EvalSettings, tuple[float, float]]:
    obj = draw_object(SEED, index)
    return obj.name, EvalSettings(objects={obj.name: obj.preset}, sensors=obj.sensors,
                                  control_law='model'), obj.preset.com_offset


@pytest.mark.parametrize('index', [9, 16, 30])
def test_model_linear_follows_the_trapezoid_by_truth(index: int) -> None:
    assert not assess(draw_object(SEED, index).preset, []).linear      # it can slide
    name, settings, _ = _settings(index)
    out = linear_slip(name, 0.02, 2.0, settings)
    assert out.result is not None and out.result.message == 'done' and out.result.success
    assert not out.dropped
    assert abs(out.final_error) <= 0.001
    assert out.trajectory_rms <= 0.001
    assert abs(out.result_time - 2.0) <= 0.2


@pytest.mark.parametrize('index', [6, 13, 17])
def test_model_rotational_follows_the_trapezoid_by_truth(index: int) -> None:
    assert not assess(draw_object(SEED, index).preset, []).rotational  # it can turn
    name, settings, com = _settings(index)
    turn, sign = lever_horizontal_turn(com)
    out = rotational_slip(name, sign * 20.0 * DEG, 2.0, settings, turn=turn)
    assert out.result is not None and out.result.success
    assert not out.dropped
    assert abs(out.final_error) <= 1.0 * DEG
    assert out.trajectory_rms <= 1.0 * DEG
    assert abs(out.result_time - 2.0) <= 0.2


def test_model_law_refuses_a_slide_the_load_cannot_make() -> None:
    """Object 1 (0.09 kg, μ_s up to 1.6 μ_c) cannot overcome static friction at 0.6 N: the
    model law refuses the LINEAR request with the measured numbers instead of "done"."""
    from slip_bringup.core.evaluation.scene import controlled_scene
    from slip_control.core.controllers import SlipMode
    from slip_control.core.mode_switch import ModeRequest
    name, settings, _ = _settings(1)
    h, ctl, _ = controlled_scene(name, settings, None)
    out = ctl.set_mode(h, ModeRequest(int(SlipMode.LINEAR), 2.0, 0.02, latch_direction=True,
                                      control_law='model'))
    assert not out.ok
    assert 'cannot overcome static friction' in out.message
    assert 'minimum force 0.60 N' in out.message
