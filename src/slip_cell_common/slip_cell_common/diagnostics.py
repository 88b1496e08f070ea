"""Publish ``diagnostic_msgs/DiagnosticArray`` on ``/diagnostics``.

(diagnostic_updater is not on PyPI.)

Tasks are callables ``(now_s) -> Report``; statuses are named ``"<node>: <task>"`` and carry the
hardware id (port or address). Published on a node-clock timer (1 Hz by default).
"""
from __future__ import annotations

from collections.abc import Callable

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.node import Node

from slip_cell_common.core import names
from slip_cell_common.core.monitors import Level, Report
from slip_cell_common.qos import DIAGNOSTICS
from slip_cell_common.time_conv import clock_seconds

Task = Callable[[float], Report]


def now_s(node: Node) -> float:
    """The node clock (sim time when ``use_sim_time``) in seconds."""
    return clock_seconds(node.get_clock())


class DiagnosticsPublisher:
    """Collects task reports and publishes them periodically."""

    def __init__(self, node: Node, hardware_id: str = '', period_s: float = 1.0) -> None:
        self._node = node
        self.hardware_id = hardware_id
        self._tasks: list[tuple[str, Task]] = []
        self._pub = node.create_publisher(DiagnosticArray, names.DIAGNOSTICS, DIAGNOSTICS)
        self._timer = node.create_timer(period_s, self.publish)

    def add(self, name: str, task: Task) -> None:
        """Register a task; its report appears as ``"<node>: <name>"``."""
        self._tasks.append((name, task))

    def statuses(self) -> list[DiagnosticStatus]:
        """Evaluate every task now (a failing task is reported as ERROR, never raised)."""
        t = now_s(self._node)
        out = []
        for name, task in self._tasks:
            try:
                report = task(t)
            except Exception as exc:
                report = Report(Level.ERROR, f'diagnostic task failed: {exc!r}')
            out.append(DiagnosticStatus(
                level=bytes([int(report.level)]), name=f'{self._node.get_name()}: {name}',
                message=report.message, hardware_id=self.hardware_id,
                values=[KeyValue(key=k, value=v) for k, v in report.values]))
        return out

    def publish(self) -> None:
        """Publish one DiagnosticArray with every task's status."""
        if not self._tasks:
            return
        msg = DiagnosticArray()
        msg.header.stamp = self._node.get_clock().now().to_msg()
        msg.status = self.statuses()
        self._pub.publish(msg)

    def destroy(self) -> None:
        """Stop the timer and the publisher."""
        self._node.destroy_timer(self._timer)
        self._node.destroy_publisher(self._pub)
