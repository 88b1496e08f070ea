"""``make bags``: record the reference experiments of ``bags/`` through the real node graph.

Each experiment starts the simulated-cell graph as separate processes (``run_graph``), brings
the cell to the experiment's starting condition with experiment-runner sequences that are not
recorded, then runs the recorded sequence (the runner records in-process), and stops the graph.
Bags are MCAP with zstd chunk compression. ``bags/README.md`` is regenerated with the topics,
durations, message counts and conditions of every bag.

    tools/run_ros.sh python -m slip_bringup.make_bags --output bags [--only linear_slip]
"""
from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import rclpy
from rclpy.action import ActionClient
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from slip_bringup.run_graph import GraphRunner, _prefix, load_graph
from slip_cell_common.bag_io import bag_info
from slip_cell_common.calls import call_service, spin_until
from slip_cell_common.core import names


@dataclass(frozen=True)
class Disturbance:
    """An external push on the object during a recording (``sim/apply_disturbance``)."""

    at: float          # [s] after the recorded sequence started (wall time of the runner)
    fx: float          # [N] gripper_middle
    fy: float          # [N]
    torque: float      # [N·m]
    duration: float    # [s]


@dataclass(frozen=True)
class Experiment:
    """One recorded experiment."""

    name: str
    description: str
    preset: str
    setup: tuple[str, ...]             # runner modes run first (not recorded)
    mode: str                          # recorded runner mode
    duration: float = 0.0
    distance: float = 0.0
    angle: float = 0.0
    disturbances: tuple[Disturbance, ...] = ()
    overrides: dict[str, dict[str, Any]] = field(default_factory=dict)


#: Brings the cell to the pick-up pose with the gripper open and biased (not recorded).
PREAMBLE = ('reset_joints', 'release', 'go_to_object')

EXPERIMENTS: tuple[Experiment, ...] = (
    Experiment('force_tracking', 'force-tracking profile: steps 5-25 N and sines 1-64 Hz '
               '(control_and_estimation §5.4), object held in the air; the topics of §5.4 only',
               'cardboard', ('est_contact', 'grasp'), 'force_tracking_test',
               overrides={'experiment_runner': {'recording.topics': [
                   names.GRASP_FORCE_CMD, names.MOTOR_COMMAND, names.ft_wrench(1),
                   names.DIAGNOSTICS]}}),
    Experiment('est_contact_cardboard', 'contact estimation (push 1 cm down, twist ±10° on '
               'the table), cardboard box', 'cardboard', (), 'est_contact'),
    Experiment('est_contact_plastic', 'contact estimation, plastic object', 'plastic', (),
               'est_contact'),
    Experiment('hold_disturbance', 'slip avoidance (HOLD) for 6 s with pushes and a twist',
               'cardboard', ('est_contact', 'grasp', 'pick_up_object'), 'hold_mode', duration=6.0,
               disturbances=(Disturbance(1.0, 0.0, -2.0, 0.0, 0.3),
                             Disturbance(2.5, 1.5, 0.0, 0.0, 0.3),
                             Disturbance(4.0, 0.0, 0.0, 0.02, 0.3))),
    Experiment('linear_slip', 'linear slip 0.02 m in 2 s', 'cardboard',
               ('est_contact', 'grasp', 'pick_up_object'), 'linear_slippage', duration=2.0,
               distance=0.02),
    Experiment('rotational_slip', 'rotational slip 0.349 rad (20°) in 2 s, starting with the '
               'object held 90° from vertical so that gravity turns it (the presets hang only '
               '1 cm below the grasp point; from 60° the torque falls short)',
               'cardboard', ('est_contact', 'grasp', 'pick_up_object', 'go_to_hinge_pose'),
               'rotational_slippage', duration=2.0, angle=0.3490659,
               overrides={'experiment_runner': {'hinge.start_angle': 1.5707963}}),
    Experiment('hinge', 'hinge: the gripper turns 60° about the grasp axis around the hanging '
               'object', 'cardboard',
               ('est_contact', 'grasp', 'pick_up_object', 'go_to_hinge_pose'),
               'hinge_mode'),
)


def _say(text: str) -> None:
    print(f'[bags {time.strftime("%H:%M:%S")}] {text}', flush=True)


class _Client:
    def __init__(self) -> None:
        from slip_msgs.action import RunExperiment
        self.node = Node('make_bags')
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.action = ActionClient(self.node, RunExperiment, names.EXPERIMENT_RUN_ACTION)
        self.goal_type = RunExperiment.Goal

    def run(self, mode: str, record: str = '', timeout_s: float = 300.0,
            duration: float = 0.0, distance: float = 0.0, angle: float = 0.0,
            disturbances: tuple[Disturbance, ...] = ()) -> Any:
        if not spin_until(self.executor, self.action.server_is_ready, 60.0):
            raise RuntimeError('experiment/run is not available')
        send = self.action.send_goal_async(self.goal_type(
            mode=mode, duration=duration, distance=distance, angle=angle,
            recording_name=record))
        if not spin_until(self.executor, send.done, 30.0) or not send.result().accepted:
            raise RuntimeError(f'{mode}: goal not accepted')
        result = send.result().get_result_async()
        start = time.monotonic()
        pending = sorted(disturbances, key=lambda d: d.at)
        while not result.done() and time.monotonic() - start < timeout_s:
            self.executor.spin_once(timeout_sec=0.01)
            if pending and time.monotonic() - start >= pending[0].at:
                self._disturb(pending.pop(0))
        if not result.done():
            raise RuntimeError(f'{mode}: no result within {timeout_s:.0f} s')
        res = result.result().result
        if not res.success:
            raise RuntimeError(f'{mode}: {res.message}')
        return res

    def _disturb(self, d: Disturbance) -> None:
        from slip_msgs.srv import ApplyDisturbance
        req = ApplyDisturbance.Request(torque=d.torque, duration=d.duration)
        req.force.x, req.force.y = d.fx, d.fy
        res = call_service(self.executor, self.node.create_client(
            ApplyDisturbance, names.SIM_APPLY_DISTURBANCE_SRV), req, 10.0)
        if res is None or not res.success:
            raise RuntimeError(f'disturbance failed: {res.message if res else "no answer"}')

    def close(self) -> None:
        self.action.destroy()
        self.executor.shutdown()
        self.node.destroy_node()


