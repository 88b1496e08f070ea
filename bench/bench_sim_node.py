# SPDX-License-Identifier: Apache-2.0
"""The simulated cell as a node, in real time (issue 4, "Performance"). Prints; never asserts.

Starts the simulated-cell graph as ``make demo`` does (``run_graph --sim``: sim_gripper,
contact_estimator, slip_controller, experiment_runner, all on ``use_sim_time``), so the
simulator shares the 2 cores with every node that consumes its streams. With ``--alone``
only sim_gripper runs. After a warm-up it measures for ``--duration`` wall seconds:

* the simulator's own tick counters from its ``realtime_factor`` diagnostics task
  (ticks, late ticks = ticks that started more than one tick period late, dropped sim time);
* simulated vs wall time advanced (real-time factor) from ``/clock``;
* received rates of ``gripper/status`` (telemetry, 500 Hz), ``finger_1/ft/wrench`` (the 1 kHz
  box, published every 2nd record) and ``finger_1/slip/twist`` (≈ 120 Hz), per simulated
  second from their stamps, and the largest stamp gap;
* CPU of every graph process.

Target (issue 4): 500 Hz telemetry and ~1 kHz F/T in real time with < 1 % late ticks over
60 s. Usage: ``tools/run_ros.sh .venv/bin/python bench/bench_sim_node.py [--quick] [--alone]``.
"""
from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
WARMUP_S = 6.0
SIM_TASK = 'sim_gripper: realtime_factor'


def _stamp(msg) -> float:
    from slip_cell_common.time_conv import stamp_to_seconds
    return stamp_to_seconds(msg.header.stamp)


def _proc_cpu_ticks(pid: int) -> int:
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return int(fields[11]) + int(fields[12])  # utime + stime


def _graph_pids(root_pid: int) -> dict[int, str]:
    """Child processes of the graph runner: pid → executable name."""
    out: dict[int, str] = {}
    for entry in Path('/proc').iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / 'stat').read_text()
            ppid = int(stat.rsplit(')', 1)[1].split()[1])
            cmd = (entry / 'cmdline').read_bytes().split(b'\0')
        except OSError:
            continue
        if ppid == root_pid and len(cmd) > 1:
            out[int(entry.name)] = Path(cmd[1].decode()).name
    return out


def _alone_graph() -> Path:
    """A graph file with only the simulator of the sim cell (same YAML files)."""
    import tempfile

    import yaml
    graph = yaml.safe_load((ROOT / 'src/slip_control/config/sim_cell.graph.yaml').read_text())
    graph['nodes'] = [n for n in graph['nodes'] if n['name'] == 'sim_gripper']
    path = Path(tempfile.mkdtemp(prefix='bench_sim_')) / 'sim_alone.graph.yaml'
    path.write_text(yaml.safe_dump(graph))
    return path


