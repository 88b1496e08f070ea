"""Root pytest configuration: ROS fixtures for tests marked ``ros``.

`make test` runs pytest inside tools/run_ros.sh, which sets a private ROS_DOMAIN_ID and
ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST; tests refuse to start ROS without them, so no test
can ever multicast on a non-loopback interface.
"""
from __future__ import annotations

import os
from collections.abc import Iterator

import pytest


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
