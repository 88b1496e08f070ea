"""docs/foxglove/slip_cell_layout.json fits our bags: every panel placed, every plot path real.

The layout is Foxglove's importable format (``configById`` + mosaic ``layout``). Each plotted
path must name a topic of a recorded bag and a numeric field of that topic's message type,
so the layout shows data when it opens any of the bags in ``bags/``.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[1]
LAYOUT = ROOT / 'docs' / 'foxglove' / 'slip_cell_layout.json'
BAG = ROOT / 'bags' / 'linear_slip'


def _leaves(node: Any) -> list[str]:
    if isinstance(node, str):
        return [node]
    assert set(node) >= {'direction', 'first', 'second'}, node
    assert node['direction'] in ('row', 'column')
    return _leaves(node['first']) + _leaves(node['second'])


def test_layout_structure() -> None:
    layout = json.loads(LAYOUT.read_text())
    assert set(layout) >= {'configById', 'layout', 'globalVariables', 'userNodes',
                           'playbackConfig'}
    leaves = _leaves(layout['layout'])
    assert sorted(leaves) == sorted(layout['configById']), 'every panel placed exactly once'
    kinds = [panel.split('!')[0] for panel in leaves]
    assert kinds.count('3D') == 1 and kinds.count('Plot') >= 4
    scene = layout['configById']['3D!scene']
    assert scene['followTf'] == 'gripper_base_link'
    assert scene['topics']['/robot_description']['visible']


def test_scene_shows_the_cells_marker_topics() -> None:
    from slip_cell_common.core import names
    scene = json.loads(LAYOUT.read_text())['configById']['3D!scene']
    for topic in (names.CELL_MARKERS, names.SIM_MARKERS, names.SIM_OBJECT_POSE):
        assert scene['topics'][names.absolute(topic)]['visible'], topic


def _field_type(msg: Any, path: list[str]) -> Any:
    value = msg
    for name in path:
        assert name in value.get_fields_and_field_types(), \
            f'{type(value).__name__} has no field {name!r}'
        value = getattr(value, name)
    return value


@pytest.mark.ros
def test_every_plotted_path_is_a_numeric_field_of_a_recorded_topic() -> None:
    from slip_cell_common.bag_io import bag_info
    from slip_cell_common.recorder import import_message_type
    layout = json.loads(LAYOUT.read_text())
    types = {t.name: t.msgtype for t in bag_info(BAG).topics}
    plotted: set[str] = set()
    for panel, config in layout['configById'].items():
        if not panel.startswith('Plot!'):
            continue
        for series in config['paths']:
            topic, *fields = series['value'].split('.')
            assert topic in types, f'{panel}: {topic} is not in the bags'
            msg = import_message_type(types[topic])()
            value = _field_type(msg, fields)
            assert isinstance(value, float), f'{series["value"]} is not a number'
            if series['timestampMethod'] == 'headerStamp':
                assert hasattr(msg, 'header'), f'{topic} has no header stamp'
            plotted.add(series['value'])
    assert {'/gripper/motor_command.force_target', '/gripper/motor_command.measured_force',
            '/slip_control/tracking.ref_pos', '/slip_control/tracking.meas_pos',
            '/finger_1/slip/twist.twist.linear.x', '/finger_2/slip/twist.twist.angular.z'} \
        <= plotted