def main() -> int:
    """Run the graph, measure, print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--duration', type=float, default=60.0, help='measured wall seconds')
    parser.add_argument('--quick', action='store_true', help='10 s (make bench)')
    parser.add_argument('--alone', action='store_true', help='only sim_gripper, no other node')
    args = parser.parse_args()
    duration = 10.0 if args.quick else args.duration
    if 'ROS_DOMAIN_ID' not in os.environ:
        print('run through tools/run_ros.sh (private ROS_DOMAIN_ID, loopback only)',
              file=sys.stderr)
        return 2

    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import TwistStamped, WrenchStamped
    from rclpy.executors import SingleThreadedExecutor
    from rosgraph_msgs.msg import Clock
    from slip_msgs.msg import GripperStatus

    from slip_cell_common.core import names
    from slip_cell_common.qos import SENSOR_SUB
    from slip_cell_common.testing import SpinThread
    from slip_cell_common.time_conv import stamp_to_seconds

    cmd = [sys.executable, '-m', 'slip_bringup.run_graph', '--sim']
    if args.alone:
        cmd = [sys.executable, '-m', 'slip_bringup.run_graph', '--config',
               str(_alone_graph())]
    graph = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                             start_new_session=True)
    rclpy.init()
    node = rclpy.create_node('bench_sim_node')
    lock = threading.Lock()
    recording = threading.Event()
    stamps: dict[str, list[float]] = {'status': [], 'wrench': [], 'twist': []}
    clock: list[tuple[float, float]] = []
    diag: dict[str, dict[str, str]] = {}

    def keep(name: str):
        def cb(msg) -> None:
            if recording.is_set():
                with lock:
                    stamps[name].append(_stamp(msg))
        return cb

    def on_clock(msg: Clock) -> None:
        if recording.is_set():
            with lock:
                clock.append((time.monotonic(), stamp_to_seconds(msg.clock)))

    def on_diag(msg: DiagnosticArray) -> None:
        for status in msg.status:
            if status.name == SIM_TASK:
                with lock:
                    diag['last'] = {kv.key: kv.value for kv in status.values}

    node.create_subscription(GripperStatus, names.GRIPPER_STATUS, keep('status'), SENSOR_SUB)
    node.create_subscription(WrenchStamped, names.ft_wrench(1), keep('wrench'), SENSOR_SUB)
    node.create_subscription(TwistStamped, names.slip_twist(1), keep('twist'), SENSOR_SUB)
    node.create_subscription(Clock, names.CLOCK, on_clock, SENSOR_SUB)
    node.create_subscription(DiagnosticArray, names.DIAGNOSTICS, on_diag, 10)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    spinner = SpinThread(executor).start()
    try:
        deadline = time.monotonic() + 30.0
        while 'last' not in diag and time.monotonic() < deadline:
            time.sleep(0.1)
        if 'last' not in diag:
            print('the simulator published no diagnostics within 30 s', file=sys.stderr)
            return 1
        # The drivers publish finger_k/ft/wrench only once biased: bias as a user would.
        from std_srvs.srv import Trigger
        client = node.create_client(Trigger, names.GRIPPER_BIAS_FT_SRV)
        if not client.wait_for_service(timeout_sec=10.0):
            print(f'{names.GRIPPER_BIAS_FT_SRV} not available', file=sys.stderr)
            return 1
        reply = client.call(Trigger.Request(), timeout_sec=10.0)
        if reply is None or not reply.success:
            print(f'bias failed: {reply}', file=sys.stderr)
            return 1
        time.sleep(WARMUP_S)
        with lock:
            first = dict(diag['last'])
        pids = _graph_pids(graph.pid)
        cpu0 = {pid: _proc_cpu_ticks(pid) for pid in pids}
        wall0 = time.monotonic()
        recording.set()
        time.sleep(duration)
        recording.clear()
        wall = time.monotonic() - wall0
        cpu1 = {pid: _proc_cpu_ticks(pid) for pid in pids if Path(f'/proc/{pid}').exists()}
        time.sleep(1.2)  # one more diagnostics period
        with lock:
            last = dict(diag['last'])
    finally:
        spinner.stop()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
        os.killpg(graph.pid, signal.SIGINT)
        try:
            graph.wait(20.0)
        except subprocess.TimeoutExpired:
            os.killpg(graph.pid, signal.SIGKILL)

    hz = os.sysconf('SC_CLK_TCK')
    ticks = int(last['ticks']) - int(first['ticks'])
    late = int(last['late_ticks']) - int(first['late_ticks'])
    dropped = float(last['behind_real_time_s']) - float(first['behind_real_time_s'])
    c = np.array(clock)
    sim_span = float(c[-1, 1] - c[0, 1]) if len(c) > 1 else float('nan')
    wall_span = float(c[-1, 0] - c[0, 0]) if len(c) > 1 else float('nan')
    print(f'simulated cell as a node: {"sim_gripper alone" if args.alone else "full sim graph"}, '
          f'{wall:.0f} s measured after {WARMUP_S:.0f} s warm-up')
    print(f'  simulator ticks             {ticks:8d}   late {late} '
          f'({100.0 * late / max(ticks, 1):.2f} %; target < 1 %), sim time behind '
          f'{dropped:.3f} s')
    print(f'  real-time factor (/clock)   {sim_span / wall_span:8.3f}   '
          f'({sim_span:.2f} sim s in {wall_span:.2f} wall s)')
    for name, nominal in (('status', 500.0), ('wrench', 500.0), ('twist', 120.0)):
        s = np.sort(np.array(stamps[name]))
        if len(s) < 2:
            print(f'  {name:<27} no messages')
            continue
        rate = (len(s) - 1) / (s[-1] - s[0])
        print(f'  {name:<27} {rate:8.1f} Hz per sim s (nominal {nominal:.0f}); '
              f'{len(s) / wall:.1f} Hz per wall s; largest stamp gap '
              f'{1e3 * np.diff(s).max():.1f} ms')
    print('  CPU (% of one core)         ' + ', '.join(
        f'{name} {100.0 * (cpu1[pid] - cpu0[pid]) / hz / wall:.0f}'
        for pid, name in sorted(pids.items(), key=lambda kv: kv[1]) if pid in cpu1))
    return 0


if __name__ == '__main__':
    sys.exit(main())
