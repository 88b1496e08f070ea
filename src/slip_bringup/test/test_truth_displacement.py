# SPDX-License-Identifier: Apache-2.0
"""The judge's displacement of the object point at the gripper centre (no ROS)."""
from __future__ import annotations

import math

import pytest

from slip_bringup.core.evaluation.truth import centre_point_displacement


def _turned(x0: float, y0: float, angle: float, cx: float = 0.0, cy: float = 0.0
            ) -> tuple[float, float]:
    """``(x0, y0)`` turned by ``angle`` about ``(cx, cy)``."""
    c, s = math.cos(angle), math.sin(angle)
    return cx + c * (x0 - cx) - s * (y0 - cy), cy + s * (x0 - cx) + c * (y0 - cy)


def test_a_turn_about_the_gripper_centre_moves_nothing_there() -> None:
    # The tracked point sits 6 mm off the centre after earlier slips; the object turns 60°
    # about the centre: the tracked point moves 6 mm, the point at the centre does not.
    x0, y0, angle = 0.006, 0.0, math.radians(60.0)
    x1, y1 = _turned(x0, y0, angle)
    assert math.hypot(x1 - x0, y1 - y0) == pytest.approx(0.006)
    dx, dy = centre_point_displacement(x0, y0, 0.1, x1, y1, 0.1 + angle)
    assert math.hypot(dx, dy) == pytest.approx(0.0, abs=1e-12)


def test_a_turn_about_another_point_and_a_slide_move_the_centre_point() -> None:
    x0, y0, angle = 0.004, -0.003, math.radians(30.0)
    # Turn about (0, 5 mm): the point at the centre moves on that circle.
    x1, y1 = _turned(x0, y0, angle, 0.0, 0.005)
    cx, cy = _turned(0.0, 0.0, angle, 0.0, 0.005)
    assert centre_point_displacement(x0, y0, 0.0, x1, y1, angle) == pytest.approx((cx, cy))
    # A slide without turning moves every point alike.
    assert centre_point_displacement(x0, y0, 0.2, x0 + 0.001, y0 - 0.002, 0.2) == \
        pytest.approx((0.001, -0.002))
