"""A command-line ROS session: one node, its executor spinning on a thread, bounded waits.

The executor spins on a `SpinThread`; commands wait for futures and graph conditions by
polling (never ``spin_until_future_complete``, which leaks tasks in rclpy 7.1.6). `close` joins
the spinning thread before the executor and the node are destroyed.
"""
from __future__ import annotations

import os
import time
from typing import Any
from collections.abc import Callable

from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from slip_cell_common.testing import SpinThread


class CliError(RuntimeError):
    """A command failed; the message is printed and the exit code is 1."""


class CliSession:
    """The CLI's node (hidden name, so it never lists itself) and its spinning executor.

    Args:
        timeout_s: Default bound of every wait [s, wall clock].
    """

    def __init__(self, timeout_s: float) -> None:
        self.node = Node(f'_slip_cli_{os.getpid()}')
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.timeout_s = timeout_s
        self._spin = SpinThread(self.executor, slice_s=0.02).start()

    def wait(self, predicate: Callable[[], bool], timeout_s: float | None = None,
             step_s: float = 0.01) -> bool:
        """Poll ``predicate`` until true or ``timeout_s`` passes; returns its last value."""
        deadline = time.monotonic() + (self.timeout_s if timeout_s is None else timeout_s)
        while time.monotonic() < deadline:
            if predicate():
                return True
            time.sleep(step_s)
        return bool(predicate())

    def call(self, srv_type: type, name: str, request: Any,
             timeout_s: float | None = None) -> Any:
        """Call a service; the response, or `CliError` when it is absent or silent."""
        timeout_s = self.timeout_s if timeout_s is None else timeout_s
        client = self.node.create_client(srv_type, name)
        try:
            if not self.wait(client.service_is_ready, timeout_s):
                raise CliError(f'service {name} is not available after {timeout_s:.0f} s '
                               '(is the node running on this ROS_DOMAIN_ID?)')
            future = client.call_async(request)
            if not self.wait(future.done, timeout_s):
                client.remove_pending_request(future)
                raise CliError(f'service {name} did not answer within {timeout_s:.0f} s')
            return future.result()
        finally:
            self.node.destroy_client(client)

    def settle_discovery(self, snapshot: Callable[[], frozenset[Any]], max_s: float,
                         min_s: float = 0.5, stable_s: float = 1.0) -> frozenset[Any]:
        """Let DDS discovery fill the graph (no daemon caches it here): wait at least ``min_s``,
        then until ``snapshot()`` is non-empty and unchanged for ``stable_s``, at most
        ``max_s`` [s]. Returns the last snapshot."""
        start = time.monotonic()
        last, since = snapshot(), start
        while time.monotonic() - start < max_s:
            time.sleep(0.1)
            now, current = time.monotonic(), snapshot()
            if current != last:
                last, since = current, now
            elif current and now - start >= min_s and now - since >= stable_s:
                break
        return last

    def close(self) -> None:
        """Join the spinning thread, then shut the executor down and destroy the node."""
        self._spin.stop()
        self.executor.shutdown()
        self.node.destroy_node()
