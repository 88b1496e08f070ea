# SPDX-License-Identifier: Apache-2.0
"""Hand ``(level, message)`` events of ROS-free cores to a node's logger.

rclpy remembers the severity of each logging call site and raises when one site logs at
another severity later ("Logger severity cannot be changed between calls"), so a choice of
severity at run time needs one call site per severity: this function.
"""
from __future__ import annotations

from typing import Any


def log_event(logger: Any, level: str, message: str) -> None:
    """Log ``message`` at ``level`` (``'error'``, ``'warn'``, anything else: info)."""
    if level == 'error':
        logger.error(message)
    elif level == 'warn':
        logger.warning(message)
    else:
        logger.info(message)
