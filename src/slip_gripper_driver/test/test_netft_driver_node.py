# SPDX-License-Identifier: Apache-2.0
"""netft_driver with real rclpy against the Net F/T emulator on 127.0.0.1 (real RDT codecs)."""
from __future__ import annotations

import socket
from typing import Any
from collections.abc import Iterator

import pytest

from slip_gripper_driver.core.netft_emulator import NetFTEmulator

pytestmark = pytest.mark.ros

TIMEOUT_S = 10.0
OFFSET_FZ = 2.5  # [N] what biasing removes


@pytest.fixture
def box() -> Iterator[NetFTEmulator]:
    emu = NetFTEmulator(host='127.0.0.1', port=0, rate_hz=1000.0,
                        offsets=(0.1, 0.0, OFFSET_FZ, 0.0, 0.0, 0.01), noise_std=0.01, seed=3)
    emu.start()
    yield emu
    emu.stop()


def overrides(port: int, **extra: Any) -> list[Any]:
    from rclpy.parameter import Parameter
    values: dict[str, Any] = {'autostart': False, 'finger': 2, 'address': '127.0.0.1',
                              'port': port, 'read_config': False, 'counts_per_force': 1.0e6,
                              'counts_per_torque': 1.0e6, 'publish_raw': True}
    values.update(extra)
    return [Parameter(k, value=v) for k, v in values.items()]


def test_raw_then_bias_service_then_biased_wrench_diagnostics_and_stop_on_shutdown(
        ros_context: Any, box: NetFTEmulator) -> None:
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import WrenchStamped
    from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor
    from rclpy.lifecycle import TransitionCallbackReturn
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from rclpy.qos import QoSProfile
    from std_srvs.srv import Trigger

    from slip_cell_common.node_main import shutdown_lifecycle
    from slip_gripper_driver.netft_driver_node import NetFTDriverNode
    from slip_cell_common.testing import SpinThread, call_service, spin_until

    node = NetFTDriverNode(context=ros_context, parameter_overrides=overrides(box.address[1]))
    executor = MultiThreadedExecutor(num_threads=2, context=ros_context)
    executor.add_node(node)
    spinner = SpinThread(executor).start()
    probe = Node('probe', context=ros_context)
    probe_exec = SingleThreadedExecutor(context=ros_context)
    probe_exec.add_node(probe)
    raw: list[WrenchStamped] = []
    biased: list[WrenchStamped] = []
    diags: list[DiagnosticArray] = []
    probe.create_subscription(WrenchStamped, 'finger_2/ft/raw', raw.append, QoSProfile(depth=500))
    probe.create_subscription(WrenchStamped, 'finger_2/ft/wrench', biased.append,
                              QoSProfile(depth=500))
    probe.create_subscription(DiagnosticArray, '/diagnostics', diags.append, 10)
    client = probe.create_client(Trigger, 'finger_2/ft/bias')
    try:
        assert node.trigger_configure() == TransitionCallbackReturn.SUCCESS, node.last_error
        assert node.trigger_activate() == TransitionCallbackReturn.SUCCESS
        assert spin_until(probe_exec, lambda: len(raw) > 100, TIMEOUT_S)
        assert not biased  # the bias-removed topic stays silent until a bias exists
        assert raw[-1].header.frame_id == 'ft_sensor_2'
        assert raw[-1].wrench.force.z == pytest.approx(OFFSET_FZ, abs=0.1)

        reply = call_service(probe_exec, client, Trigger.Request(), TIMEOUT_S)
        assert reply is not None and reply.success, reply
        assert '127.0.0.1' in reply.message
        assert spin_until(probe_exec, lambda: len(biased) > 100, TIMEOUT_S)
        recent = biased[-50:]
        assert sum(w.wrench.force.z for w in recent) / 50 == pytest.approx(0.0, abs=0.05)
        assert sum(w.wrench.torque.z for w in recent) / 50 == pytest.approx(0.0, abs=0.05)
        assert spin_until(probe_exec, lambda: any(
            s.name == 'netft_driver: ft' and s.level == b'\x00' for d in diags[-1:]
            for s in d.status), 5.0), diags[-1] if diags else 'no diagnostics'
        status = next(s for s in diags[-1].status if s.name == 'netft_driver: ft')
        values = {kv.key: kv.value for kv in status.values}
        assert status.hardware_id == '127.0.0.1'
        assert float(values['rate_hz']) == pytest.approx(1000.0, rel=0.15)
        assert values['biased'] == 'true' and values['status'] == '0x00000000'

        # device-side bias (0x0042) selected at run time; verified by a host window
        assert node.set_parameters([Parameter('bias.mode', value='device')])[0].successful
        reply = call_service(probe_exec, client, Trigger.Request(), TIMEOUT_S)
        assert reply is not None and reply.success, reply
        assert box.biases == 1
    finally:
        spinner.stop()  # no wait set may hold entities that the shutdown destroys
        shutdown_lifecycle(node)
        executor.shutdown()
        probe_exec.shutdown()
        node.destroy_node()
        probe.destroy_node()
    assert box.stops >= 1 and not box.streaming  # stop (0x0000) sent on shutdown


