"""run_graph: installed console-script nodes as processes with parameter files, clean stop."""
from __future__ import annotations

import time
from pathlib import Path

import pytest
import yaml
from support.sample_bags import write_sample_bag

pytestmark = pytest.mark.ros


def _params(path: Path, node: str, values: dict) -> str:
    path.write_text(yaml.safe_dump({node: {'ros__parameters': values}}))
    return str(path)


def test_graph_of_installed_nodes_replays_into_a_recorder(ros_env, tmp_path: Path) -> None:
    from slip_cell_common.bag_io import bag_info
    from slip_bringup.run_graph import GraphRunner, load_graph
    source = tmp_path / 'source'
    write_sample_bag(source, n=1500)  # 3 s at 500 Hz
    out = tmp_path / 'recorded'
    graph_file = tmp_path / 'graph.yaml'
    graph_file.write_text(yaml.safe_dump({'nodes': [
        {'name': 'recorder', 'package': 'slip_bringup', 'executable': 'bag_recorder',
         'params': [_params(tmp_path / 'rec.yaml', 'recorder',
                            {'output': str(out), 'topics': ['gripper/status', 'contact/*']})]},
        {'name': 'player', 'package': 'slip_bringup', 'executable': 'bag_replay',
         'params': [_params(tmp_path / 'play.yaml', 'player',
                            {'bag': str(source), 'start_delay': 20.0,
                             'exit_when_done': False})]},
    ]}))
    runner = GraphRunner(load_graph(graph_file), tmp_path / 'logs', env=ros_env)
    runner.start()
    try:
        deadline = time.monotonic() + 40.0
        while time.monotonic() < deadline and 'replay finished' not in runner.log('player'):
            time.sleep(0.1)
        assert runner.exited() == {}, runner.log('player') + runner.log('recorder')
    finally:
        codes = runner.stop()
    assert codes == {'recorder': 0, 'player': 0}, runner.log('recorder') + runner.log('player')
    counts = {t.name: t.count for t in bag_info(out).topics}
    assert counts.get('/gripper/status', 0) > 1000, (counts, runner.log('recorder'))


def test_bad_graphs_fail_before_starting_anything(ros_env, tmp_path: Path) -> None:
    from slip_bringup.run_graph import GraphError, GraphRunner, load_graph, main
    bad = tmp_path / 'bad.yaml'
    bad.write_text('nodes:\n  - name: a\n    package: slip_control\n')
    with pytest.raises(GraphError, match="lacks \\['executable'\\]"):
        load_graph(bad)
    missing = tmp_path / 'missing.yaml'
    missing.write_text(yaml.safe_dump({'nodes': [
        {'name': 'a', 'package': 'slip_bringup', 'executable': 'bag_recorder',
         'params': ['slip_control/config/does_not_exist.yaml']},
        {'name': 'b', 'package': 'no_such_package', 'executable': 'x'}]}))
    runner = GraphRunner(load_graph(missing), tmp_path / 'logs', env=ros_env)
    with pytest.raises(GraphError, match='does_not_exist.yaml'):
        runner.start()
    assert runner.procs == {}
    assert main(['--config', str(bad)]) == 2
