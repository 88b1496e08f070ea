# SPDX-License-Identifier: Apache-2.0
"""Benchmark of the velocity-sensor host path (issue 6: < 2 % of one core at 120 Hz per
sensor, line arrival to published twist p99 <= 1 ms).

1. CPU cost per line, offline: parse + session (validation, pose integration) + host fusion of
   six chip readings (+ outlier check) + publish, over emulator-generated lines. Reported per
   stage in µs and as % of one core at 120 Hz.
2. Latency against the firmware emulator on a pseudo-terminal (in a child process), through
   the same serial reader the node uses (``slip_cell_common.core.serial_transport.SerialLink``):
   arrival stamp (bytes returned by the read) → processed and published sample, and emulator
   write → published sample (includes the pty and the reader thread wake-up); plus the CPU
   share of the whole host process while streaming.

"publish" is simulated by default (both messages built and serialised to bytes, as the
middleware would); ``--publish ros`` publishes real TwistStamped messages (needs rclpy and the
isolated environment of tools/run_ros.sh). Prints a table; never asserts.
"""
from __future__ import annotations

import argparse
import math
import multiprocessing
import os
import statistics
import struct
import sys
import time
from collections import deque
from multiprocessing.connection import Connection
from pathlib import Path
from collections.abc import Callable

import numpy as np

_ROOT = Path(__file__).resolve().parents[1]
for _pkg in ('slip_velocity_sensor', 'slip_gripper_driver'):
    _path = str(_ROOT / 'src' / _pkg)
    if _path not in sys.path:
        sys.path.insert(0, _path)

from slip_cell_common.core import names  # noqa: E402
from slip_cell_common.core.serial_transport import SerialLink  # noqa: E402
from slip_velocity_sensor.core.emulator import (EmulatorParams, FirmwareEmulator,  # noqa: E402
                                                PtyEmulator, SineTwist)
from slip_velocity_sensor.core.fusion import RigidBodyFusion  # noqa: E402
from slip_velocity_sensor.core.protocol import LineParser, LineSplitter  # noqa: E402
from slip_velocity_sensor.core.session import Sample, SensorSession  # noqa: E402

RATE_HZ = 143.0  # mean line rate of the firmware (6-8 ms periods)
MOTION = SineTwist(vx=0.03, vy=-0.02, omega=0.8, frequency=0.7)
_TWIST = struct.Struct('<iI16s6d')           # header stamp, frame id, linear, angular
_PLANAR = struct.Struct('<iI16s9dBbd?')      # PlanarSlip fields


class SimulatedPublisher:
    """Build and serialise TwistStamped + PlanarSlip as bytes into a bounded queue."""

    def __init__(self) -> None:
        self.queue: deque[bytes] = deque(maxlen=64)
        self.frame = b'vel_sensor_1'

    def publish(self, s: Sample) -> None:
        sec = math.floor(s.stamp)
        nsec = int((s.stamp - sec) * 1e9)
        self.queue.append(_TWIST.pack(sec, nsec, self.frame, s.vx, s.vy, 0.0, 0.0, 0.0,
                                      s.omega))
        self.queue.append(_PLANAR.pack(sec, nsec, self.frame, s.vx, s.vy, s.omega, s.x, s.y,
                                       s.theta, s.chip_vx, s.chip_vy, 0.0, s.chip_mode,
                                       s.excluded_chip, s.residual_ratio, s.valid))


class RosPublisher:
    """Real rclpy publisher of TwistStamped (only inside the isolated ROS environment)."""

    def __init__(self) -> None:
        if os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE') != 'LOCALHOST' or \
                not os.environ.get('ROS_DOMAIN_ID'):
            raise SystemExit('--publish ros needs tools/run_ros.sh (private, loopback domain)')
        import rclpy
        from geometry_msgs.msg import TwistStamped
        from rclpy.context import Context

        from slip_cell_common.time_conv import seconds_to_stamp
        self._rclpy = rclpy
        self._msg = TwistStamped
        self._stamp = seconds_to_stamp
        self._context = Context()
        rclpy.init(context=self._context)
        self._node = rclpy.create_node('bench_velocity_sensor', context=self._context)
        self._pub = self._node.create_publisher(TwistStamped, 'bench/twist', 10)

    def publish(self, s: Sample) -> None:
        msg = self._msg()
        msg.header.stamp = self._stamp(s.stamp)
        msg.header.frame_id = names.vel_sensor_frame(1)
        msg.twist.linear.x, msg.twist.linear.y, msg.twist.angular.z = s.vx, s.vy, s.omega
        self._pub.publish(msg)

    def close(self) -> None:
        self._node.destroy_node()
        self._rclpy.try_shutdown(context=self._context)


