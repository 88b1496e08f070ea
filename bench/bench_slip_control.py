# SPDX-License-Identifier: Apache-2.0
"""Cost of one slip-controller step and one estimator step (ROS-free cores), in µs; and, with
``--dds``, the sensor-message-in → grasp-force-command-out latency of the slip_controller node.

Prints p50/p99/max per mode; never asserts (targets from issue 7: controller step ≤ 100 µs in
the core; DDS in → out p99 ≤ 5 ms). The core inputs are pre-built snapshots from the synthetic
streams, so only the core step is timed.

``--dds`` starts the slip_controller node in a subprocess (its YAML plus the shared cell.yaml),
publishes valid contact properties, switches it to HOLD and plays 500 Hz wrenches and 120 Hz
twists (both fingers, stamped with the system clock) from this process. Latency = time from
publishing a finger-1 twist (the control trigger) to receiving the command it produced, both
on this process's monotonic clock, so it includes two DDS hops, both executors and the step.

Usage: python bench/bench_slip_control.py [--quick] [--dds]
(run from the repository root; `make bench` passes --quick; --dds needs the workspace
environment: tools/run_ros.sh .venv/bin/python bench/bench_slip_control.py --dds).
"""
from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
for pkg in ('slip_control', 'slip_cell_common'):
    sys.path.insert(0, str(ROOT / 'src' / pkg))

from slip_control.core.contact import ContactProperties, ContactSource, FingerContact  # noqa: E402
from slip_control.core.controllers import (ControlContact, HingeController,  # noqa: E402
                                           HoldController, LinearController, OffController,
                                           RotationalController, SlipController, SlipMode)
from slip_control.core.contact_estimator import ContactEstimator, EstimationPhase  # noqa: E402
from slip_control.core.controller_host import ControllerHost  # noqa: E402
from slip_control.core.mode_switch import ModeRequest, build_controller  # noqa: E402
from slip_control.core.params import (ContactEstimatorParams,  # noqa: E402
                                      EstimatorOnlineParams, SlipControllerParams)
from slip_control.core.signals import SensorSnapshot  # noqa: E402
from slip_control.core.synthetic import (TrueContact, controlled_slip,  # noqa: E402
                                         exploration_linear, exploration_rotational)


def _stats(ns: list[int]) -> tuple[float, float, float]:
    a = np.asarray(ns, dtype=np.float64) / 1000.0
    return float(np.percentile(a, 50)), float(np.percentile(a, 99)), float(a.max())


def _snapshots(n: int) -> list[SensorSnapshot]:
    """≥ n realistic snapshots with increasing stamps (controlled slip, repeated)."""
    truth = (TrueContact(), TrueContact(mu_c=0.4, r=0.005))
    base = controlled_slip(truth, seed=0)
    period = len(base) / 120.0 + 1.0
    out: list[SensorSnapshot] = []
    k = 0
    while len(out) < n:
        out.extend(controlled_slip(truth, t0=k * period, seed=k))
        k += 1
    return out[:n]


def _time_controller(make: Callable[[float], SlipController], snaps: list[SensorSnapshot],
                     repeats: int) -> list[int]:
    samples: list[int] = []
    clock = time.perf_counter_ns
    for _ in range(repeats):
        ctrl = make(snaps[0].twist_1.stamp)  # type: ignore[union-attr]
        for s in snaps:
            t = s.twist_1.stamp + 0.0005  # type: ignore[union-attr]
            t0 = clock()
            out = ctrl.step(s, t)
            samples.append(clock() - t0)
            if out.next_controller is not None:      # keep timing the mode under test
                ctrl = make(t)
    return samples


def _props() -> ContactProperties:
    f = FingerContact(mu_c=0.45, mu_s=0.5, mu_v=1.0, r=0.006, u=3.6e-5, mu_c_std=0.005,
                      r_std=2e-4, n_linear=60, n_static=5, n_rotational=60, linear_valid=True,
                      viscous_valid=True, static_valid=True, rotational_valid=True)
    return ContactProperties(f, f, ContactSource.ESTIMATED)


