# SPDX-License-Identifier: Apache-2.0
"""Error-flagged Net F/T records never reach the grasp loop, in both F/T modes (real rclpy).

``gripper_driver`` runs against the pty firmware emulator; two Net F/T emulators share the
host address 127.0.0.1 on their own RDT and HTTP ports (per-box ports; the scale and the
measuring range are read from each box's ``netftapi2.xml``). In ``embedded`` mode the gripper
driver owns both boxes; in ``topic`` mode two ``netft_driver`` nodes do, and the gripper driver
consumes ``finger_k/ft/wrench``. One box then streams status ``0x80020000`` (saturation / A-D
error) at its full rate: the loop gets no sample from it (F/T not fresh: the safe fallback)
until the box is healthy again.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any
from collections.abc import Iterator

import pytest

from slip_gripper_driver.core.firmware_emulator import (FirmwareEmulator, GripperModelParams,
                                                        PtyFirmwareEmulator)
from slip_gripper_driver.core.netft_emulator import NetFTEmulator

pytestmark = pytest.mark.ros

TIMEOUT_S = 10.0
#: Half the real 1 kHz: one test process holds the firmware, two boxes and up to three nodes.
BOX_RATE_HZ = 500.0
SATURATED = 0x80020000


class Bench:
    """Firmware on a pty and two boxes on 127.0.0.1, each on its own UDP and HTTP port."""

    def __init__(self, tmp_path: Path) -> None:
        model = GripperModelParams(object_width=0.03, initial_opening=0.031)
        self.firmware = PtyFirmwareEmulator(FirmwareEmulator(model),
                                            link_path=str(tmp_path / 'gripper'))
        self.firmware.start()

        def pad(_: float) -> tuple[float, ...]:
            return (0.0, 0.0, -self.firmware.grasp_force(), 0.0, 0.0, 0.0)
        self.boxes = [NetFTEmulator(rate_hz=BOX_RATE_HZ, force_source=pad, serve_http=True,
                                    offsets=(0.0, 0.0, fz, 0.0, 0.0, 0.0), noise_std=0.01,
                                    seed=k)
                      for k, fz in ((1, 1.5), (2, -0.7))]
        for box in self.boxes:
            box.start()

    def box_params(self, k: int) -> dict[str, Any]:
        box = self.boxes[k - 1]
        return {'address': '127.0.0.1', 'port': box.address[1], 'http_port': box.http_port}

    def stop(self) -> None:
        self.firmware.stop()
        for box in self.boxes:
            box.stop()


@pytest.fixture
def bench(tmp_path: Path) -> Iterator[Bench]:
    b = Bench(tmp_path)
    yield b
    b.stop()


@pytest.fixture
def switch_interval() -> Iterator[None]:
    """The driver's GIL switch interval (``main`` sets it): ~10 busy threads in one process."""
    from slip_gripper_driver.gripper_driver_node import SWITCH_INTERVAL_S
    previous = sys.getswitchinterval()
    sys.setswitchinterval(SWITCH_INTERVAL_S)
    yield
    sys.setswitchinterval(previous)


def _params(values: dict[str, Any]) -> list[Any]:
    from rclpy.parameter import Parameter
    return [Parameter(k, value=v) for k, v in values.items()]


def wait_until(predicate: Any, timeout_s: float = TIMEOUT_S) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.01)
    return bool(predicate())


