"""The check that no test module leaves a process running on the run's ROS domain finds such a
ROS process by its environment, and not a process without ROS, the test process or its
ancestors."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest
from support.processes import ancestors, processes_on_domain

pytestmark = pytest.mark.skipif(not sys.platform.startswith('linux'), reason='reads /proc')


@pytest.mark.ros
def test_a_ros_process_on_the_domain_is_found_until_it_exits() -> None:
    pytest.importorskip('rclpy')
    domain = f'guard-{os.getpid()}'            # no real domain looks like this
    env = {**os.environ, 'ROS_DOMAIN_ID': domain}
    ros = subprocess.Popen([sys.executable, '-c', 'import rclpy, time; '
                            'print("ready", flush=True); time.sleep(60)'],
                           env=env, stdout=subprocess.PIPE, text=True)
    plain = subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(60)'], env=env)
    try:
        assert ros.stdout is not None and ros.stdout.readline().strip() == 'ready'
        found = processes_on_domain(domain)
        assert ros.pid in found and 'time.sleep(60)' in found[ros.pid], found
        assert plain.pid not in found, found        # no ROS loaded: cannot join the domain
        assert ros.pid not in processes_on_domain(os.environ.get('ROS_DOMAIN_ID', 'none'))
    finally:
        for child in (ros, plain):
            child.kill()
            child.wait()
        assert ros.stdout is not None
        ros.stdout.close()
    assert ros.pid not in processes_on_domain(domain)       # reaped: gone


def test_the_test_process_and_its_parent_are_ancestors() -> None:
    mine = ancestors()
    assert os.getpid() in mine and os.getppid() in mine