def test_silent_box_fails_configure_naming_it(ros_context: Any) -> None:
    from rclpy.lifecycle import TransitionCallbackReturn

    from slip_gripper_driver.netft_driver_node import NetFTDriverNode
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sink:  # bound, never answers
        sink.bind(('127.0.0.1', 0))
        port = sink.getsockname()[1]
        node = NetFTDriverNode(context=ros_context, parameter_overrides=overrides(port))
        try:
            assert node.trigger_configure() == TransitionCallbackReturn.FAILURE
            assert f'127.0.0.1:{port}' in node.last_error
            assert 'no RDT data' in node.last_error
        finally:
            node.destroy_node()
    for extra, message in (({'address': ''}, 'address is required'),
                           ({'counts_per_force': 0.0},
                            'counts_per_force and counts_per_torque are required')):
        node = NetFTDriverNode(context=ros_context, parameter_overrides=overrides(port, **extra))
        try:
            assert node.trigger_configure() == TransitionCallbackReturn.FAILURE
            assert message in node.last_error
        finally:
            node.destroy_node()


def test_error_records_and_a_reboot_in_device_bias_mode_never_reach_the_wrench_topic(
        ros_context: Any, box: NetFTEmulator) -> None:
    """Error-flagged records go to ft/raw only (publish_on_error); a reboot loses the device
    bias: diagnostics ERROR 'bias lost after device restart', ft/wrench silent until biased."""
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import WrenchStamped
    from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor
    from rclpy.lifecycle import TransitionCallbackReturn
    from rclpy.node import Node
    from rclpy.qos import QoSProfile
    from std_srvs.srv import Trigger

    from slip_cell_common.node_main import shutdown_lifecycle
    from slip_cell_common.time_conv import stamp_to_seconds
    from slip_gripper_driver.netft_driver_node import NetFTDriverNode
    from slip_cell_common.testing import SpinThread, call_service, spin_until

    node = NetFTDriverNode(context=ros_context, parameter_overrides=overrides(
        box.address[1], **{'bias.mode': 'device', 'publish_on_error': True,
                           'publish_decimation': 1}))
    executor = MultiThreadedExecutor(num_threads=2, context=ros_context)
    executor.add_node(node)
    spinner = SpinThread(executor).start()
    probe = Node('probe', context=ros_context)
    probe_exec = SingleThreadedExecutor(context=ros_context)
    probe_exec.add_node(probe)
    raw: list[WrenchStamped] = []
    biased: list[WrenchStamped] = []
    diags: list[DiagnosticArray] = []
    probe.create_subscription(WrenchStamped, 'finger_2/ft/raw', raw.append,
                              QoSProfile(depth=1000))
    probe.create_subscription(WrenchStamped, 'finger_2/ft/wrench', biased.append,
                              QoSProfile(depth=1000))
    probe.create_subscription(DiagnosticArray, '/diagnostics', diags.append, 10)
    client = probe.create_client(Trigger, 'finger_2/ft/bias')

    def ft_status() -> Any:
        return next((s for d in diags[-1:] for s in d.status if s.name == 'netft_driver: ft'),
                    None)

    def silent_while_raw_flows(since: float) -> None:
        """ft/wrench gets nothing stamped after ``since`` [s, node clock] while ft/raw gets
        another 200 messages (wrenches stamped before it may still be on their way)."""
        assert spin_until(probe_exec, lambda: len(raw) > 50, TIMEOUT_S)
        n_raw = len(raw)
        assert spin_until(probe_exec, lambda: len(raw) >= n_raw + 200, TIMEOUT_S)
        late = [stamp_to_seconds(w.header.stamp) for w in biased
                if stamp_to_seconds(w.header.stamp) > since]
        assert not late, (since, late[:5])

    try:
        assert node.trigger_configure() == TransitionCallbackReturn.SUCCESS, node.last_error
        assert node.trigger_activate() == TransitionCallbackReturn.SUCCESS
        reply = call_service(probe_exec, client, Trigger.Request(), TIMEOUT_S)
        assert reply is not None and reply.success, reply
        assert box.biases == 1
        assert spin_until(probe_exec, lambda: len(biased) > 100, TIMEOUT_S)

        box.set_status(0x80020000)
        assert spin_until(probe_exec, lambda: node.channel.health().status_errors > 50,
                          TIMEOUT_S)
        raw.clear()
        silent_while_raw_flows(node.now())  # publish_on_error: on ft/raw, never on ft/wrench
        assert spin_until(probe_exec, lambda: ft_status() is not None
                          and 'records dropped' in ft_status().message, 5.0)
        assert ft_status().level == b'\x02'
        box.set_status(0)
        n = len(biased)
        assert spin_until(probe_exec, lambda: len(biased) > n + 100, TIMEOUT_S)

        box.reboot()  # the device bias is gone; the readings jump by the tare (+2.5 N)
        assert spin_until(probe_exec, lambda: node.channel.bias_lost, TIMEOUT_S)
        raw.clear()
        silent_while_raw_flows(node.now())
        assert raw[-1].wrench.force.z == pytest.approx(OFFSET_FZ, abs=0.1)
        assert spin_until(probe_exec, lambda: ft_status() is not None
                          and 'bias lost after device restart' in ft_status().message, 5.0)
        values = {kv.key: kv.value for kv in ft_status().values}
        assert ft_status().level == b'\x02' and values['biased'] == 'false'
        assert values['device_restarts'] == '1'

        reply = call_service(probe_exec, client, Trigger.Request(), TIMEOUT_S)  # unloaded
        assert reply is not None and reply.success, reply
        n = len(biased)
        assert spin_until(probe_exec, lambda: len(biased) > n + 100, TIMEOUT_S)
        recent = biased[-50:]
        assert sum(w.wrench.force.z for w in recent) / 50 == pytest.approx(0.0, abs=0.05)
        assert not node.channel.bias_lost
    finally:
        spinner.stop()  # no wait set may hold entities that the shutdown destroys
        shutdown_lifecycle(node)
        executor.shutdown()
        probe_exec.shutdown()
        node.destroy_node()
        probe.destroy_node()


