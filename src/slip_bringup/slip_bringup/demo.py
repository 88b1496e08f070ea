"""``slip_demo`` (``make demo``): the main job on the simulated cell.

1. Starts the simulated-cell graph as separate processes (sim_gripper, contact_estimator,
   slip_controller, experiment_runner) with the packages' YAML files (`run_graph`).
2. Runs the experiment runner's ``demo`` sequence (grasp, estimate, pick up, hold, linear slip,
   hinge, rotational slip, release) through the ``experiment/run`` action, printing progress.
3. The runner records every topic of the graph (``recording.topics: ['*']``: sensors, commands,
   ``joint_states``, ``/tf``, ``/tf_static``, ``robot_description``, the simulator's object pose
   and twist, ``/clock``, diagnostics, logs) to a rosbag2 (MCAP) bag.
4. Stops every process (SIGINT, then SIGKILL), analyses the bag and prints a summary:
   estimates vs simulator truth, one row per slip segment (the demo's own target, the
   controller's, the sensors' and the simulator's result, PASS or FAILED with the reason),
   the worst ``/diagnostics`` level seen, the achieved real-time factor, grasp forces, and
   the output paths (`slip_bringup.core.demo_summary`).

Honest exit code: 0 only when the runner succeeded **and** every slip segment ended "done"
with the simulator's truth within the stated tolerance (``--linear-tolerance``,
``--angle-tolerance``); otherwise 1 (2: bad arguments or graph; 130: interrupted).
``--set NODE.PARAM=VALUE`` overrides a parameter of one node of the graph (a test hook, e.g.
to inject a fault into the real graph).

Outputs go to ``--out`` (default ``$SLIP_DATA_DIR/demo/<time>``, else
``~/.local/share/slip_cell/demo/<time>``; never the working directory unless asked).
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

import rclpy
import yaml
from rclpy.action import ActionClient
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions

from slip_bringup.analyze import report as analysis_report
from slip_bringup.core.demo_summary import (
    DemoVerdict,
    Tolerances,
    Trajectory,
    build_verdict,
    demo_targets,
    format_verdict,
    object_motion,
    realtime_factor,
    trajectories_from_states,
    truth_window,
    worst_diagnostics,
)
from slip_bringup.run_graph import GraphError, GraphRunner, _prefix, load_graph
from slip_cell_common.bag_io import BagError, default_data_directory, read_messages, stamp_s
from slip_cell_common.calls import spin_until
from slip_cell_common.core import names

#: The demo bag holds every topic of the graph (hidden action topics excepted, as rosbag2).
RECORD_EVERY_TOPIC = ('*',)


def _say(text: str) -> None:
    print(f'[demo {time.strftime("%H:%M:%S")}] {text}', flush=True)


def _finger_row(name: str, est: Any, truth: Any) -> str:
    def cell(value: float | None, scale: float = 1.0, fmt: str = '{:8.4f}') -> str:
        return fmt.format(value * scale) if value is not None and math.isfinite(value) \
            else f'{"n/a":>8}'
    mu_err = (est['mu_c'] - truth['mu_c']) if est and truth else None
    r_err = (est['r'] - truth['r']) if est and truth else None
    return (f'  {name:<9} mu_c {cell(est["mu_c"] if est else None)} (truth '
            f'{cell(truth["mu_c"] if truth else None)}, err {cell(mu_err)})   r '
            f'{cell(est["r"] if est else None, 1e3, "{:6.2f}")} mm (truth '
            f'{cell(truth["r"] if truth else None, 1e3, "{:6.2f}")} mm, err '
            f'{cell(r_err, 1e3, "{:6.2f}")} mm)')


def summary(metrics: dict[str, Any], verdict: DemoVerdict | None = None,
            tolerances: Tolerances | None = None) -> str:
    """The table printed at the end of the demo (`format_verdict` for the slip rows, the
    diagnostics, the real-time factor and the result)."""
    lines = ['', '=== Summary ' + '=' * 66]
    est = metrics.get('estimation', {})
    last = est.get('estimates', [])[-1] if est.get('estimates') else None
    truth = est.get('truth')
    lines.append('Contact estimate vs simulator truth'
                 + (f' (object {truth["preset"]!r})' if truth else '') + ':')
    for key in ('finger_1', 'finger_2'):
        lines.append(_finger_row(key, last[key] if last else None,
                                 truth[key] if truth else None))
    force = metrics.get('force', {})
    if 'measured_range' in force:
        lo, hi = force['measured_range']
        lines.append(f'Grasp force: measured {lo:.2f} .. {hi:.2f} N, tracking RMS '
                     f'{force.get("tracking_rms", float("nan")):.2f} N')
    if verdict is not None:
        lines += format_verdict(verdict, tolerances or Tolerances())
    return '\n'.join(lines)


def _level(value: Any) -> int:
    """A ``DiagnosticStatus.level`` (bytes in rclpy, int in rosbags) as an int."""
    return value[0] if isinstance(value, (bytes, bytearray)) else int(value)


@dataclass
class RunRecord:
    """What the verdict is judged from, as plain tuples (stamps [s], sim time).

    Filled live by `RunMonitor` (the demo's own subscriptions: a light process that keeps up
    when the runner's recorder falls behind on a busy host) and from the bag; duplicates are
    merged.
    """

    states: set[tuple[float, bool, str]] = field(default_factory=set)
    sim: dict[float, tuple[float, float, float, float]] = field(default_factory=dict)
    diagnostics: list[tuple[int, str, str]] = field(default_factory=list)
    _diag_seen: set[tuple[float, str, str]] = field(default_factory=set)

    def add_state(self, msg: Any) -> None:
        """A ``slip_control/state`` message."""
        self.states.add((stamp_s(msg), bool(msg.goal_active), str(msg.reason)))

    def add_sim(self, msg: Any) -> None:
        """A ``sim/state`` message: ``(x, y, theta, realtime_factor)`` by stamp."""
        self.sim[stamp_s(msg)] = (float(msg.x), float(msg.y), float(msg.theta),
                                  float(msg.realtime_factor))

    def add_diagnostics(self, msg: Any) -> None:
        """A ``/diagnostics`` array (each status once per stamp)."""
        t = stamp_s(msg)
        for st in msg.status:
            key = (t, str(st.name), str(st.message))
            if key not in self._diag_seen:
                self._diag_seen.add(key)
                self.diagnostics.append((_level(st.level), str(st.name), str(st.message)))

    def add_bag(self, bag: Path) -> None:
        """Merge the same topics from the demo's bag."""
        topics = (names.absolute(names.SLIP_CONTROLLER_STATE), names.absolute(names.SIM_STATE),
                  names.absolute(names.DIAGNOSTICS))
        msgs = read_messages(bag, topics)
        for _, m in msgs.get(topics[0], []):
            self.add_state(m)
        for _, m in msgs.get(topics[1], []):
            self.add_sim(m)
        for _, m in msgs.get(topics[2], []):
            self.add_diagnostics(m)

    def last_sim_t(self) -> float:
        """Newest ``sim/state`` stamp [s] (0 if none)."""
        return max(self.sim) if self.sim else 0.0


class RunMonitor:
    """The demo's own subscriptions to ``slip_control/state``, ``sim/state`` and
    ``/diagnostics`` for the whole run (into a `RunRecord`)."""

    def __init__(self, node: Node, record: RunRecord) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from slip_msgs.msg import SimState, SlipControllerState
        keep_all = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                              reliability=ReliabilityPolicy.RELIABLE,
                              durability=DurabilityPolicy.VOLATILE)
        latched = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                             reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        node.create_subscription(SlipControllerState, names.SLIP_CONTROLLER_STATE,
                                 record.add_state, latched)
        node.create_subscription(SimState, names.SIM_STATE, record.add_sim, keep_all)
        node.create_subscription(DiagnosticArray, names.DIAGNOSTICS, record.add_diagnostics,
                                 keep_all)


