"""``run_graph``: bring up a graph of nodes as processes without ``ros2 launch``.

A graph file (YAML) names the nodes, their executables and parameter files::

    use_sim_time: true
    nodes:
      - name: sim_gripper
        package: friction_models
        executable: sim_gripper
        params: [slip_gripper_driver/config/cell.yaml, friction_models/config/sim_gripper.yaml]
        args: []            # extra --ros-args, e.g. ['-p', 'seed:=3']

Parameter files are ``<package>/<path inside the package's share directory>`` or absolute
paths. Each node runs in its own process group; SIGINT/SIGTERM to the runner stops every node
with SIGINT, then SIGKILL after ``--stop-timeout``. When a node exits on its own, the runner
stops the others and exits non-zero.

The same graphs exist as launch files (``slip_bringup/launch/*.launch.py``) for full installs.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from collections.abc import Sequence

import yaml

from slip_cell_common.core.cli_args import Parser, non_negative_float, plain_doc, positive_float


class GraphError(RuntimeError):
    """A graph file is invalid or a node cannot be started; the message says which."""


@dataclass(frozen=True)
class NodeSpec:
    """One node of a graph."""

    name: str
    package: str
    executable: str
    params: tuple[str, ...] = ()
    args: tuple[str, ...] = ()


@dataclass(frozen=True)
class GraphSpec:
    """A set of nodes and graph-wide settings."""

    nodes: tuple[NodeSpec, ...]
    use_sim_time: bool = False
    overrides: dict[str, dict[str, Any]] = field(default_factory=dict)


def _prefix(package: str) -> Path:
    from ament_index_python.packages import PackageNotFoundError, get_package_prefix
    try:
        return Path(get_package_prefix(package))
    except PackageNotFoundError:
        raise GraphError(f'package {package!r} is not installed (source install/setup.bash)') \
            from None


def resolve_params_file(ref: str) -> Path:
    """``pkg/rel/path.yaml`` → the installed file in the package's share directory."""
    path = Path(ref)
    if path.is_absolute():
        if not path.is_file():
            raise GraphError(f'parameter file {path} does not exist')
        return path
    package, _, rel = ref.partition('/')
    resolved = _prefix(package) / 'share' / package / rel
    if not resolved.is_file():
        raise GraphError(f'parameter file {ref!r} not found at {resolved}')
    return resolved


def executable_path(package: str, executable: str) -> Path:
    """Installed console script ``<prefix>/lib/<package>/<executable>``."""
    path = _prefix(package) / 'lib' / package / executable
    if not os.access(path, os.X_OK):
        raise GraphError(f'executable {executable!r} of package {package!r} not found at {path}')
    return path


def load_graph(path: Path | str) -> GraphSpec:
    """Parse and check a graph file (every problem raises GraphError naming the file)."""
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise GraphError(f'cannot read graph file {path}: {exc}') from exc
    if not isinstance(data, dict) or not isinstance(data.get('nodes'), list):
        raise GraphError(f'graph file {path}: expected a mapping with a "nodes" list')
    nodes = []
    for i, item in enumerate(data['nodes']):
        missing = {'name', 'package', 'executable'} - set(item or {})
        if missing:
            raise GraphError(f'graph file {path}: node {i} lacks {sorted(missing)}')
        nodes.append(NodeSpec(str(item['name']), str(item['package']), str(item['executable']),
                              tuple(item.get('params', ())), tuple(map(str, item.get('args', ())))))
    names = [n.name for n in nodes]
    if len(set(names)) != len(names):
        raise GraphError(f'graph file {path}: duplicate node names in {names}')
    return GraphSpec(tuple(nodes), bool(data.get('use_sim_time', False)))


def node_command(spec: NodeSpec, use_sim_time: bool, extra: Sequence[str] = ()) -> list[str]:
    """Command line that starts one node with its parameter files."""
    cmd = [str(executable_path(spec.package, spec.executable)), '--ros-args',
           '-r', f'__node:={spec.name}']
    for ref in spec.params:
        cmd += ['--params-file', str(resolve_params_file(ref))]
    if use_sim_time:
        cmd += ['-p', 'use_sim_time:=true']
    return cmd + list(spec.args) + list(extra)


def _check_environment() -> None:
    if os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE') != 'LOCALHOST':
        raise GraphError('refusing to start nodes without ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST '
                         '(use tools/run_ros.sh, or export it for a networked cell)')


