# SPDX-License-Identifier: Apache-2.0
"""One executor turn that outlives entities destroyed while it waits.

rclpy 7.1.6 collects a node's entities, then adds each to the wait set. When another thread
destroys one in between (a lifecycle cleanup or shutdown transition run from a service
callback, or from a test thread), adding it raises ``InvalidHandle`` ("destruction was
requested") or ``RCLError`` ("... pointer is invalid") out of ``spin_once``. Nothing was
taken or run in that turn; the next turn collects the entities again without the destroyed
one. Without this guard the exception ended the process's spin loop: a driver that had just
made its hardware safe on cleanup then exited with an "unhandled error".
"""
from __future__ import annotations

from typing import Any

from rclpy.exceptions import InvalidHandle
from rclpy._rclpy_pybind11 import RCLError

#: How rcl reports an entity that was already finalised when it was added to a wait set.
_DESTROYED_ENTITY_TEXT = 'pointer is invalid'


def spin_once_outliving_destruction(executor: Any, timeout_sec: float) -> bool:
    """``executor.spin_once(timeout_sec)``; False when the turn was lost to an entity that
    another thread destroyed meanwhile (nothing ran; call again). Other errors propagate."""
    try:
        executor.spin_once(timeout_sec=timeout_sec)
    except InvalidHandle:
        return False
    except RCLError as exc:
        if _DESTROYED_ENTITY_TEXT not in str(exc):
            raise
        return False
    return True