def _dds(n_twists: int) -> None:
    """Sensor message in → grasp-force command out through DDS, controller in a subprocess."""
    import os
    import tempfile

    import rclpy
    from geometry_msgs.msg import TwistStamped, WrenchStamped
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from slip_cell_common.time_conv import nanoseconds_to_stamp
    from slip_control.slip_msgs_conv import properties_to_msg
    from slip_cell_common.calls import call_service, spin_until
    from slip_cell_common.core import names
    from slip_cell_common.qos import LATCHED, SENSOR_PUB
    from slip_cell_common.testing import NodeProcess
    from slip_msgs.msg import ContactProperties as ContactPropertiesMsg
    from slip_msgs.msg import GraspForceCommand
    from slip_msgs.srv import SetSlipMode

    if os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE') != 'LOCALHOST':
        sys.exit('--dds needs the workspace environment: tools/run_ros.sh '
                 '.venv/bin/python bench/bench_slip_control.py --dds')
    cfg = ROOT / 'src' / 'slip_control' / 'config' / 'slip_controller.yaml'
    cell = ROOT / 'src' / 'slip_gripper_driver' / 'config' / 'cell.yaml'
    log = Path(tempfile.mkdtemp(prefix='bench_slip_dds_')) / 'slip_controller.log'
    proc = NodeProcess.python_module('slip_control.slip_controller_node', [
        '--ros-args', '-r', '__node:=slip_controller', '--params-file', str(cell),
        '--params-file', str(cfg)], log)
    rclpy.init()
    node = Node('bench_slip_dds')
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    wpub = [node.create_publisher(WrenchStamped, names.ft_wrench(k), SENSOR_PUB)
            for k in (1, 2)]
    tpub = [node.create_publisher(TwistStamped, names.slip_twist(k), SENSOR_PUB)
            for k in (1, 2)]
    ppub = node.create_publisher(ContactPropertiesMsg, names.CONTACT_PROPERTIES, LATCHED)
    arrivals: list[int] = []
    node.create_subscription(
        GraspForceCommand, names.GRASP_FORCE_CMD,
        lambda m: arrivals.append(time.perf_counter_ns()),
        QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE))
    clock = node.get_clock()

    def wrenches() -> None:
        stamp = nanoseconds_to_stamp(clock.now().nanoseconds)
        for k, pub in enumerate(wpub, start=1):
            m = WrenchStamped()
            m.header.stamp, m.header.frame_id = stamp, names.ft_sensor_frame(k)
            m.wrench.force.x, m.wrench.force.y, m.wrench.force.z = 0.3, 0.8, -6.0
            m.wrench.torque.z = 1e-3
            pub.publish(m)

    def twists() -> int:
        stamp = nanoseconds_to_stamp(clock.now().nanoseconds)
        msgs = []
        for k in (2, 1):
            m = TwistStamped()
            m.header.stamp, m.header.frame_id = stamp, names.vel_sensor_frame(k)
            m.twist.linear.x = 0.001
            msgs.append((k, m))
        tpub[1].publish(msgs[0][1])
        t0 = time.perf_counter_ns()
        tpub[0].publish(msgs[1][1])
        return t0

    def play(n: int, latencies: list[int] | None) -> int:
        lost = 0
        period = 1.0 / 120.0
        for _ in range(n):
            t_next = time.perf_counter() + period
            wrenches()
            before = len(arrivals)
            t0 = twists()
            got = spin_until(ex, lambda before=before: len(arrivals) > before, 0.05, step_s=0.001)
            if got and latencies is not None:
                latencies.append(arrivals[before] - t0)
            elif not got:
                lost += 1
            for k in (1, 2, 3):       # the remaining 500 Hz wrench samples of this period
                t_w = t_next - period + k * 0.002
                while time.perf_counter() < t_w:
                    ex.spin_once(timeout_sec=max(0.0, t_w - time.perf_counter()))
                wrenches()
            while time.perf_counter() < t_next:
                ex.spin_once(timeout_sec=max(0.0, t_next - time.perf_counter()))
        return lost

    try:
        props = _props()
        ppub.publish(properties_to_msg(props, nanoseconds_to_stamp(clock.now().nanoseconds)))
        client = node.create_client(SetSlipMode, names.SLIP_SET_MODE_SRV)
        ok = False
        deadline = time.monotonic() + 20.0
        while not ok and time.monotonic() < deadline:
            res = call_service(ex, client, SetSlipMode.Request(mode=SetSlipMode.Request.HOLD),
                               10.0)
            ok = res is not None and res.success
            if not ok:
                ppub.publish(properties_to_msg(props,
                                               nanoseconds_to_stamp(clock.now().nanoseconds)))
                spin_until(ex, lambda: False, 0.2)
        if not ok:
            sys.exit(f'slip_controller did not accept HOLD; log: {log}')
        play(240, None)                                   # warm-up (2 s)
        lat: list[int] = []
        lost = play(n_twists, lat)
    finally:
        ex.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
        proc.stop()
    a = np.asarray(lat, dtype=np.float64) / 1e6
    print(f'slip_controller DDS latency: finger-1 twist published -> grasp-force command '
          f'received ({len(a)} samples at 120 Hz with 500 Hz wrenches, {lost} without a '
          'command within 50 ms)')
    print(f'{"":<10}{"p50 ms":>9}{"p90 ms":>9}{"p99 ms":>9}{"max ms":>9}')
    print(f'{"in->out":<10}{np.percentile(a, 50):>9.3f}{np.percentile(a, 90):>9.3f}'
          f'{np.percentile(a, 99):>9.3f}{a.max():>9.3f}')
    print(f'p99 {np.percentile(a, 99):.3f} ms (target <= 5 ms)')