def _lines(seconds: float) -> list[bytes]:
    emulator = FirmwareEmulator(EmulatorParams(default_radius=0.0243, seed=1), MOTION)
    emulator.advance(0.0)
    data = emulator.advance(seconds)
    return [line for line, _ in LineSplitter().feed(data)]


def _session() -> SensorSession:
    session = SensorSession(port='bench', expected_name='sensor_1')
    session.mark_initialised(calibration_source='bench', calibration_uploaded=True,
                             speed_term='zero')
    return session


def _time_per_item(func: Callable[[int], None], n: int, repeats: int) -> float:
    """Best-of-``repeats`` process CPU time per item [s]."""
    best = math.inf
    for _ in range(repeats):
        start = time.process_time()
        for i in range(n):
            func(i)
        best = min(best, (time.process_time() - start) / n)
    return best


def cpu_cost(seconds: float, repeats: int, publisher: Callable[[Sample], None]) -> list[tuple]:
    """Per-stage CPU time per line [s]."""
    lines = _lines(seconds)
    n = len(lines)
    stamps = [k / RATE_HZ for k in range(n)]
    rng = np.random.default_rng(0)
    fusion = RigidBodyFusion()
    twists = np.array([MOTION(t) for t in stamps])
    chips = fusion.forward(twists) + rng.normal(0.0, 5e-4, (n, 6))
    chips[::7, 0:2] = 0.0  # every 7th set has chip 1 off the surface
    chip_rows = [np.ascontiguousarray(row) for row in chips]
    parser = LineParser()
    parse = _time_per_item(lambda i: parser.parse(lines[i]), n, repeats)

    def run_session(i: int, s: SensorSession = _session()) -> None:
        s.handle_line(stamps[i], lines[i])
    session = _time_per_item(run_session, n, repeats)
    fuse = _time_per_item(lambda i: fusion.fuse(chip_rows[i]), n, repeats)
    samples = [s for s in (_session().handle_line(t, ln) for t, ln in zip(stamps, lines)) if s]
    publish = _time_per_item(lambda i: publisher(samples[i % len(samples)]), n, repeats)

    def full(i: int, s: SensorSession = _session()) -> None:
        sample = s.handle_line(stamps[i], lines[i])
        fusion.fuse(chip_rows[i])
        if sample is not None:
            publisher(sample)
    total = _time_per_item(full, n, repeats)
    return [('parse (line -> SI values)', parse), ('session (parse + validity + pose)', session),
            ('host fusion (6 chip readings, outlier check)', fuse), ('publish', publish),
            ('total per line (session + fusion + publish)', total)], n


def _serve_emulator(conn: Connection) -> None:
    """Child process: the firmware emulator on a pty, started and stopped by the parent."""
    pty = PtyEmulator(FirmwareEmulator(EmulatorParams(default_radius=0.0243), MOTION),
                      record_write_times=True)
    conn.send(pty.port)
    try:
        if conn.recv() != 'start':
            return
        pty.start()
        conn.recv()                     # 'stop'
        pty.emulator.set_silent(True)   # no more lines; the parent drains its reader
        conn.send(pty.write_times)
        conn.recv()                     # 'close'
    finally:
        pty.stop()