def judge_run(record: RunRecord, metrics: dict[str, Any], mode: str, distance: float,
              angle: float, tolerances: Tolerances, runner_success: bool, runner_message: str,
              rtf_target: float, duration: float = 0.0) -> DemoVerdict:
    """Trajectories from the controller's state changes, the simulator's truth over each one
    and its settling, the analysis of each tracked segment, the diagnostics: the verdict."""
    t = sorted(record.sim)
    x, y, th = ([record.sim[k][i] for k in t] for i in range(3))
    last_t = t[-1] if t else 0.0
    trajectories = []
    for traj in trajectories_from_states(sorted(record.states)):
        t0, t1 = truth_window(traj, last_t)
        truth = object_motion(traj.mode, t, x, y, th, t0, t1)
        seg = next((s for s in metrics.get('slip', []) if s.get('mode') == traj.mode
                    and traj.t_start - 0.1 <= s.get('t_start', -1.0) <=
                    (traj.t_end if traj.t_end is not None else last_t) + 0.1), None)
        controller = sensors = None
        if seg is not None:
            controller = seg.get('final_measured')
            sensors = ((seg.get('sensor_slip') or {}).get('signed') if traj.mode == 'linear'
                       else seg.get('sensor_angle'))
        trajectories.append(Trajectory(traj.mode, traj.t_start, traj.t_end, traj.outcome,
                                       controller, sensors, truth))
    rtf = realtime_factor((record.sim[k][3] for k in t), rtf_target)
    return build_verdict(demo_targets(mode, distance, angle, duration), trajectories,
                         tolerances, runner_success, runner_message,
                         worst_diagnostics(record.diagnostics), rtf)


