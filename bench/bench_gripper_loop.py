# SPDX-License-Identifier: Apache-2.0
"""Benchmark of the 500 Hz gripper loop (issue 5: line in → voltage written, p99 ≤ 1 ms,
zero missed ticks over 60 s).

The firmware emulator runs in a child process on a pseudo-terminal (its console entry point,
``python -m slip_gripper_driver.core.firmware_emulator``) with an object between the fingers
and, by default, two Net F/T emulators measuring the pad force. This process runs what the
``gripper_driver`` node runs in its reader threads: `transport.SerialLink` (pyserial
``serial_for_url`` on the pty) → `bridge.GripperBridge` (parse, observer, grasp-force
controller in closed loop at 10 N) → ``T<volts>`` written, plus two `netft_client.NetFTClient`
threads at 1 kHz each feeding the bridge.

Latency per telemetry line = ``time.monotonic()`` right after the command write returned −
the line's arrival stamp (taken by the reader when the read returned). A tick is *missed*
when its command was not written before the next line's period (latency > 2 ms) or no
command was written for it. Prints a table; never asserts.

``--node`` runs the same measurement through the real ``gripper_driver`` lifecycle node in this
process (rclpy, publishing from the reader thread, watchdog, embedded Net F/T clients on
127.0.0.6/127.0.0.5 served by the emulator child process).

``--hold`` (issue 16 item 2) holds grasps through the real node under host load: for each
target (``--targets``, default 10 N and 40 N) and each real-time setting (``--rt``, default
on = ``realtime.priority`` 10 and off = 0), two CPU-burning processes (``--burners``) run
beside the driver for ``--duration`` seconds while the node holds the object closed-loop on
the emulator's Net F/T. Printed per case: 0 V dropouts (safe voltage written while the grasp
was commanded), disarms, link stale/fault events, host stalls (telemetry processed late while
the firmware kept sending), catch-up lines, resume ramps, and the force error (F/T grasp force
− target) max and RMS over the hold. The emulator (standing for the firmware) runs
``SCHED_FIFO`` ``--emulator-priority`` in every case.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

_ROOT = Path(__file__).resolve().parents[1]
_SRC = str(_ROOT / 'src' / 'slip_gripper_driver')
if _SRC not in sys.path:
    sys.path.insert(0, _SRC)

from slip_gripper_driver.core.bridge import GripperBridge  # noqa: E402
from slip_gripper_driver.core.bridge_params import BridgeParams  # noqa: E402
from slip_gripper_driver.core.ft_scale import ForceTorqueScale  # noqa: E402
from slip_gripper_driver.core.netft_client import FtSample, NetFTClient  # noqa: E402
from slip_gripper_driver.core.protocol import LineKind  # noqa: E402
from slip_gripper_driver.core.realtime import (RealtimeParams, ThreadTuning,  # noqa: E402
                                               freeze_gc)
from slip_cell_common.core.serial_transport import SerialLink  # noqa: E402

PERIOD_S = 0.002
WARMUP_S = 1.0


def _start_emulator(link: str, seconds: float, with_ft: bool, boxes_at: list[str] | None = None,
                    priority: int = 0, truth_path: str = ''
                    ) -> tuple[subprocess.Popen, list[tuple[str, int]]]:
    cmd = [sys.executable, '-m', 'slip_gripper_driver.core.firmware_emulator', '--link', link,
           '--object-width', '0.03', '--initial-opening', '0.031', '--duration', f'{seconds}',
           '--stats-json', '--priority', str(priority)]
    if truth_path:
        cmd += ['--record-truth', truth_path]
    if with_ft:
        cmd += ['--netft', '127.0.0.1:0', '--netft', '127.0.0.1:0']
    for box in boxes_at or []:
        cmd += ['--netft', box]
    env = dict(os.environ)
    env['PYTHONPATH'] = _SRC + os.pathsep + env.get('PYTHONPATH', '')
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True, env=env)
    boxes: list[tuple[str, int]] = []
    deadline = time.monotonic() + 20.0
    assert proc.stdout is not None
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line:
            break
        if line.startswith('Net F/T emulator'):
            host, port = line.rsplit(' ', 1)[1].strip().rsplit(':', 1)
            boxes.append((host, int(port)))
        if line.startswith('gripper firmware emulator on'):
            return proc, boxes
    proc.kill()
    raise RuntimeError('firmware emulator did not start')


def run(duration_s: float, with_ft: bool, rt: RealtimeParams, emulator_priority: int) -> None:
    """Run the benchmark for ``duration_s`` seconds of measurement and print the table.

    ``rt`` is applied as the node applies its ``realtime.*`` parameters: scheduling of the
    reader threads (`ThreadTuning`) and `freeze_gc` once everything is set up.
    """
    tmp = tempfile.mkdtemp(prefix='bench_gripper_')
    port = os.path.join(tmp, 'gripper')
    proc, boxes = _start_emulator(port, duration_s + WARMUP_S + 3.0, with_ft,
                                  priority=emulator_priority)
    tuning = ThreadTuning.from_params(rt)

    n_max = int((duration_s + WARMUP_S + 2.0) / PERIOD_S) + 1000
    arrival = np.full(n_max, np.nan)
    written = np.full(n_max, np.nan)
    count = [0]
    write_done = [np.nan]
    lock = threading.Lock()
    link_holder: list[SerialLink] = []

    def writer(data: bytes) -> bool:
        ok = link_holder[0].write(data)
        write_done[0] = time.monotonic()
        return ok

    bridge = GripperBridge(BridgeParams(), writer)

    def on_line(line: bytes, overflow: bool, t: float) -> None:
        result = bridge.on_line(line, overflow, t)
        if result.kind != LineKind.TELEMETRY:
            return
        with lock:
            i = count[0]
            if i < n_max:
                arrival[i] = t
                if result.command is not None and result.written:
                    written[i] = write_done[0]
            count[0] = i + 1

    link = SerialLink(port, clock=time.monotonic, on_line=on_line,
                      on_connected=bridge.on_connected, on_lost=bridge.on_link_lost,
                      read_timeout_s=0.02, thread_setup=tuning.apply)
    link_holder.append(link)
    clients: list[NetFTClient] = []
    scale = ForceTorqueScale(1e6, 1e6, 'N', 'N-m')
    for finger, (host, box_port) in enumerate(boxes, start=1):
        def on_sample(sample: FtSample, finger: int = finger) -> None:
            bridge.on_ft_sample(finger, sample.stamp, sample.wrench[2], True)
        clients.append(NetFTClient(host, port=box_port, scale=scale, clock=time.monotonic,
                                   on_sample=on_sample, thread_setup=tuning.apply))
    link.open()
    for client in clients:
        client.start()
    if rt.freeze_gc:
        freeze_gc()
    bridge.activate(time.monotonic())
    link.start()
    bridge.set_grasp_force(10.0, time.monotonic())
    time.sleep(WARMUP_S)
    with lock:
        first = count[0]
    cpu0, wall0 = time.process_time(), time.monotonic()
    time.sleep(duration_s)
    with lock:
        last = count[0]
    cpu1, wall1 = time.process_time(), time.monotonic()
    status = bridge.status(time.monotonic())
    bridge.deactivate(time.monotonic())
    link.close()
    ft_stats = [c.stats() for c in clients]
    for client in clients:
        client.close()
    out, _ = proc.communicate(timeout=30.0)
    emu = json.loads(out.strip().splitlines()[-1]) if out.strip() else {}

    a = arrival[first:last]
    w = written[first:last]
    latency_us = (w - a) * 1e6
    unanswered = int(np.isnan(latency_us).sum())
    lat = latency_us[~np.isnan(latency_us)]
    gaps = np.diff(a) * 1e3
    late = int((lat > PERIOD_S * 1e6).sum())
    expected = int(round((wall1 - wall0) / PERIOD_S))
    print(f'gripper loop: pty emulator at 500 Hz, {duration_s:.0f} s measured '
          f'({"closed loop at 10 N with 2 Net F/T clients at 1 kHz" if with_ft else "no F/T"})')
    print(f'  realtime                   {_tuning_text(tuning, rt, emulator_priority)}')
    print(f'  telemetry lines            {a.size:10d}   (≈ {expected} expected)')
    print(f'  latency line → T written   p50 {np.percentile(lat, 50):7.1f} µs   '
          f'p99 {np.percentile(lat, 99):7.1f} µs   max {lat.max():7.1f} µs')
    print(f'  missed ticks               {late + unanswered:10d}   '
          f'(latency > 2 ms: {late}, no command: {unanswered})')
    print(f'  arrival gaps > 3 ms        {int((gaps > 3.0).sum()):10d}   '
          f'(max gap {gaps.max():.2f} ms; emulator late ticks {emu.get("late_ticks", "?")})')
    print(f'  host CPU                   {100 * (cpu1 - cpu0) / (wall1 - wall0):9.1f} %  '
          f'of one core')
    print(f'  grasp force                {status.measured_grasp_force:10.2f} N   '
          f'(target 10 N, closed loop: {not status.safe_state and status.in_contact})')
    for k, s in enumerate(ft_stats, start=1):
        print(f'  F/T {k}                      {s.accepted:10d} records, lost {s.lost}, '
              f'out of order {s.out_of_order}, bad {s.bad_datagrams}')
    print(f'  bad lines {status.bad_line_count}, reconnects {status.reconnect_count}, '
          f'link callback errors {link.stats().callback_errors}')


def _tuning_text(tuning: ThreadTuning, rt: RealtimeParams, emulator_priority: int) -> str:
    threads = sorted(set(tuning.results.values())) or ['normal']
    return (f'reader threads: {", ".join(threads)}; GC frozen: {rt.freeze_gc}; '
            f'emulator SCHED_FIFO {emulator_priority or "off"}')


def _free_port(host: str) -> int:
    import socket
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind((host, 0))
        return probe.getsockname()[1]


def run_node(duration_s: float, with_ft: bool, rt: RealtimeParams,
             emulator_priority: int) -> None:
    """Same measurement through the real ``gripper_driver`` lifecycle node (in this process).

    The node runs as ``main`` runs it (multi-threaded executor, parameters, publishers): every
    line is also published as ``gripper/status`` and ``gripper/motor_command`` from the reader
    thread, the watchdog runs every 5 ms, the boxes publish ``finger_k/ft/wrench``. Latency =
    node clock in the result callback (called right after the command was written) − the line's
    arrival stamp.
    """
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import MultiThreadedExecutor
    from rclpy.lifecycle import TransitionCallbackReturn
    from rclpy.parameter import Parameter
    from rclpy.signals import SignalHandlerOptions
    from std_srvs.srv import Trigger

    from slip_gripper_driver.gripper_driver_node import GripperDriverNode
    from slip_cell_common.testing import SpinThread

    tmp = tempfile.mkdtemp(prefix='bench_gripper_node_')
    port = os.path.join(tmp, 'gripper')
    box_port = _free_port('127.0.0.6')
    hosts = ('127.0.0.6', '127.0.0.5')
    cmd_boxes = [f'{h}:{box_port}' for h in hosts] if with_ft else []
    proc, _ = _start_emulator(port, duration_s + WARMUP_S + 6.0, False, cmd_boxes,
                              priority=emulator_priority)
    context = Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    overrides = {'autostart': False, 'serial.port': port,
                 'ft.mode': 'embedded' if with_ft else 'topic',
                 'ft.finger_1.address': hosts[0], 'ft.finger_2.address': hosts[1],
                 'ft.port': box_port, 'ft.read_config': False, 'ft.counts_per_force': 1.0e6,
                 'ft.counts_per_torque': 1.0e6, 'realtime.priority': rt.priority,
                 'realtime.freeze_gc': rt.freeze_gc}
    node = GripperDriverNode(context=context, parameter_overrides=[
        Parameter(k, value=v) for k, v in overrides.items()])
    n_max = int((duration_s + WARMUP_S + 4.0) / PERIOD_S) + 1000
    arrival = np.full(n_max, np.nan)
    done = np.full(n_max, np.nan)
    count = [0]
    publish_us: list[float] = []
    original = node._on_result

    def on_result(result: object) -> None:
        t_done = node.now()
        if result.kind == LineKind.TELEMETRY:  # type: ignore[attr-defined]
            i = count[0]
            if i < n_max:
                arrival[i] = result.stamp  # type: ignore[attr-defined]
                if result.written:  # type: ignore[attr-defined]
                    done[i] = t_done
            count[0] = i + 1
        t0 = time.perf_counter()
        original(result)
        publish_us.append((time.perf_counter() - t0) * 1e6)

    node._on_result = on_result
    executor = MultiThreadedExecutor(context=context)
    executor.add_node(node)
    # As ``main`` does: the spinning thread (and the executor workers it starts) get the
    # node's realtime.* scheduling, so no GIL holder of the driver is preempted by others.
    spin_tuning: list[str] = []
    spinner = SpinThread(executor, on_start=lambda: spin_tuning.append(node.tune_spin_thread()))
    spinner.start()
    try:
        ok = TransitionCallbackReturn.SUCCESS
        if node.trigger_configure() != ok or node.trigger_activate() != ok:
            raise RuntimeError(f'gripper_driver did not start: {node.last_error}')
        time.sleep(0.5)
        if with_ft:
            reply = node._srv_bias(Trigger.Request(), Trigger.Response())
            print(f'bias: {reply.message}')
        node.core.bridge.set_grasp_force(10.0, node.now())
        time.sleep(WARMUP_S)
        first = count[0]
        cpu0, wall0 = time.process_time(), time.monotonic()
        time.sleep(duration_s)
        last = count[0]
        cpu1, wall1 = time.process_time(), time.monotonic()
        status = node.core.bridge.status(node.now())
        diag = node.core.bridge.diagnostics(node.now())
        tuning = node._tuning
    finally:
        from slip_cell_common.node_main import shutdown_lifecycle
        shutdown_lifecycle(node)
        spinner.stop()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    out, _ = proc.communicate(timeout=30.0)
    emu = json.loads(out.strip().splitlines()[-1]) if out.strip() else {}
    a, w = arrival[first:last], done[first:last]
    lat = (w - a) * 1e6
    unanswered = int(np.isnan(lat).sum())
    lat = lat[~np.isnan(lat)]
    late = int((lat > PERIOD_S * 1e6).sum())
    gaps = np.diff(a) * 1e3
    pub = np.array(publish_us[-(last - first):]) if publish_us else np.zeros(1)
    print(f'gripper loop THROUGH THE NODE: {duration_s:.0f} s measured '
          f'({"closed loop at 10 N, 2 embedded Net F/T clients" if with_ft else "no F/T"})')
    print(f'  realtime                   {_tuning_text(tuning, rt, emulator_priority)}; '
          f'executor threads: {", ".join(spin_tuning) or "?"}')
    print(f'  telemetry lines            {a.size:10d}   '
          f'(≈ {int(round((wall1 - wall0) / PERIOD_S))} expected)')
    print(f'  latency line → T written   p50 {np.percentile(lat, 50):7.1f} µs   '
          f'p99 {np.percentile(lat, 99):7.1f} µs   max {lat.max():7.1f} µs')
    print(f'  missed ticks               {late + unanswered:10d}   '
          f'(latency > 2 ms: {late}, no command: {unanswered})')
    slow = np.flatnonzero((w - a) * 1e6 > PERIOD_S * 1e6)
    if slow.size:
        print('  late lines at [s] (latency ms)  ' + ', '.join(
            f'{a[i] - a[0]:.3f} ({(w[i] - a[i]) * 1e3:.1f})' for i in slow[:12]))
    print(f'  arrival gaps > 3 ms        {int((gaps > 3.0).sum()):10d}   '
          f'(max gap {gaps.max():.2f} ms; emulator late ticks {emu.get("late_ticks", "?")})')
    print(f'  status+motor publish       p50 {np.percentile(pub, 50):7.1f} µs   '
          f'p99 {np.percentile(pub, 99):7.1f} µs (after the write, same thread)')
    print(f'  host CPU                   {100 * (cpu1 - cpu0) / (wall1 - wall0):9.1f} %  '
          f'of one core')
    print(f'  grasp force                {status.measured_grasp_force:10.2f} N   '
          f'(target 10 N, closed loop: {diag.closed_loop})')
    print(f'  stale events {diag.stale_events}, reconnects {diag.reconnects}, '
          f'armed at the end: {diag.armed}')


def _steal_s() -> float:
    """CPU time the hypervisor took from this virtual machine since boot [s] (0 elsewhere)."""
    try:
        with open('/proc/stat') as stat:
            fields = stat.readline().split()
        return int(fields[8]) / os.sysconf('SC_CLK_TCK')
    except (OSError, IndexError, ValueError):
        return 0.0


def _io_stall_counters() -> tuple[float, int]:
    """``(s, n)``: time some task stalled on I/O since boot (``/proc/pressure/io``, NaN where
    there is no pressure information) and major page faults since boot (-1 where unknown)."""
    stall, faults = math.nan, -1
    try:
        with open('/proc/pressure/io') as pressure:
            some = pressure.readline().split()
        stall = int(some[-1].split('=')[1]) * 1e-6
    except (OSError, IndexError, ValueError):
        pass
    try:
        with open('/proc/vmstat') as vmstat:
            for line in vmstat:
                if line.startswith('pgmajfault '):
                    faults = int(line.split()[1])
    except (OSError, ValueError):
        pass
    return stall, faults


_PAUSE_PROBE = '''
import json, signal, sys, time
worst, when, t0 = 0.0, 0.0, time.monotonic()
def report(*_):
    print(json.dumps({"longest_pause_s": worst, "at_s": when}), flush=True)
    sys.exit(0)
signal.signal(signal.SIGTERM, report)
last = time.monotonic()
while True:
    time.sleep(0.001)
    now = time.monotonic()
    if now - last > worst:
        worst, when = now - last, now - t0
    last = now
'''


def _pause_probe() -> subprocess.Popen:
    """A separate normal-priority process that sleeps 1 ms at a time and reports the longest
    it went without running: a pause of the whole host, not only of the driver process."""
    return subprocess.Popen([sys.executable, '-c', _PAUSE_PROBE], stdout=subprocess.PIPE,
                            text=True)


def _burn() -> subprocess.Popen:
    return subprocess.Popen([sys.executable, '-c', 'while True: pass'])


def run_hold(duration_s: float, target_n: float, rt_priority: int, burners: int,
             emulator_priority: int) -> dict[str, float]:
    """Hold ``target_n`` [N] for ``duration_s`` [s] through the real node beside CPU burners.

    Returns:
        The figures printed for the case.
    """
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import MultiThreadedExecutor
    from rclpy.lifecycle import TransitionCallbackReturn
    from rclpy.parameter import Parameter
    from rclpy.signals import SignalHandlerOptions
    from std_srvs.srv import Trigger

    from slip_cell_common.node_main import shutdown_lifecycle
    from slip_cell_common.testing import SpinThread
    from slip_gripper_driver.gripper_driver_node import GripperDriverNode

    tmp = tempfile.mkdtemp(prefix='bench_gripper_hold_')
    port = os.path.join(tmp, 'gripper')
    box_port = _free_port('127.0.0.6')
    hosts = ('127.0.0.6', '127.0.0.5')
    truth_path = os.path.join(tmp, 'truth.f64')
    proc, _ = _start_emulator(port, duration_s + 30.0, False,
                              [f'{h}:{box_port}' for h in hosts], priority=emulator_priority,
                              truth_path=truth_path)
    context = Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    overrides = {'autostart': False, 'serial.port': port, 'ft.mode': 'embedded',
                 'ft.finger_1.address': hosts[0], 'ft.finger_2.address': hosts[1],
                 'ft.port': box_port, 'ft.read_config': False, 'ft.counts_per_force': 1.0e6,
                 'ft.counts_per_torque': 1.0e6, 'realtime.priority': rt_priority}
    node = GripperDriverNode(context=context, parameter_overrides=[
        Parameter(k, value=v) for k, v in overrides.items()])
    n_max = int((duration_s + 10.0) / PERIOD_S) + 1000
    force = np.full(n_max, np.nan)
    volts = np.full(n_max, np.nan)
    armed = np.zeros(n_max, dtype=bool)
    line_t = np.full(n_max, np.nan)  # monotonic [s] when the line's command had been written
    force_cmd = np.full(n_max, np.nan)
    bypass = np.zeros(n_max, dtype=np.int8)
    integral = np.full(n_max, np.nan)
    count = [0]
    recording = [False]
    events: list[tuple[str, str]] = []
    original_result, original_event = node._on_result, node._on_event

    def on_result(result: object) -> None:
        status = result.status  # type: ignore[attr-defined]
        if recording[0] and status is not None and result.command is not None:  # type: ignore
            i = count[0]
            if i < n_max:
                force[i], volts[i], armed[i] = (status.measured_grasp_force,
                                                status.voltage_cmd, status.armed)
                line_t[i] = time.monotonic()
                motor = result.motor  # type: ignore[attr-defined]
                if motor is not None:
                    force_cmd[i], bypass[i], integral[i] = (motor.force_cmd,
                                                            motor.bypass_reason, motor.integral)
                count[0] = i + 1
        original_result(result)

    def on_event(t: float, kind: str, message: str) -> None:
        if recording[0]:
            events.append((kind, message))
        original_event(t, kind, message)

    node._on_result = on_result
    node._on_event = on_event
    executor = MultiThreadedExecutor(context=context)
    executor.add_node(node)
    spinner = SpinThread(executor, on_start=node.tune_spin_thread)
    spinner.start()
    burning: list[subprocess.Popen] = []
    try:
        ok = TransitionCallbackReturn.SUCCESS
        if node.trigger_configure() != ok or node.trigger_activate() != ok:
            raise RuntimeError(f'gripper_driver did not start: {node.last_error}')
        time.sleep(0.5)
        reply = node._srv_bias(Trigger.Request(), Trigger.Response())
        if not reply.success:
            raise RuntimeError(f'bias failed: {reply.message}')
        burning = [_burn() for _ in range(burners)]
        probe = _pause_probe()
        burning.append(probe)  # killed with the burners if anything below fails
        node.core.bridge.set_grasp_force(target_n, node.now())
        time.sleep(2.0)  # close and settle
        diag0 = node.core.bridge.diagnostics(node.now())
        recording[0] = True
        steal0 = _steal_s()
        io0 = _io_stall_counters()
        cpu0, wall0 = time.process_time(), time.monotonic()
        time.sleep(duration_s)
        recording[0] = False
        cpu1, wall1 = time.process_time(), time.monotonic()
        steal1 = _steal_s()
        io1 = _io_stall_counters()
        probe.terminate()
        probe_out, _ = probe.communicate(timeout=10.0)
        host_pause = json.loads(probe_out.strip().splitlines()[-1]) if probe_out.strip() \
            else {}
        diag = node.core.bridge.diagnostics(node.now())
        tuning = sorted(set(node._tuning.results.values()))
    finally:
        for burner in burning:
            burner.kill()
            burner.wait()
        spinner.stop()  # before the endpoints go: no wait set built over destroyed entities
        shutdown_lifecycle(node)
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        proc.send_signal(2)
    out, _ = proc.communicate(timeout=30.0)
    emu = json.loads(out.strip().splitlines()[-1]) if out.strip() else {}
    truth = np.fromfile(truth_path, dtype=np.float64).reshape(-1, 3) \
        if os.path.exists(truth_path) else np.zeros((0, 3))
    truth = truth[(truth[:, 0] >= wall0) & (truth[:, 0] <= wall1)]
    truth_error = truth[:, 1] - target_n
    n = count[0]
    f, v, a = force[:n], volts[:n], armed[:n]
    error = f - target_n
    valid = error[np.isfinite(error)]
    dropouts = int(np.sum(v == 0.0))
    disarms = int(np.sum(a[:-1] & ~a[1:])) + (0 if n == 0 or a[0] else 1)
    figures = {
        'lines': n, 'expected': int(round((wall1 - wall0) / PERIOD_S)),
        'dropouts_0V': dropouts, 'disarms': disarms,
        'stale': diag.stale_events - diag0.stale_events,
        'faults': diag.link_faults - diag0.link_faults,
        'host_stalls': diag.host_stalls - diag0.host_stalls,
        'max_host_stall_ms': 1e3 * diag.max_host_stall_s,
        'catch_up_lines': diag.catch_up_lines - diag0.catch_up_lines,
        'resume_ramps': diag.resume_ramps - diag0.resume_ramps,
        'max_watchdog_gap_ms': 1e3 * diag.max_watchdog_gap_s,
        'steal_s': steal1 - steal0,
        'io_stall_s': io1[0] - io0[0],
        'major_faults': io1[1] - io0[1] if min(io0[1], io1[1]) >= 0 else -1,
        'host_pause_ms': 1e3 * host_pause.get('longest_pause_s', math.nan),
        'err_max': float(np.max(np.abs(valid))) if valid.size else math.nan,
        'err_rms': float(np.sqrt(np.mean(valid ** 2))) if valid.size else math.nan,
        'within_1N': float(np.mean(np.abs(valid) <= 1.0)) if valid.size else math.nan,
        'beyond_1N': int(np.sum(np.abs(valid) > 1.0)),
        'ft_missing': int(np.sum(~np.isfinite(error))),
        'truth_ticks': int(truth.shape[0]),
        'truth_err_max': float(np.max(np.abs(truth_error))) if truth.size else math.nan,
        'truth_err_rms': float(np.sqrt(np.mean(truth_error ** 2))) if truth.size else math.nan,
        'truth_beyond_1N': int(np.sum(np.abs(truth_error) > 1.0)),
        'cpu': 100 * (cpu1 - cpu0) / (wall1 - wall0),
        'emu_late_ticks': emu.get('late_ticks', -1),
        'emu_max_gap_ms': 1e3 * emu.get('max_send_gap_s', math.nan),
        'emu_long_gaps': emu.get('long_gaps', -1),
        'malformed': emu.get('malformed_commands', -1)}
    print(f'hold {target_n:.0f} N for {duration_s:.0f} s, realtime.priority {rt_priority} '
          f'({", ".join(tuning) or "?"}), {burners} CPU burners beside the driver')
    print(f'  commands written           {n:10d}   (≈ {figures["expected"]} periods)')
    print(f'  0 V dropouts               {dropouts:10d}   disarms {disarms}   '
          f'stale {figures["stale"]}   link faults {figures["faults"]}')
    print(f'  host stalls                {figures["host_stalls"]:10d}   (longest '
          f'{figures["max_host_stall_ms"]:.0f} ms over the run; catch-up lines '
          f'{figures["catch_up_lines"]}, resume ramps {figures["resume_ramps"]})')
    print(f'  driver process paused      longest {figures["max_watchdog_gap_ms"]:6.0f} ms (the '
          f'watchdog did not run; whole run); CPU stolen by the hypervisor during the hold '
          f'{figures["steal_s"]:.1f} s; a separate probe process went '
          f'{figures["host_pause_ms"]:.0f} ms at most without running')
    print(f'  host I/O during the hold       some task stalled on I/O for '
          f'{figures["io_stall_s"]:.1f} s; {figures["major_faults"]} major page faults '
          f'(pages read back from storage)')
    print(f'  force error (F/T − target) max {figures["err_max"]:6.2f} N   RMS '
          f'{figures["err_rms"]:5.3f} N   within ±1 N {100 * figures["within_1N"]:5.1f} %   '
          f'(lines without a fresh F/T value: {figures["ft_missing"]})')
    if figures['beyond_1N']:
        worst = int(np.nanargmax(np.abs(error)))
        around = slice(max(0, worst - 10), worst + 11)
        print(f'  lines beyond ±1 N          {figures["beyond_1N"]:10d}   worst at line {worst} '
              f'(≈ {worst * PERIOD_S:.1f} s into the hold); around it, F/T force [N]: '
              + ' '.join(f'{x:.1f}' for x in f[around]) + '; voltage [V]: '
              + ' '.join(f'{x:.2f}' for x in v[around]))
    print(f'  pad force (plant truth)    max error {figures["truth_err_max"]:6.2f} N   RMS '
          f'{figures["truth_err_rms"]:5.3f} N   ticks beyond ±1 N {figures["truth_beyond_1N"]} '
          f'of {figures["truth_ticks"]}')
    if figures['truth_beyond_1N']:
        _print_worst_truth(truth, target_n, line_t[:n], force_cmd[:n], bypass[:n],
                           integral[:n], f)
    print(f'  emulator (the firmware)    {figures["emu_long_gaps"]:10d}   sends > 20 ms after '
          f'the previous one (real link gaps, whole run; longest '
          f'{figures["emu_max_gap_ms"]:.1f} ms); late ticks {figures["emu_late_ticks"]}, '
          f'writes the pty refused {emu.get("dropped_writes", "?")}')
    _print_emulator_gaps(emu.get('gap_log', []), wall0)
    print(f'  driver CPU {figures["cpu"]:5.1f} % of one core; malformed commands at the '
          f'firmware {figures["malformed"]}', flush=True)
    for kind, message in events[:8]:
        print(f'    event {kind}: {message}')
    if len(events) > 8:
        print(f'    ... {len(events) - 8} more events')
    return figures


def _print_emulator_gaps(gaps: list[dict[str, float]], wall0: float) -> None:
    """The emulator's longest link gaps and where its thread spent them (CPU time used,
    preemptions, late wake-up, time in read/tick/write); ``wall0`` = hold start, monotonic
    [s] (the emulator's clock is the same system-wide one)."""
    if not gaps:
        return
    print('    longest emulator gaps (s into the hold (negative: before it); ms: gap, thread CPU '
          'meanwhile; preemptions/blocks; ms waiting for a CPU (nan: sysctl '
          'kernel.task_delayacct=0); major page faults; ms: sleep overslept, read, tick, '
          'write, own counter reads):')
    for g in gaps[:5]:
        print(f'      {g["at_s"] - wall0:8.1f} s  {1e3 * g["gap_s"]:7.1f}  cpu '
              f'{1e3 * g["cpu_s"]:6.1f}  switches {g["involuntary_switches"]:3d}/'
              f'{g["voluntary_switches"]:<4d}  runq {1e3 * g["runqueue_wait_s"]:7.1f}  '
              f'majflt {g["major_faults"]:3d}  overslept {1e3 * g["overslept_s"]:7.1f}  read '
              f'{1e3 * g["read_s"]:6.1f}  tick {1e3 * g["tick_s"]:6.1f}  write '
              f'{1e3 * g["write_s"]:6.1f}  clock {1e3 * g["clock_s"]:6.1f}')


def _print_worst_truth(truth: np.ndarray, target_n: float, line_t: np.ndarray,
                       force_cmd: np.ndarray, bypass: np.ndarray, integral: np.ndarray,
                       ft_force: np.ndarray) -> None:
    """The worst plant-truth tick, ±40 ms of plant force, and the driver's steps then."""
    worst = int(np.argmax(np.abs(truth[:, 1] - target_n)))
    t_w = truth[worst, 0]
    near = np.abs(truth[:, 0] - t_w) <= 0.040
    print(f'    worst tick: {truth[worst, 1]:.2f} N; plant force every 4 ms from -40 ms: '
          + ' '.join(f'{x:.1f}' for x in truth[near, 1][::2]))
    steps = np.flatnonzero(np.abs(line_t - t_w) <= 0.040)
    print('    driver steps then (ms from worst: F/T force, command N, bypass, integral N): '
          + '; '.join(f'{1e3 * (line_t[i] - t_w):+.0f}: {ft_force[i]:.1f}, {force_cmd[i]:.1f}, '
                      f'{bypass[i]}, {integral[i]:.2f}' for i in steps))


def main() -> int:
    """Parse arguments and run."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--duration', type=float, default=60.0, help='measured seconds')
    parser.add_argument('--quick', action='store_true', help='5 s run (make bench)')
    parser.add_argument('--no-ft', action='store_true', help='without the Net F/T emulators')
    parser.add_argument('--switch-interval-us', type=float, default=0.0,
                        help='sys.setswitchinterval for this process [µs]; 0 = Python default '
                             '(5000 µs) for the core run, the node\'s 500 µs with --node')
    parser.add_argument('--hold', action='store_true',
                        help='hold grasps through the node beside CPU burners (issue 16): one '
                             'case per --targets x --rt, each for --duration seconds')
    parser.add_argument('--targets', type=float, nargs='+', default=[10.0, 40.0],
                        help='--hold: grasp force targets [N] (default 10 40)')
    parser.add_argument('--rt', choices=('on', 'off'), nargs='+', default=['on', 'off'],
                        help='--hold: realtime.priority 10 (on) and/or 0 (off) (default both)')
    parser.add_argument('--burners', type=int, default=2,
                        help='--hold: CPU-burning processes beside the driver (default 2)')
    parser.add_argument('--node', action='store_true',
                        help='go through the real gripper_driver lifecycle node (rclpy, '
                             'publishers, watchdog) instead of the bare core')
    defaults = RealtimeParams()
    parser.add_argument('--priority', type=int, default=defaults.priority,
                        help='realtime.priority: SCHED_FIFO priority of the reader threads '
                             f'(node default {defaults.priority}; 0 = normal scheduling)')
    parser.add_argument('--no-freeze-gc', action='store_true',
                        help='realtime.freeze_gc false (no gc.freeze after set-up)')
    parser.add_argument('--emulator-priority', type=int, default=None,
                        help='SCHED_FIFO priority of the emulator child (it stands for the '
                             'firmware, whose timing does not depend on the host load); default '
                             '5, below the driver\'s so it never preempts a GIL holder of the '
                             'driver (at 20 it did: node p99 559 µs, 6 misses in 30 s); with '
                             '--hold 20, above it: a starved emulator stops sending, which is a '
                             'real link gap and not what --hold measures; 0 = off')
    args = parser.parse_args()
    if args.emulator_priority is None:
        args.emulator_priority = 20 if args.hold else 5
    rt = RealtimeParams(priority=args.priority, freeze_gc=not args.no_freeze_gc)
    if args.switch_interval_us > 0.0:
        sys.setswitchinterval(args.switch_interval_us * 1e-6)
    elif args.node:
        from slip_gripper_driver.gripper_driver_node import SWITCH_INTERVAL_S
        sys.setswitchinterval(SWITCH_INTERVAL_S)
    print(f'GIL switch interval {sys.getswitchinterval() * 1e6:.0f} µs')
    duration = 5.0 if args.quick else args.duration
    if args.hold:
        from slip_gripper_driver.gripper_driver_node import SWITCH_INTERVAL_S
        sys.setswitchinterval(SWITCH_INTERVAL_S)
        for rt in args.rt:
            for target in args.targets:
                run_hold(duration, target, 10 if rt == 'on' else 0, args.burners,
                         args.emulator_priority)
        return 0
    if args.node:
        run_node(duration, not args.no_ft, rt, args.emulator_priority)
    else:
        run(duration, not args.no_ft, rt, args.emulator_priority)
    return 0


if __name__ == '__main__':
    sys.exit(main())