class GraphRunner:
    """Starts a graph's nodes as child processes and stops them cleanly.

    Args:
        graph: The nodes to run.
        log_dir: Each node's output goes to ``<log_dir>/<name>.log``.
        extra_args: Per-node extra ``--ros-args`` (remappings and the like).
        overrides: Per-node parameter values (``{'sim_gripper': {'seed': 2}}``), written to a
            parameter file keyed by the node name and passed last. (``-p name:=value`` is a
            ``/**`` wildcard, which node-specific keys of the packages' YAML files take
            precedence over, so it cannot override them.)
        stop_timeout_s: Time between SIGINT and SIGKILL.
    """

    def __init__(self, graph: GraphSpec, log_dir: Path | str,
                 extra_args: dict[str, Sequence[str]] | None = None,
                 overrides: dict[str, dict[str, Any]] | None = None,
                 stop_timeout_s: float = 8.0, env: dict[str, str] | None = None,
                 check_localhost: bool = True) -> None:
        if check_localhost:
            _check_environment()
        self.graph = graph
        self.log_dir = Path(log_dir)
        self.log_dir.mkdir(parents=True, exist_ok=True)
        self.stop_timeout_s = stop_timeout_s
        self._env = dict(env if env is not None else os.environ)
        self._env.setdefault('PYTHONUNBUFFERED', '1')
        self._extra = {name: list(args) for name, args in (extra_args or {}).items()}
        for name, values in (overrides or {}).items():
            path = self.log_dir / f'{name}.overrides.yaml'
            path.write_text(yaml.safe_dump({name: {'ros__parameters': dict(values)}}))
            self._extra.setdefault(name, []).extend(['--params-file', str(path)])
        self.procs: dict[str, subprocess.Popen[bytes]] = {}
        self._logs: dict[str, Any] = {}

    def start(self) -> None:
        """Start every node (commands are resolved first, so a bad graph starts nothing)."""
        commands = {n.name: node_command(n, self.graph.use_sim_time, self._extra.get(n.name, ()))
                    for n in self.graph.nodes}
        for name, cmd in commands.items():
            log = open(self.log_dir / f'{name}.log', 'wb')
            self._logs[name] = log
            self.procs[name] = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT,
                                                env=self._env, start_new_session=True)

    def exited(self) -> dict[str, int]:
        """Nodes that have exited, with their exit codes."""
        return {n: p.returncode for n, p in self.procs.items() if p.poll() is not None}

    def stop(self) -> dict[str, int]:
        """SIGINT every node, wait, SIGKILL stragglers' process groups; returns exit codes."""
        for proc in self.procs.values():
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
        deadline = time.monotonic() + self.stop_timeout_s
        for proc in self.procs.values():
            try:
                proc.wait(timeout=max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(timeout=5.0)
        for log in self._logs.values():
            log.close()
        return {n: p.returncode for n, p in self.procs.items()}

    def log(self, name: str) -> str:
        """A node's output so far."""
        return (self.log_dir / f'{name}.log').read_text(errors='replace')


class _Stop(Exception):
    pass


def main(argv: list[str] | None = None) -> int:
    """Console script ``run_graph``."""
    parser = Parser(prog='run_graph', description=plain_doc(__doc__))
    graph = parser.add_mutually_exclusive_group()
    graph.add_argument('--sim', action='store_true',
                       help='the simulated cell, config/sim_cell.graph.yaml (the default graph)')
    graph.add_argument('--hardware', action='store_true',
                       help='the hardware cell, config/hardware_cell.graph.yaml')
    graph.add_argument('--config', metavar='FILE',
                       help='a graph YAML of your own (default: the --sim graph)')
    parser.add_argument('--duration', type=non_negative_float, default=0.0, metavar='S',
                        help='stop the graph after S seconds (0 = run until Ctrl-C)')
    parser.add_argument('--log-dir', metavar='DIR', default=os.path.join(
        os.environ.get('ROS_LOG_DIR', '/tmp'), 'run_graph'),
        help='directory for one <node>.log per node ($ROS_LOG_DIR/run_graph)')
    parser.add_argument('--stop-timeout', type=positive_float, default=8.0, metavar='S',
                        help='after SIGINT, wait this long [s] for each node before SIGKILL')
    ns = parser.parse_args(argv)
    if ns.config:
        config = Path(ns.config)
    else:
        name = 'hardware_cell.graph.yaml' if ns.hardware else 'sim_cell.graph.yaml'
        config = _prefix('slip_bringup') / 'share' / 'slip_bringup' / 'config' / name
    try:
        runner = GraphRunner(load_graph(config), ns.log_dir, stop_timeout_s=ns.stop_timeout)
        runner.start()
    except GraphError as exc:
        print(f'run_graph: error: {exc}', file=sys.stderr)
        return 2

    def _raise(signum: int, frame: object) -> None:
        raise _Stop

    signal.signal(signal.SIGINT, _raise)
    signal.signal(signal.SIGTERM, _raise)
    print(f'run_graph: started {", ".join(runner.procs)}; logs in {ns.log_dir}', flush=True)
    code = 0
    start = time.monotonic()
    try:
        while not ns.duration or time.monotonic() - start < ns.duration:
            exited = runner.exited()
            if exited:
                print(f'run_graph: node(s) exited: {exited}; stopping the graph', file=sys.stderr)
                code = 1
                break
            time.sleep(0.1)
    except _Stop:
        pass
    finally:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        codes = runner.stop()
        print(f'run_graph: stopped, exit codes {codes}', flush=True)
    return code


if __name__ == '__main__':
    sys.exit(main())