def record(exp: Experiment, output: Path, work: Path, realtime_factor: float) -> Path:
    """Run one experiment through the graph; returns the bag path inside ``output``."""
    graph = load_graph(_prefix('slip_bringup') / 'share' / 'slip_bringup' / 'config' /
                       'sim_cell.graph.yaml')
    overrides: dict[str, dict[str, Any]] = {
        'sim_gripper': {'preset': exp.preset, 'realtime_factor': realtime_factor},
        'experiment_runner': {'recording.directory': str(work)}}
    for node, values in exp.overrides.items():
        overrides.setdefault(node, {}).update(values)
    runner = GraphRunner(graph, work / 'logs', overrides=overrides)
    client = _Client()
    try:
        runner.start()
        for mode in PREAMBLE + exp.setup:
            _say(f'{exp.name}: {mode}')
            client.run(mode)
        _say(f'{exp.name}: {exp.mode} (recording)')
        res = client.run(exp.mode, record=exp.name, duration=exp.duration,
                         distance=exp.distance, angle=exp.angle,
                         disturbances=exp.disturbances)
    finally:
        client.close()
        codes = runner.stop()
        _say(f'{exp.name}: graph stopped {codes}')
    bag = Path(res.bag_path)
    target = output / exp.name
    if target.exists():
        shutil.rmtree(target)
    shutil.move(str(bag), target)
    return target


def write_readme(output: Path) -> None:
    """bags/README.md: one section per bag with topics, duration, counts and conditions."""
    lines = ['# Recorded experiments', '',
             'Recorded from the simulated cell through the real node graph (sim_gripper, '
             'contact_estimator, slip_controller, experiment_runner as separate processes, '
             'simulated time) by `make bags` (`python -m slip_bringup.make_bags`). rosbag2 '
             'version 9, MCAP storage with zstd chunk compression, CDR; readable with '
             '`slip_bag info <bag>`, `slip_analyze <bag>`, and `ros2 bag info` on a full install. '
             'The tests in `tests/test_bag_replay.py` replay them.', '']
    for exp in EXPERIMENTS:
        path = output / exp.name
        if not path.exists():
            continue
        info = bag_info(path)
        size = sum(f.stat().st_size for f in path.iterdir()) / 1e6
        args = ', '.join(f'{k} {v}' for k, v in (('duration', exp.duration),
                                                  ('distance', exp.distance),
                                                  ('angle', exp.angle)) if v)
        lines += [f'## {exp.name}', '', f'{exp.description}.', '',
                  f'* object preset: `{exp.preset}`; set-up (not recorded): '
                  f'{", ".join(PREAMBLE + exp.setup)}; recorded runner mode: `{exp.mode}`'
                  + (f' ({args})' if args else ''),
                  f'* duration {info.duration_s:.1f} s (sim time), {info.message_count} '
                  f'messages, {size:.2f} MB', '', '| topic | type | messages |', '|---|---|---|']
        lines += [f'| `{t.name}` | `{t.msgtype}` | {t.count} |' for t in info.topics]
        lines.append('')
    (output / 'README.md').write_text('\n'.join(lines))


def main(argv: list[str] | None = None) -> int:
    """Record every (or the selected) experiment into ``--output``."""
    parser = argparse.ArgumentParser(prog='make_bags', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--output', required=True,
                        help="directory of the reference bags (`make bags` passes the "
                             "repository's bags/); no default, so nothing lands in a working "
                             'directory by accident')
    parser.add_argument('--only', action='append', help='experiment name (repeatable)')
    parser.add_argument('--realtime-factor', type=float, default=1.0)
    ns = parser.parse_args(argv)
    output = Path(ns.output).resolve()
    output.mkdir(parents=True, exist_ok=True)
    chosen = [e for e in EXPERIMENTS if not ns.only or e.name in ns.only]
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    failed = []
    try:
        for exp in chosen:
            with tempfile.TemporaryDirectory(prefix=f'bag_{exp.name}_') as tmp:
                try:
                    path = record(exp, output, Path(tmp), ns.realtime_factor)
                    _say(f'{exp.name}: {path} ({bag_info(path).message_count} messages)')
                except RuntimeError as exc:
                    _say(f'{exp.name}: FAILED: {exc}')
                    failed.append(exp.name)
    finally:
        rclpy.try_shutdown()
    write_readme(output)
    _say(f'bags/README.md written; failed: {failed or "none"}')
    return 1 if failed else 0


if __name__ == '__main__':
    sys.exit(main())