def _overrides(pairs: list[str]) -> dict[str, dict[str, Any]]:
    """``['slip_controller.trajectory.contact_lost_force=9.0']`` → per-node values."""
    out: dict[str, dict[str, Any]] = {}
    for pair in pairs:
        key, sep, text = pair.partition('=')
        node, dot, param = key.partition('.')
        if not (sep and dot and node and param):
            raise ValueError(f'--set {pair!r}: expected NODE.PARAM=VALUE')
        out.setdefault(node, {})[param] = yaml.safe_load(text)
    return out


def _run_experiment(node: Node, executor: SingleThreadedExecutor, mode: str, recording: str,
                    timeout_s: float, **goal: float) -> Any:
    from slip_msgs.action import RunExperiment
    client = ActionClient(node, RunExperiment, names.EXPERIMENT_RUN_ACTION)
    if not spin_until(executor, client.server_is_ready, 60.0):
        raise RuntimeError(f'{names.EXPERIMENT_RUN_ACTION} did not come up within 60 s')
    last_phase = ['']

    def feedback(msg: Any) -> None:
        phase = msg.feedback.phase
        if phase != last_phase[0]:
            last_phase[0] = phase
            _say(f'  {msg.feedback.elapsed:6.1f} s  {phase}')
    send = client.send_goal_async(RunExperiment.Goal(mode=mode, recording_name=recording,
                                                     **goal),
                                  feedback_callback=feedback)
    if not spin_until(executor, send.done, 30.0) or not send.result().accepted:
        raise RuntimeError(f'experiment {mode!r} was not accepted')
    result = send.result().get_result_async()
    if not spin_until(executor, result.done, timeout_s):
        raise RuntimeError(f'experiment {mode!r} did not finish within {timeout_s:.0f} s')
    return result.result().result


