# SPDX-License-Identifier: Apache-2.0
"""`log_event` logs one source of events at changing severities through a real rclpy logger."""
from __future__ import annotations

import pytest


def test_one_event_source_may_log_at_every_severity_in_turn() -> None:
    from rclpy.logging import get_logger

    from slip_cell_common.log_sink import log_event
    logger = get_logger('log_sink_test')

    def report(level: str) -> None:  # one call site, as a core's event callback is
        log_event(logger, level, f'event at {level}')
    for level in ('info', 'warn', 'error', 'info', 'error'):
        report(level)

    def naive(ok: bool) -> None:  # the pattern log_event replaces
        (logger.info if ok else logger.error)('naive')
    naive(True)
    with pytest.raises(ValueError, match='severity cannot be changed'):
        naive(False)