def test_bias_service_refuses_while_the_box_or_the_gripper_status_says_the_pads_are_loaded(
        ros_context: Any) -> None:
    """A direct call of finger_k/ft/bias (ft.mode topic) cannot bias under load: the box's
    own bias-removed force and the gripper driver's status both refuse it, with the reason."""
    from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor
    from rclpy.lifecycle import TransitionCallbackReturn
    from rclpy.node import Node
    from std_srvs.srv import Trigger

    from slip_msgs.msg import GripperStatus
    from slip_cell_common.node_main import shutdown_lifecycle
    from slip_cell_common.qos import SENSOR_PUB
    from slip_gripper_driver.netft_driver_node import NetFTDriverNode
    from slip_cell_common.testing import SpinThread, call_service, spin_until

    load = {'fz': 0.0}  # [N] on top of the offsets: what the pads squeeze
    emu = NetFTEmulator(host='127.0.0.1', port=0, rate_hz=1000.0,
                        offsets=(0.0, 0.0, OFFSET_FZ, 0.0, 0.0, 0.0), noise_std=0.01, seed=5,
                        force_source=lambda _t: (0.0, 0.0, load['fz'], 0.0, 0.0, 0.0))
    emu.start()
    node = NetFTDriverNode(context=ros_context, parameter_overrides=overrides(emu.address[1]))
    executor = MultiThreadedExecutor(num_threads=2, context=ros_context)
    executor.add_node(node)
    spinner = SpinThread(executor).start()
    probe = Node('probe', context=ros_context)
    probe_exec = SingleThreadedExecutor(context=ros_context)
    probe_exec.add_node(probe)
    client = probe.create_client(Trigger, 'finger_2/ft/bias')
    status_pub = probe.create_publisher(GripperStatus, 'gripper/status', SENSOR_PUB)

    def bias() -> Any:
        reply = call_service(probe_exec, client, Trigger.Request(), TIMEOUT_S)
        assert reply is not None
        return reply

    def gripper_says(**fields: Any) -> None:
        msg = GripperStatus(armed=True, **fields)
        seen = node.now()
        for _ in range(20):  # until the driver has it (discovery takes a moment)
            status_pub.publish(msg)
            if spin_until(probe_exec, lambda: node._gripper_load is not None and
                          node._gripper_load.received >= seen and
                          node._gripper_load.force_target == msg.force_target and
                          node._gripper_load.force_cmd == msg.force_cmd, 0.2):
                return
        raise AssertionError('the driver never received the gripper status')

    try:
        assert node.trigger_configure() == TransitionCallbackReturn.SUCCESS, node.last_error
        assert node.trigger_activate() == TransitionCallbackReturn.SUCCESS
        assert spin_until(probe_exec, lambda: node.channel is not None and
                          node.channel.sample_age(node.now()) < 0.05, TIMEOUT_S)
        first = bias()  # no gripper running, nothing on the pads: allowed, with the caveat
        assert first.success, first.message
        assert 'nothing was checked for load' in first.message  # no bias yet to read with
        biases_done = node.channel.accumulator.offsets

        load['fz'] = -6.0  # the pads squeeze: 6 N of normal force on the biased box
        assert spin_until(probe_exec, lambda: (node.channel.normal_force(node.now(), 0.1)
                                               or 0.0) < -5.5, TIMEOUT_S)
        refused = bias()
        assert not refused.success
        assert 'finger 2 F/T measures 6.0 N of normal force' in refused.message
        assert node.channel.accumulator.offsets == biases_done  # the old bias stays

        load['fz'] = 0.0  # unloaded box, but the gripper squeezes (e.g. another finger)
        assert spin_until(probe_exec, lambda: abs(
            node.channel.normal_force(node.now(), 0.1) or 9.0) < 0.2, TIMEOUT_S)
        gripper_says(force_target=10.0, force_cmd=10.0)
        refused = bias()
        assert not refused.success and 'squeezing target of 10.0 N' in refused.message
        gripper_says(measured_grasp_force=3.0, force_cmd=0.25)
        refused = bias()
        assert not refused.success and 'the gripper measures 3.0 N of grasp force' in \
            refused.message
        gripper_says(force_target=-8.0, force_cmd=-8.0)  # opened: allowed, no caveat
        allowed = bias()
        assert allowed.success, allowed.message
        assert 'no recent gripper status' not in allowed.message
    finally:
        spinner.stop()  # no wait set may hold entities that the shutdown destroys
        shutdown_lifecycle(node)
        executor.shutdown()
        probe_exec.shutdown()
        node.destroy_node()
        probe.destroy_node()
        emu.stop()