def main(argv: list[str] | None = None) -> int:
    """Run the demo; exit code 0 only when the runner and every slip segment succeeded."""
    parser = argparse.ArgumentParser(prog='slip_demo', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--out', default=str(default_data_directory() / 'demo' /
                                             datetime.now().strftime('%Y%m%d_%H%M%S')),
                        help='output directory (bag, metrics, plots, logs); default '
                             '$SLIP_DATA_DIR/demo/<time> or ~/.local/share/slip_cell/demo/<time>')
    parser.add_argument('--mode', default='demo', help='runner mode (default: demo)')
    parser.add_argument('--preset', default='', help='object preset of the simulator')
    parser.add_argument('--realtime-factor', type=float, default=1.0)
    parser.add_argument('--timeout', type=float, default=240.0,
                        help='experiment timeout [s, wall clock]')
    parser.add_argument('--distance', type=float, default=0.0,
                        help='linear slip target [m] (0: the demo default, 0.02)')
    parser.add_argument('--angle', type=float, default=0.0,
                        help='rotational slip target [deg] (0: the demo default, 20)')
    parser.add_argument('--duration', type=float, default=0.0,
                        help='slip duration [s] (0: the demo default, 2)')
    default_tol = Tolerances()
    parser.add_argument('--linear-tolerance', type=float, default=default_tol.linear * 1e3,
                        help='largest miss of the true object slide vs its target [mm] '
                             '(default %(default).1f)')
    parser.add_argument('--angle-tolerance', type=float,
                        default=math.degrees(default_tol.angle),
                        help='largest miss of the true object rotation vs its target [deg] '
                             '(default %(default).1f)')
    parser.add_argument('--set', action='append', default=[], metavar='NODE.PARAM=VALUE',
                        help='override one parameter of one node of the graph (repeatable; '
                             'VALUE is YAML); a test hook, e.g. to inject a fault')
    ns = parser.parse_args(argv)
    tolerances = Tolerances(linear=ns.linear_tolerance * 1e-3,
                            angle=math.radians(ns.angle_tolerance))
    try:
        overrides = _overrides(ns.set)
    except ValueError as exc:
        print(f'slip_demo: error: {exc}', file=sys.stderr)
        return 2
    out = Path(ns.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    started = time.monotonic()
    graph_path = _prefix('slip_bringup') / 'share' / 'slip_bringup' / 'config' / \
        'sim_cell.graph.yaml'
    sim_values: dict[str, Any] = {'realtime_factor': float(ns.realtime_factor)}
    if ns.preset:
        sim_values['preset'] = ns.preset
    try:
        values = {'sim_gripper': sim_values,
                  'experiment_runner': {'recording.directory': str(out),
                                        'recording.topics': list(RECORD_EVERY_TOPIC)}}
        for name, extra in overrides.items():
            values.setdefault(name, {}).update(extra)
        graph = load_graph(graph_path)
        unknown = sorted(set(overrides) - {n.name for n in graph.nodes})
        if unknown:
            raise GraphError(f'--set names node(s) not in the graph: {", ".join(unknown)}')
        runner = GraphRunner(graph, out / 'logs', overrides=values)
    except GraphError as exc:
        print(f'slip_demo: error: {exc}', file=sys.stderr)
        return 2
    _say(f'starting the simulated cell ({", ".join(n.name for n in runner.graph.nodes)}); '
         f'ROS_DOMAIN_ID={os.environ.get("ROS_DOMAIN_ID")}, logs in {out / "logs"}')
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = Node('slip_demo')
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    record = RunRecord()
    RunMonitor(node, record)
    code = 1
    result = None
    try:
        runner.start()
        _say(f'running experiment {ns.mode!r} (recording every topic)')
        result = _run_experiment(node, executor, ns.mode, 'demo', ns.timeout,
                                 distance=float(ns.distance), angle=math.radians(ns.angle),
                                 duration=float(ns.duration))
        _say(f'experiment finished: success={result.success} {result.message}')
        code = 0 if result.success else 1
        # The truth of the last segment is read to its settling end: wait for that sim/state.
        ends = [truth_window(tr, math.inf)[1]
                for tr in trajectories_from_states(sorted(record.states))]
        if ends and math.isfinite(ends[-1]):
            spin_until(executor, lambda: record.last_sim_t() >= ends[-1], 10.0)
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
        verdict = None
        metrics: dict[str, Any] = {}
        plots: list[Path] = []
        try:
            metrics, plots = analysis_report(bag, out,
                                             progress=lambda text: _say(f'analysis: {text}'))
            record.add_bag(bag)
            verdict = judge_run(record, metrics, ns.mode, ns.distance, math.radians(ns.angle),
                                tolerances, bool(result.success), str(result.message),
                                float(ns.realtime_factor), float(ns.duration))
        except BagError as exc:
            _say(f'FAILED: cannot judge the run from its bag: {exc}')
            code = code or 1
        if verdict is not None and not verdict.ok and code == 0:
            code = 1
        print(summary(metrics, verdict, tolerances))
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
