"""``slip_demo`` (``make demo``): the main job on the simulated cell.

1. Starts the simulated-cell graph as separate processes (sim_gripper, contact_estimator,
   slip_controller, experiment_runner) with the packages' YAML files (`run_graph`).
2. Runs the experiment runner's ``demo`` sequence (grasp, estimate, pick up, hold, linear slip,
   hinge, rotational slip, release) through the ``experiment/run`` action, printing progress.
3. The runner records every topic to a rosbag2 (MCAP) bag.
4. Stops every process (SIGINT, then SIGKILL), analyses the bag and prints a summary:
   estimates vs simulator truth, slip targets vs achieved, grasp forces, and the output paths.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from datetime import datetime
from pathlib import Path
from typing import Any

import rclpy
from rclpy.action import ActionClient
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from slip_bringup.analyze import _jsonable, analyze_bag, plot_bag
from slip_bringup.run_graph import GraphError, GraphRunner, _prefix, load_graph
from slip_cell_common.calls import spin_until


def _say(text: str) -> None:
    print(f'[demo {time.strftime("%H:%M:%S")}] {text}', flush=True)


def _finger_row(name: str, est: Any, truth: Any) -> str:
    def cell(value: float, scale: float = 1.0, fmt: str = '{:8.4f}') -> str:
        return fmt.format(value * scale) if value is not None and math.isfinite(value) \
            else f'{"n/a":>8}'
    mu_err = (est['mu_c'] - truth['mu_c']) if est and truth else None
    r_err = (est['r'] - truth['r']) if est and truth else None
    return (f'  {name:<9} mu_c {cell(est["mu_c"] if est else None)} (truth '
            f'{cell(truth["mu_c"] if truth else None)}, err {cell(mu_err)})   r '
            f'{cell(est["r"] if est else None, 1e3, "{:6.2f}")} mm (truth '
            f'{cell(truth["r"] if truth else None, 1e3, "{:6.2f}")} mm, err '
            f'{cell(r_err, 1e3, "{:6.2f}")} mm)')


def summary(metrics: dict[str, Any]) -> str:
    """The table printed at the end of the demo."""
    lines = ['', '=== Summary ' + '=' * 66]
    est = metrics.get('estimation', {})
    last = est.get('estimates', [])[-1] if est.get('estimates') else None
    truth = est.get('truth')
    lines.append('Contact estimate vs simulator truth'
                 + (f' (object {truth["preset"]!r})' if truth else '') + ':')
    for key in ('finger_1', 'finger_2'):
        lines.append(_finger_row(key, last[key] if last else None,
                                 truth[key] if truth else None))
    lines.append('Slip: target vs achieved:')
    for seg in metrics.get('slip', []):
        unit, scale = ('mm', 1e3) if seg['mode'] == 'linear' else ('deg', 180.0 / math.pi)
        true = seg.get('true_motion', {})
        true_val = true.get('distance' if seg['mode'] == 'linear' else 'angle')
        sensor = (seg.get('sensor_slip', {}) or {}).get('signed') if seg['mode'] == 'linear' \
            else seg.get('sensor_angle')
        dur = seg['t_end'] - seg['t_start']
        fmt = (lambda v: f'{v * scale:7.2f} {unit}' if v is not None else '    n/a')  # noqa: E731
        lines.append(f'  {seg["mode"]:<10} target {fmt(seg["target"])}   controller '
                     f'{fmt(seg["final_measured"])}   sensors {fmt(sensor)}   true object '
                     f'{fmt(abs(true_val) if true_val is not None else None)}   ({dur:.1f} s)')
    force = metrics.get('force', {})
    if 'measured_range' in force:
        lo, hi = force['measured_range']
        lines.append(f'Grasp force: measured {lo:.2f} .. {hi:.2f} N, tracking RMS '
                     f'{force.get("tracking_rms", float("nan")):.2f} N')
    return '\n'.join(lines)


def _run_experiment(node: Node, executor: SingleThreadedExecutor, mode: str, recording: str,
                    timeout_s: float) -> Any:
    from slip_msgs.action import RunExperiment
    client = ActionClient(node, RunExperiment, 'experiment/run')
    if not spin_until(executor, client.server_is_ready, 60.0):
        raise RuntimeError('experiment/run did not come up within 60 s')
    last_phase = ['']

    def feedback(msg: Any) -> None:
        phase = msg.feedback.phase
        if phase != last_phase[0]:
            last_phase[0] = phase
            _say(f'  {msg.feedback.elapsed:6.1f} s  {phase}')
    send = client.send_goal_async(RunExperiment.Goal(mode=mode, recording_name=recording),
                                  feedback_callback=feedback)
    if not spin_until(executor, send.done, 30.0) or not send.result().accepted:
        raise RuntimeError(f'experiment {mode!r} was not accepted')
    result = send.result().get_result_async()
    if not spin_until(executor, result.done, timeout_s):
        raise RuntimeError(f'experiment {mode!r} did not finish within {timeout_s:.0f} s')
    return result.result().result


def main(argv: list[str] | None = None) -> int:
    """Run the demo; exit code 0 when the experiment succeeded."""
    parser = argparse.ArgumentParser(prog='slip_demo', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--out', default=os.path.join('demo_output',
                                                      datetime.now().strftime('%Y%m%d_%H%M%S')))
    parser.add_argument('--mode', default='demo', help='runner mode (default: demo)')
    parser.add_argument('--preset', default='', help='object preset of the simulator')
    parser.add_argument('--realtime-factor', type=float, default=1.0)
    parser.add_argument('--timeout', type=float, default=240.0, help='experiment timeout [s]')
    ns = parser.parse_args(argv)
    out = Path(ns.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    started = time.monotonic()
    graph_path = _prefix('slip_bringup') / 'share' / 'slip_bringup' / 'config' / \
        'sim_cell.graph.yaml'
    sim_values: dict[str, Any] = {'realtime_factor': float(ns.realtime_factor)}
    if ns.preset:
        sim_values['preset'] = ns.preset
    try:
        runner = GraphRunner(load_graph(graph_path), out / 'logs', overrides={
            'sim_gripper': sim_values,
            'experiment_runner': {'recording.directory': str(out)}})
    except GraphError as exc:
        print(f'slip_demo: error: {exc}', file=sys.stderr)
        return 2
    _say(f'starting the simulated cell ({", ".join(n.name for n in runner.graph.nodes)}); '
         f'ROS_DOMAIN_ID={os.environ.get("ROS_DOMAIN_ID")}, logs in {out / "logs"}')
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = Node('slip_demo')
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    code = 1
    result = None
    try:
        runner.start()
        _say(f'running experiment {ns.mode!r} (recording every topic)')
        result = _run_experiment(node, executor, ns.mode, 'demo', ns.timeout)
        _say(f'experiment finished: success={result.success} {result.message}')
        code = 0 if result.success else 1
    except (RuntimeError, GraphError) as exc:
        _say(f'FAILED: {exc}')
    except KeyboardInterrupt:
        _say('interrupted')
        code = 130
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
        codes = runner.stop() if runner.procs else {}
        _say(f'stopped the graph: exit codes {codes}')
        crashed = {n: c for n, c in codes.items() if c not in (0, -2, 130)}
        if crashed:
            _say(f'node(s) did not stop cleanly: {crashed}; see {out / "logs"}')
            code = code or 1
    if result is not None and result.bag_path:
        bag = Path(result.bag_path)
        metrics = _jsonable(analyze_bag(bag))
        (out / 'metrics.json').write_text(json.dumps(metrics, indent=2) + '\n')
        plots = plot_bag(bag, out)
        print(summary(metrics))
        print('\nOutputs:')
        print(f'  bag      {bag}')
        print(f'  metrics  {out / "metrics.json"}')
        for p in plots:
            print(f'  plot     {p}')
        print(f'  logs     {out / "logs"}')
    _say(f'done in {time.monotonic() - started:.0f} s (exit code {code})')
    return code


if __name__ == '__main__':
    sys.exit(main())
