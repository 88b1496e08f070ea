"""Adding an object needs no code: a YAML entry is simulated and evaluated as it is.

A new object written in a temporary presets file is grasped and lifted by the simulated cell
(`friction_models.core`), and the evaluation (`slip_evaluate`'s core, with ``presets_file``)
explores it and estimates its contact — without a line of Python naming it.
"""
from __future__ import annotations

from pathlib import Path

import pytest

from friction_models.core.harness import Harness
from friction_models.core.presets import load_presets, reference_presets
from friction_models.core.sim_cell import SimCell, SimParams
from slip_bringup.core.evaluation.estimation import estimate
from slip_bringup.core.evaluation.settings import EvalSettings

JAR = '''
presets:
  glass_jar:                 # not a reference object, nowhere in the code
    mass: 0.10
    width: 0.065
    height_below: 0.070
    height_above: 0.050
    thickness: 0.055
    finger_1: {mu_c: 0.30, mu_s: 0.33, mu_v: 0.5, r: 0.0055}
    finger_2: {mu_c: 0.34, mu_s: 0.36, mu_v: 0.5, r: 0.0065}
'''


@pytest.fixture()
def presets_file(tmp_path: Path) -> Path:
    path = tmp_path / 'my_objects.yaml'
    path.write_text(JAR)
    return path


def test_a_yaml_object_joins_the_reference_objects(presets_file: Path) -> None:
    presets = load_presets(presets_file)
    assert set(presets) == {'glass_jar', *reference_presets()}
    jar = presets['glass_jar']
    assert (jar.finger_1.mu_c, jar.finger_2.r, jar.surface) == (0.30, 0.0065, 'circle')


def test_the_simulated_cell_grasps_and_lifts_a_yaml_object(presets_file: Path) -> None:
    cell = SimCell(SimParams(physics_dt=1e-3), load_presets(presets_file), 'glass_jar')
    assert cell.preset.name == 'glass_jar'
    assert [c.mu_c for c in cell.true_contact()] == pytest.approx([0.30, 0.34])
    h = Harness(cell)
    h.home()
    h.bias()
    h.command_force(10.0)
    h.run_for(1.0)
    h.move(lift=0.10, duration=0.5)
    h.run_for(0.5)
    s = h.state()
    assert s.in_grasp and not s.dropped and not s.on_table and s.preset == 'glass_jar'
    assert s.normal_force_1 == pytest.approx(10.0, abs=1.0)


def test_the_evaluation_estimates_a_yaml_object(presets_file: Path) -> None:
    out = estimate('glass_jar', EvalSettings(presets_file=str(presets_file)))
    assert out.valid and not out.dropped
    for f, (mu_c, r) in zip(out.fingers, ((0.30, 0.0055), (0.34, 0.0065))):
        assert (f.mu_c_true, f.r_true) == (mu_c, r)
        assert f.mu_c == pytest.approx(mu_c, rel=0.1)
        assert f.r == pytest.approx(r, rel=0.25)


@pytest.mark.ros
@pytest.mark.slow
def test_the_sim_gripper_node_runs_an_object_from_a_presets_file(
        presets_file: Path, ros_context: object, ros_env: dict[str, str], tmp_path: Path) -> None:
    """The node's ``presets_file`` and ``preset`` parameters pick the new object."""
    import yaml
    from ament_index_python.packages import get_package_prefix, get_package_share_directory
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    from slip_cell_common.calls import spin_until
    from slip_cell_common.qos import LATCHED
    from slip_cell_common.testing import NodeProcess
    from slip_msgs.msg import ContactProperties

    overrides = tmp_path / 'overrides.yaml'
    overrides.write_text(yaml.safe_dump({'sim_gripper': {'ros__parameters': {
        'presets_file': str(presets_file), 'preset': 'glass_jar'}}}))
    share = Path(get_package_share_directory('friction_models'))
    cell = Path(get_package_share_directory('slip_gripper_driver')) / 'config' / 'cell.yaml'
    exe = Path(get_package_prefix('friction_models')) / 'lib' / 'friction_models' / 'sim_gripper'
    sim = NodeProcess([str(exe), '--ros-args', '--params-file', str(cell),
                       '--params-file', str(share / 'config' / 'sim_gripper.yaml'),
                       '--params-file', str(overrides)], tmp_path / 'sim.log', ros_env)
    node = Node('presets_probe', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    truth: list[ContactProperties] = []
    node.create_subscription(ContactProperties, 'sim/true_contact', truth.append, LATCHED)
    try:
        assert spin_until(executor, lambda: bool(truth), 60.0), sim.output()
        assert truth[-1].preset_name == 'glass_jar'
        assert truth[-1].finger_1.mu_c == pytest.approx(0.30)
        assert truth[-1].finger_2.r == pytest.approx(0.0065)
    finally:
        executor.shutdown()
        node.destroy_node()
        code = sim.stop()
    assert code == 0 and 'Traceback' not in sim.output(), sim.output()