def latency(seconds: float, publisher: Callable[[Sample], None],
            process: bool = True) -> dict[str, object]:
    """Arrival → published and emulator write → published latencies [s], host CPU share.

    The emulator runs in a child process, so the host figures (latency, CPU) are those of a
    node process: reader thread, parsing, session and publishing, with nothing else competing
    for the interpreter lock. Both processes stamp with CLOCK_MONOTONIC. With ``process=False``
    the lines are only counted (the cost of the serial reader alone).
    """
    ctx = multiprocessing.get_context('spawn')
    parent, child = ctx.Pipe()
    server = ctx.Process(target=_serve_emulator, args=(child,), daemon=True)
    server.start()
    session = _session()
    arrival: list[float] = []
    processed: list[float] = []

    def on_line(line: bytes, overflow: bool, t: float) -> None:
        sample = session.handle_line(t, line, overflow) if process else None
        if sample is not None:
            publisher(sample)
            processed.append(time.monotonic())
            arrival.append(t)
        elif not process:
            processed.append(t)
            arrival.append(t)

    port = parent.recv()
    link = SerialLink(port, clock=time.monotonic, on_line=on_line, read_timeout_s=0.02)
    try:
        link.open()
        link.start()
        cpu0, wall0 = time.process_time(), time.monotonic()
        parent.send('start')            # the device starts talking once the reader listens
        time.sleep(seconds)
        parent.send('stop')
        writes = np.array(parent.recv())
        time.sleep(0.1)
        wall, cpu = time.monotonic() - wall0, time.process_time() - cpu0
    finally:
        link.close()
        parent.send('close')
        server.join(5.0)
    host = np.array(processed) - np.array(arrival)
    # Match lines in order: the pty loses nothing; the reader drops what precedes its first
    # line terminator (the first line), so the processed lines are the last ones written.
    skipped = len(writes) - len(processed)
    emit = (np.array(processed) - writes[skipped:]) if 0 <= skipped <= 2 else np.array([])
    return {'lines': len(processed), 'rate_hz': len(processed) / wall,
            'arrival': host, 'emit': emit, 'process_cpu_pct': 100.0 * cpu / wall}


def _fmt(x: np.ndarray) -> str:
    if len(x) == 0:
        return 'n/a'
    p50, p99, mx = np.percentile(x, 50), np.percentile(x, 99), np.max(x)
    return f'{p50 * 1e6:8.1f} {p99 * 1e6:8.1f} {mx * 1e6:9.1f}'


def main(argv: list[str] | None = None) -> int:
    """Run both parts and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--duration', type=float, default=10.0,
                        help='seconds of pty streaming for the latency part (and ×6 of lines '
                             'for the CPU part)')
    parser.add_argument('--quick', action='store_true', help='short run (make bench)')
    parser.add_argument('--publish', choices=('simulated', 'ros'), default='simulated')
    args = parser.parse_args(argv)
    duration = 3.0 if args.quick else args.duration
    repeats = 3 if args.quick else 5
    ros = RosPublisher() if args.publish == 'ros' else None
    publisher = ros.publish if ros is not None else SimulatedPublisher().publish
    try:
        stages, n_lines = cpu_cost(6.0 * duration, repeats, publisher)
        lat = latency(duration, publisher)
        reader_only = latency(duration, publisher, process=False)
    finally:
        if ros is not None:
            ros.close()
    load = ', '.join(f'{x:.2f}' for x in os.getloadavg())
    print(f'velocity sensor host path, {RATE_HZ:.0f} Hz per sensor, publish={args.publish} '
          f'(python {sys.version.split()[0]}, {os.cpu_count()} cpu, load {load})')
    print(f'\nCPU per line (best of {repeats} passes over {n_lines} emulator lines)')
    print(f'{"stage":<46} {"us/line":>9} {f"% core @{RATE_HZ:.0f} Hz":>15}')
    for name, per_line in stages:
        print(f'{name:<46} {per_line * 1e6:9.2f} {100.0 * per_line * RATE_HZ:14.3f}%')
    print(f'\nLatency, pty emulator, {lat["lines"]} lines in {duration:.0f} s '
          f'({lat["rate_hz"]:.1f} Hz)')
    print(f'{"path":<46} {"p50 us":>8} {"p99 us":>8} {"max us":>9}')
    print(f'{"arrival stamp -> published sample":<46} {_fmt(lat["arrival"])}')
    print(f'{"emulator write -> published sample":<46} {_fmt(lat["emit"])}')
    print('\nCPU of the host process while streaming, % of one core')
    print(f'{"reader thread + parse + session + publish":<46} {lat["process_cpu_pct"]:8.2f}')
    print(f'{"serial reader alone (same link, lines dropped)":<46} '
          f'{reader_only["process_cpu_pct"]:8.2f}')
    print(f'(statistics: mean arrival latency '
          f'{statistics.fmean(lat["arrival"]) * 1e6 if len(lat["arrival"]) else math.nan:.1f} us)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
