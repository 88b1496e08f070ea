"""``slip_cli``'s ros2-like commands against a real node (in-process, private domain).

The probe node spins on its own thread in its own context; each ``slip_cli`` call runs its
``main(argv)`` in-process with its own node, as a user's shell would.
"""
from __future__ import annotations

from typing import Any
from collections.abc import Iterator

import pytest
import yaml

pytestmark = pytest.mark.ros


class Probe:
    """Parameters with ranges, a 50 Hz stamped topic, a latched topic and two services."""

    def __init__(self, ctx: Any) -> None:
        from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        from slip_cell_common.qos import LATCHED, SENSOR_PUB
        from slip_cell_common.testing import SpinThread
        from slip_msgs.msg import GripperStatus
        from slip_msgs.srv import ApplyDisturbance, StartEstimation
        from std_msgs.msg import String
        self.node = Node('slip_cli_probe', context=ctx)
        self.node.declare_parameter('gain', 2.0, ParameterDescriptor(
            description='proportional gain [-]',
            floating_point_range=[FloatingPointRange(from_value=0.0, to_value=20.0)]))
        self.node.declare_parameter('samples', 10, ParameterDescriptor(
            description='window [samples]',
            integer_range=[IntegerRange(from_value=1, to_value=100, step=1)]))
        self.node.declare_parameter('port', '/dev/null', ParameterDescriptor(read_only=True))
        self.requests: list[Any] = []
        self.node.create_service(StartEstimation, 'probe/start', self._start)
        self.node.create_service(ApplyDisturbance, 'probe/disturb', self._disturb)
        latched = self.node.create_publisher(String, 'probe/latched', LATCHED)
        latched.publish(String(data='hello'))
        self._status = self.node.create_publisher(GripperStatus, 'probe/status', SENSOR_PUB)
        self._k = 0
        self.node.create_timer(0.02, self._tick)
        self.executor = SingleThreadedExecutor(context=ctx)
        self.executor.add_node(self.node)
        self.spin = SpinThread(self.executor).start()

    def _tick(self) -> None:
        from slip_msgs.msg import GripperStatus
        msg = GripperStatus(line_count=self._k)
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(self._k * 20_000_000,
                                                                1_000_000_000)
        self._status.publish(msg)
        self._k += 1

    def _start(self, req: Any, res: Any) -> Any:
        self.requests.append(req)
        res.accepted, res.message = True, f'phase {req.phase} for {req.duration} s'
        return res

    def _disturb(self, req: Any, res: Any) -> Any:
        self.requests.append(req)
        res.success = req.torque >= 0.0
        res.message = 'ok' if res.success else 'negative torque refused'
        return res

    def close(self) -> None:
        self.spin.stop()
        self.executor.shutdown()
        self.node.destroy_node()