def main() -> None:
    """Run the benchmarks and print a table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--quick', action='store_true', help='fewer repetitions')
    ap.add_argument('--dds', action='store_true',
                    help='only the DDS in->out latency of the slip_controller node')
    args = ap.parse_args()
    if args.dds:
        _dds(600 if args.quick else 3600)
        return
    n, repeats = (960, 3) if args.quick else (4800, 10)

    p = SlipControllerParams()
    c = ControlContact(mu_c=0.45, r=0.006, r_valid=True)
    snaps = _snapshots(n)
    rows: list[tuple[str, list[int]]] = []
    modes: dict[str, Callable[[float], SlipController]] = {
        'OFF': lambda t: OffController(p),
        'HOLD': lambda t: HoldController(p, c, initial_force=5.0),
        'HINGE': lambda t: HingeController(p, c),
        'LINEAR (direction-aware)': lambda t: LinearController(p, c, 0.1, 60.0, t),
        'LINEAR (reference)': lambda t: LinearController(
            SlipControllerParams(direction_aware=False), c, 0.1, 60.0, t),
        'ROTATIONAL': lambda t: RotationalController(p, c, 6.0, 60.0, t),
    }
    for name, make in modes.items():
        rows.append((f'controller step {name}', _time_controller(make, snaps, repeats)))

    # Safe-hold path (velocity stale: watchdog steps with an old twist).
    stale = [SensorSnapshot(s.wrench_1, s.wrench_2, snaps[0].twist_1, snaps[0].twist_2)
             for s in snaps]
    samples: list[int] = []
    hold = HoldController(p, c, initial_force=5.0)
    for i, s in enumerate(stale):
        t = 1.0 + i * 0.01
        t0 = time.perf_counter_ns()
        hold.step(s, t)
        samples.append(time.perf_counter_ns() - t0)
    rows.append(('controller step HOLD safe-hold (stale velocity)', samples))

    # The node's host around HOLD: four samples in, stale check + debounce, the step.
    props = _props()
    samples = []
    for _ in range(repeats):
        host = ControllerHost(p, props)
        host.switch(ModeRequest(int(SlipMode.HOLD)), snaps[0].twist_1.stamp)  # type: ignore
        for i, s in enumerate(snaps):
            t = s.twist_1.stamp + 0.0005  # type: ignore[union-attr]
            t0 = time.perf_counter_ns()
            host.on_wrench(1, s.wrench_1)  # type: ignore[arg-type]
            host.on_wrench(2, s.wrench_2)  # type: ignore[arg-type]
            host.on_twist(2, s.twist_2)  # type: ignore[arg-type]
            if host.on_twist(1, s.twist_1):  # type: ignore[arg-type]
                host.step(t, steady=float(i))
            samples.append(time.perf_counter_ns() - t0)
    rows.append(('controller host HOLD (4 samples in + step)', samples))

    # Mode switch: validate + build a complete controller.
    samples = []
    req = ModeRequest(int(SlipMode.LINEAR), duration=2.0, distance=0.02)
    for i in range(n):
        t0 = time.perf_counter_ns()
        build_controller(req, props, p, float(i))
        samples.append(time.perf_counter_ns() - t0)
    rows.append(('mode switch build_controller(LINEAR)', samples))

    # Estimator steps (per finger-1 twist; both fingers processed).
    ep = ContactEstimatorParams(online=EstimatorOnlineParams(enabled=True))
    truth = (TrueContact(), TrueContact(mu_c=0.4, r=0.005))
    for phase, gen in ((EstimationPhase.LINEAR, exploration_linear),
                       (EstimationPhase.ROTATIONAL, exploration_rotational)):
        samples = []
        fit_ns: list[int] = []
        for r in range(max(3, repeats * 3)):
            est = ContactEstimator(ep, props)
            data = gen(truth, t0=10.0, seed=r)
            est.start(phase, 1.0, 10.0)
            for s in data:
                t = s.twist_1.stamp  # type: ignore[union-attr]
                t0 = time.perf_counter_ns()
                est.step(s, t)
                samples.append(time.perf_counter_ns() - t0)
            t0 = time.perf_counter_ns()
            est.poll(11.0)                          # window over: fit and flags
            fit_ns.append(time.perf_counter_ns() - t0)
        rows.append((f'estimator step {phase.name} (collect)', samples))
        rows.append((f'estimator {phase.name} end of phase (fit)', fit_ns))
    samples = []
    est = ContactEstimator(ep, props)
    est.start(EstimationPhase.ONLINE, 0.0, 0.0)
    for s in snaps:
        t = s.twist_1.stamp  # type: ignore[union-attr]
        t0 = time.perf_counter_ns()
        est.step(s, t)
        samples.append(time.perf_counter_ns() - t0)
    rows.append(('estimator step ONLINE (RLS update)', samples))

    width = max(len(r[0]) for r in rows)
    print(f'slip_control core step cost (python {sys.version.split()[0]}, '
          f'{"quick" if args.quick else "full"} run)')
    print(f'{"step":<{width}}  {"n":>6}  {"p50 µs":>8}  {"p99 µs":>8}  {"max µs":>8}')
    for name, ns in rows:
        p50, p99, mx = _stats(ns)
        print(f'{name:<{width}}  {len(ns):>6}  {p50:>8.1f}  {p99:>8.1f}  {mx:>8.1f}')
    worst = max(_stats(ns)[1] for name, ns in rows if name.startswith('controller step'))
    print(f'worst controller-step p99: {worst:.1f} µs (target ≤ 100 µs)')


if __name__ == '__main__':
    main()
