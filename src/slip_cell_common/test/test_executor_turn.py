# SPDX-License-Identifier: Apache-2.0
"""Which executor errors a turn outlives (the race itself runs in the driver node tests)."""
from __future__ import annotations

import pytest
from rclpy._rclpy_pybind11 import RCLError
from rclpy.exceptions import InvalidHandle

from slip_cell_common.executor_turn import spin_once_outliving_destruction


class _Turns:
    """Stands in for an executor whose next turn raises ``error`` (or runs, when None)."""

    def __init__(self, error: Exception | None) -> None:
        self.error = error
        self.timeouts: list[float] = []

    def spin_once(self, timeout_sec: float) -> None:
        self.timeouts.append(timeout_sec)
        if self.error is not None:
            raise self.error


def test_a_turn_that_ran_reports_true_with_the_timeout_passed_on() -> None:
    turns = _Turns(None)
    assert spin_once_outliving_destruction(turns, 0.25) is True
    assert turns.timeouts == [0.25]


@pytest.mark.parametrize('error', [
    InvalidHandle('cannot use Destroyable because destruction was requested'),
    RCLError("Failed to add 'rcl_action_server_t' to wait set: action server pointer is "
             'invalid, at rcl_action/action_server.c:998')])
def test_a_turn_lost_to_a_destroyed_entity_reports_false(error: Exception) -> None:
    assert spin_once_outliving_destruction(_Turns(error), 0.1) is False


def test_other_rcl_errors_propagate() -> None:
    with pytest.raises(RCLError, match='context is invalid'):
        spin_once_outliving_destruction(_Turns(RCLError('context is invalid')), 0.1)
