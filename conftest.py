"""Root pytest configuration: ROS fixtures for tests marked ``ros``.

`make test` runs pytest inside tools/run_ros.sh, which sets a private ROS_DOMAIN_ID and
ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST; tests refuse to start ROS without them, so no test
can ever multicast on a non-loopback interface. All tests of one run share that domain, so a
process one test module leaves running would talk to the next module's graph:
`_no_process_outlives_its_module` fails the module that leaves one (and stops it).
"""
from __future__ import annotations

import os
import signal
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from support.processes import ancestors, processes_on_domain

#: How long a module's processes may take to exit after its last test [s].
EXIT_GRACE_S = 5.0


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Count tests per marker in the header so CI logs show what ran."""
    del config
    ros = sum(1 for i in items if i.get_closest_marker('ros'))
    print(f'\ncollected {len(items)} tests ({ros} with real ROS 2 / DDS)')


def _require_isolated_ros_env() -> None:
    if os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE') != 'LOCALHOST' or \
            not os.environ.get('ROS_DOMAIN_ID'):
        pytest.fail('ROS tests must run with ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST and a private '
                    'ROS_DOMAIN_ID: use `make test` or tools/run_ros.sh')


@pytest.fixture
def ros_context() -> Iterator[object]:
    """A private rclpy Context, shut down after the test."""
    _require_isolated_ros_env()
    rclpy = pytest.importorskip('rclpy')
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions
    context = Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    yield context
    rclpy.try_shutdown(context=context)


@pytest.fixture
def ros_env() -> dict[str, str]:
    """Environment for child ROS processes: the same private domain, loopback only."""
    _require_isolated_ros_env()
    env = os.environ.copy()
    env['PYTHONUNBUFFERED'] = '1'
    return env


@pytest.fixture(scope='module', autouse=True)
def _no_process_outlives_its_module() -> Iterator[None]:
    """Fail a test module that leaves a process running on the run's ROS domain (Linux only;
    the check is skipped where ``/proc`` has no environments)."""
    domain = os.environ.get('ROS_DOMAIN_ID', '')
    if not domain or not Path(f'/proc/{os.getpid()}/environ').exists():
        yield
        return
    before = set(processes_on_domain(domain)) | ancestors()
    yield
    deadline = time.monotonic() + EXIT_GRACE_S
    while True:
        left = {p: c for p, c in processes_on_domain(domain).items() if p not in before}
        if not left or time.monotonic() > deadline:
            break
        time.sleep(0.1)
    for pid in left:
        try:
            os.kill(pid, signal.SIGKILL)
        except OSError:
            pass
    if left:
        pytest.fail(f'{len(left)} process(es) still running on ROS_DOMAIN_ID={domain} '
                    f'{EXIT_GRACE_S:.0f} s after the module ended (killed): '
                    + '; '.join(f'{p}: {c[:160]}' for p, c in sorted(left.items())),
                    pytrace=False)
