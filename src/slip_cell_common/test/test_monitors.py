"""Diagnostics monitors (ROS-free)."""
from __future__ import annotations

import pytest

from slip_cell_common.core.monitors import AgeMonitor, FrequencyMonitor, Level


def test_frequency_monitor_levels() -> None:
    mon = FrequencyMonitor(expected_hz=100.0, tolerance=0.1, window_s=1.0)
    assert mon.report(0.0).level == Level.ERROR
    for k in range(200):
        mon.tick(k * 0.01)
    assert mon.rate(1.995) == pytest.approx(100.0, rel=0.02)
    assert mon.report(1.995).level == Level.OK
    for k in range(50):
        mon.tick(2.0 + k * 0.02)
    assert mon.report(2.99).level == Level.WARN


def test_age_monitor() -> None:
    mon = AgeMonitor(0.02)
    assert not mon.fresh(1.0)
    mon.tick(1.0)
    assert mon.fresh(1.015) and not mon.fresh(1.03)
    with pytest.raises(ValueError):
        AgeMonitor(0.0)