@pytest.fixture
def probe(ros_context: Any) -> Iterator[Probe]:
    p = Probe(ros_context)
    yield p
    p.close()


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    from slip_bringup.slip_cli import main
    capsys.readouterr()
    code = main(['--timeout', '15', *argv])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_topic_and_node_list(probe: Probe, ros_env: dict[str, str],
                             capsys: pytest.CaptureFixture[str]) -> None:
    import subprocess
    import sys
    code, out, err = run(capsys, 'topic', 'list')
    assert code == 0, err
    rows = dict(line.split(None, 1) for line in out.splitlines())
    assert rows['/probe/status'] == '[slip_msgs/msg/GripperStatus]'
    assert rows['/probe/latched'] == '[std_msgs/msg/String]'
    # Node names come from the discovery-info topic; in our runs a second rclpy context made
    # in the same process after the first one closed did not see the probe node within the
    # discovery wait. Run it as a user does: one process per command.
    proc = subprocess.run([sys.executable, '-m', 'slip_bringup.slip_cli', 'node', 'list'],
                          env=ros_env, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert '/slip_cli_probe' in proc.stdout.split()
    assert not any(n.rsplit('/', 1)[-1].startswith('_') for n in proc.stdout.split())


def test_param_list_describe_get_set(probe: Probe, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, 'param', 'list', 'slip_cli_probe')
    assert code == 0, err
    assert {'gain', 'samples', 'port', 'use_sim_time'} <= set(out.split())
    code, out, err = run(capsys, 'param', 'describe', 'slip_cli_probe', 'gain')
    assert code == 0, err
    assert 'Type: double' in out and 'Description: proportional gain [-]' in out
    assert 'Min value: 0.0' in out and 'Max value: 20.0' in out
    code, out, _ = run(capsys, 'param', 'describe', 'slip_cli_probe', 'samples')
    assert 'Type: integer' in out and 'Min value: 1' in out and 'Max value: 100' in out
    code, out, _ = run(capsys, 'param', 'describe', 'slip_cli_probe', 'port')
    assert 'Read only: true' in out
    assert run(capsys, 'param', 'set', 'slip_cli_probe', 'gain', '3.5')[0] == 0
    code, out, _ = run(capsys, 'param', 'get', 'slip_cli_probe', 'gain')
    assert code == 0 and out.strip() == 'gain = 3.5'
    code, _, err = run(capsys, 'param', 'describe', 'slip_cli_probe', 'nope')
    assert code == 1 and 'no parameter' in err


def test_call_any_service_with_yaml(probe: Probe, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, 'call', 'probe/start', 'slip_msgs/srv/StartEstimation',
                         '{phase: 1, duration: 2}')
    assert code == 0, err
    req = probe.requests[-1]
    assert req.phase == 1 and req.duration == 2.0
    response = yaml.safe_load(out.split('response:\n', 1)[1])
    assert response == {'accepted': True, 'message': 'phase 1 for 2.0 s'}
    # type looked up in the graph; nested message fields
    code, out, err = run(capsys, 'call', '/probe/disturb',
                         '{force: {x: 1.5, y: -2}, torque: 0.02, duration: 0.3}')
    assert code == 0, err
    req = probe.requests[-1]
    assert (req.force.x, req.force.y, req.torque) == (1.5, -2.0, 0.02)
    # a refusal (success: false) fails the command
    code, _, err = run(capsys, 'call', 'probe/disturb', 'slip_msgs/srv/ApplyDisturbance',
                       '{torque: -1.0, duration: 0.3}')
    assert code == 1 and 'negative torque refused' in err
    code, _, err = run(capsys, 'call', 'probe/start', 'slip_msgs/srv/StartEstimation',
                       '{phase: 1, speed: 3}')
    assert code == 1 and "no field 'speed'" in err and 'phase, duration' in err


def test_echo_prints_yaml_also_for_latched_topics(probe: Probe,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, 'echo', 'probe/latched')
    assert code == 0, err
    assert [d for d in yaml.safe_load_all(out) if d] == [{'data': 'hello'}]
    code, out, err = run(capsys, 'echo', '/probe/status', '--count', '3')
    assert code == 0, err
    docs = [d for d in yaml.safe_load_all(out) if d]
    assert len(docs) == 3
    counts = [d['line_count'] for d in docs]
    assert counts == sorted(counts) and set(docs[0]['header']['stamp']) == {'sec', 'nanosec'}


def test_topic_hz(probe: Probe, capsys: pytest.CaptureFixture[str]) -> None:
    # From the header stamps (exactly 20 ms apart): exactly 50 Hz whatever the host load.
    code, out, err = run(capsys, 'topic', 'hz', 'probe/status', '--header', '--count', '30',
                         '--duration', '20')
    assert code == 0, err
    assert 'average rate: 50.000' in out and 'window: 30' in out
    # From receive times: a rate of the right order (the publisher is a 50 Hz wall timer).
    code, out, err = run(capsys, 'topic', 'hz', 'probe/status', '--count', '40',
                         '--duration', '20')
    assert code == 0, err
    rate = float(out.split('average rate: ')[1].split()[0])
    assert 10.0 < rate < 250.0
    code, _, err = run(capsys, '--timeout', '1', 'topic', 'hz', 'probe/none')
    assert code == 1 and 'no publisher of /probe/none' in err