@pytest.mark.parametrize('mode', ['embedded', 'topic'])
def test_error_status_records_never_reach_the_loop(bench: Bench, ros_context: Any, mode: str,
                                                   switch_interval: None) -> None:
    from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor
    from rclpy.lifecycle import TransitionCallbackReturn
    from rclpy.node import Node
    from std_srvs.srv import Trigger

    from slip_cell_common.node_main import shutdown_lifecycle
    from slip_cell_common.testing import SpinThread, call_service
    from slip_gripper_driver.gripper_driver_node import GripperDriverNode
    from slip_gripper_driver.netft_driver_node import NetFTDriverNode

    ports: dict[str, Any] = {}
    for k in (1, 2):
        ports.update({f'ft.finger_{k}.{key}': value
                      for key, value in bench.box_params(k).items()})
    gripper = GripperDriverNode(context=ros_context, parameter_overrides=_params({
        'autostart': False, 'serial.port': bench.firmware.port, 'ft.mode': mode, **ports,
        'ft.read_config': True, 'ft.expected_rate': BOX_RATE_HZ, 'ft.publish_decimation': 1,
        # Robust against scheduling gaps of a loaded, shared host (as the driver node tests).
        'link.stale_after': 0.5, 'link.fault_after': 1.0,
        'reconnect.initial_delay': 0.05, 'reconnect.max_delay': 0.2,
        'force_control.ft_stale_after': 0.05, 'force_control.ft_fault_after': 0.2,
        'bias.duration': 0.5}))
    drivers = []
    if mode == 'topic':
        drivers = [NetFTDriverNode(f'netft_driver_{k}', context=ros_context,
                                   parameter_overrides=_params({
                                       'autostart': False, 'finger': k, **bench.box_params(k),
                                       'read_config': True, 'expected_rate': BOX_RATE_HZ,
                                       'publish_decimation': 1, 'bias.duration': 0.5}))
                   for k in (1, 2)]
    nodes = (gripper, *drivers)
    executor = MultiThreadedExecutor(num_threads=4, context=ros_context)
    for node in nodes:
        executor.add_node(node)
    spinner = SpinThread(executor).start()
    probe = Node('probe', context=ros_context)
    probe_exec = SingleThreadedExecutor(context=ros_context)
    probe_exec.add_node(probe)
    box = bench.boxes[0]
    try:
        for node in nodes:  # the gripper first: its configure freezes the GC (a long pause)
            assert node.trigger_configure() == TransitionCallbackReturn.SUCCESS, node.last_error
            assert node.trigger_activate() == TransitionCallbackReturn.SUCCESS
        assert len(gripper.channels) == (2 if mode == 'embedded' else 0)
        assert all(b.starts >= 1 for b in bench.boxes)  # each box reached on its own port
        client = probe.create_client(Trigger, 'gripper/bias_ft')
        reply = call_service(probe_exec, client, Trigger.Request(), 15.0)
        assert reply is not None and reply.success, reply

        def status() -> Any:
            return gripper.core.bridge.status(gripper.now())

        def loop_samples() -> int:  # samples of finger 1 that reached the loop
            return gripper.core.bridge.diagnostics(gripper.now()).ft_samples[0]
        assert wait_until(lambda: status().ft_biased and status().ft_fresh)

        box.set_status(SATURATED)
        sent = box.records_sent
        assert wait_until(lambda: box.records_sent >= sent + 100)  # flagged ones in flight
        assert wait_until(lambda: not status().ft_fresh)
        before = loop_samples()
        sent = box.records_sent
        assert wait_until(lambda: box.records_sent >= sent + 300)
        assert loop_samples() == before, 'an error-flagged record reached the grasp loop'
        assert not status().ft_fresh
        owner = gripper.channels[0] if mode == 'embedded' else drivers[0].channel
        assert owner is not None and owner.health().status_errors >= 300

        box.set_status(0)
        assert wait_until(lambda: loop_samples() > before + 50)
        assert wait_until(lambda: status().ft_fresh)
    finally:
        spinner.stop()  # no wait set may hold entities that the shutdown destroys
        for node in nodes:
            shutdown_lifecycle(node)
        executor.shutdown()
        probe_exec.shutdown()
        for node in (*nodes, probe):
            node.destroy_node()
    # Each driver's stop request is a datagram the box's own thread receives after the
    # shutdown returned.
    assert wait_until(lambda: all(b.stops >= 1 for b in bench.boxes))
