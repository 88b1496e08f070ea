"""Bounded service calls without ``spin_until_future_complete`` (rclpy 7.1.6 leaks tasks there)."""
from __future__ import annotations

import time
from typing import Any
from collections.abc import Callable

from rclpy.executors import Executor


def spin_until(executor: Executor, predicate: Callable[[], bool], timeout_s: float,
               step_s: float = 0.01) -> bool:
    """Spin ``executor`` until ``predicate()`` is true; False after ``timeout_s`` (wall clock)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        executor.spin_once(timeout_sec=step_s)
    return predicate()


def call_service(executor: Executor, client: Any, request: Any, timeout_s: float = 10.0) -> Any:
    """Call a service with ``call_async``, spinning until the response; None on timeout.

    The first call from a new client to a long-running server can take ~2 s (Fast DDS
    discovery of the response path), so keep ``timeout_s`` ≥ 5 s for first calls.
    """
    if not spin_until(executor, client.service_is_ready, timeout_s):
        return None
    future = client.call_async(request)
    spin_until(executor, future.done, timeout_s)
    if not future.done():
        client.remove_pending_request(future)
        return None
    return future.result()
