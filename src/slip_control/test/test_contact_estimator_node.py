# SPDX-License-Identifier: Apache-2.0
"""contact_estimator node through real DDS: synthetic sensor streams, sim time, latched output."""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from slip_control.core.synthetic import (StreamNoise, TrueContact, exploration_linear,
                                         exploration_rotational)

pytestmark = pytest.mark.ros

T0 = 100.0
TRUTH = (TrueContact(mu_c=0.45, r=0.006), TrueContact(mu_c=0.40, r=0.005))


def _estimator(harness, **params):
    from rclpy.parameter import Parameter
    from slip_control.contact_estimator_node import ContactEstimatorNode
    overrides = [Parameter('use_sim_time', value=True)]
    overrides += [Parameter(k, value=v) for k, v in params.items()]
    node = harness.add(ContactEstimatorNode(context=harness.context,
                                            parameter_overrides=overrides))
    harness.advance(T0)
    return node


def _latched_props(harness):
    from slip_cell_common.qos import LATCHED
    from slip_msgs.msg import ContactProperties
    return harness.collect(ContactProperties, 'contact/properties', LATCHED)


def _start(harness, phase: int, duration: float):
    from slip_msgs.srv import StartEstimation
    res = harness.call(StartEstimation, 'contact/start',
                       StartEstimation.Request(phase=phase, duration=duration))
    assert res is not None, 'contact/start did not answer'
    return res


def _get(harness):
    from slip_msgs.srv import GetContactProperties
    res = harness.call(GetContactProperties, 'contact/get_properties',
                       GetContactProperties.Request())
    assert res is not None, 'contact/get_properties did not answer'
    return res


def test_exploration_publishes_valid_properties_latched(harness) -> None:
    from slip_msgs.msg import ContactProperties
    from slip_msgs.srv import StartEstimation
    node = _estimator(harness)
    props = _latched_props(harness)
    assert harness.spin_until(lambda: len(props) >= 1)
    first = props[0]
    assert first.source == ContactProperties.SOURCE_DEFAULT and not first.valid

    # The pads hold the object (stick phase) before the phase starts: the precheck passes.
    lin = exploration_linear(TRUTH, t0=T0 + 0.005, seed=3)
    harness.play(lin[:1], node)
    res = _start(harness, StartEstimation.Request.LINEAR, 1.0)
    assert res.accepted, res.message
    harness.play(lin[1:], node)
    harness.advance(T0 + 1.1)                  # window over: the timer ends the phase
    assert harness.spin_until(lambda: len(props) >= 2)
    after_linear = props[-1]
    assert after_linear.source == ContactProperties.SOURCE_ESTIMATED
    assert after_linear.finger_1.linear_valid and after_linear.finger_2.linear_valid
    assert not after_linear.valid                       # no torsional radius yet
    assert math.isnan(after_linear.finger_1.r)          # not a placeholder number

    t1 = T0 + 1.2
    rot = exploration_rotational(TRUTH, t0=t1 + 0.005, seed=4)
    harness.advance(t1)
    harness.play(rot[:1], node)
    res = _start(harness, StartEstimation.Request.ROTATIONAL, 1.0)
    assert res.accepted, res.message
    harness.play(rot[1:], node)
    harness.advance(t1 + 1.1)
    assert harness.spin_until(lambda: len(props) >= 3)
    est = props[-1]
    assert est.valid and est.source == ContactProperties.SOURCE_ESTIMATED
    for f, truth in ((est.finger_1, TRUTH[0]), (est.finger_2, TRUTH[1])):
        assert f.mu_c == pytest.approx(truth.mu_c, abs=0.04)
        assert f.r == pytest.approx(truth.r, abs=0.001)
        assert f.n_linear >= 20 and f.n_rotational >= 20
        assert 0.0 < f.mu_c_std < 0.05 and 0.0 < f.r_std < 0.002
        assert f.linear_valid and f.rotational_valid

    late = _latched_props(harness)                     # a late joiner gets the last set
    assert harness.spin_until(lambda: len(late) >= 1)
    assert late[0].valid and late[0].finger_1.mu_c == est.finger_1.mu_c
    got = _get(harness)
    assert got.valid and got.properties.finger_2.r == est.finger_2.r
    assert 'succeeded' in got.message


def test_start_without_contact_fails_clearly_and_publishes_nothing(harness) -> None:
    from slip_msgs.msg import ContactProperties
    from slip_msgs.srv import StartEstimation
    node = _estimator(harness)
    props = _latched_props(harness)
    assert harness.spin_until(lambda: len(props) >= 1)

    res = _start(harness, StartEstimation.Request.LINEAR, 1.0)      # no sensor data at all
    assert not res.accepted
    assert 'no samples received yet' in res.message and 'finger_1/ft/wrench' in res.message

    # Open gripper: streams run, but the pads carry no normal force.
    free = exploration_linear(TRUTH, t0=T0 + 0.005, f_n=0.05,
                              noise=StreamNoise(force=0.001), seed=5)
    harness.play(free[:3], node)
    res = _start(harness, StartEstimation.Request.LINEAR, 1.0)
    assert not res.accepted
    assert 'no contact' in res.message and 'min_normal_force' in res.message

    # Contact lost right after a start: the phase fails, nothing is published, no defaults.
    touch = exploration_linear(TRUTH, t0=T0 + 0.05, seed=6)
    harness.play(touch[:1], node)
    res = _start(harness, StartEstimation.Request.LINEAR, 0.5)
    assert res.accepted, res.message
    harness.play([s for s in free if s.twist_1.stamp > harness.t][:40], node)
    harness.advance(harness.t + 0.6)
    got = _get(harness)
    assert not got.valid
    assert got.properties.source == ContactProperties.SOURCE_DEFAULT
    assert 'failed, properties unchanged' in got.message and 'no contact' in got.message
    harness.spin_for(0.2)
    assert len(props) == 1                             # only the initial DEFAULT set


def test_bad_start_requests_are_refused_with_reasons(harness) -> None:
    from slip_msgs.srv import StartEstimation
    node = _estimator(harness)
    harness.play(exploration_linear(TRUTH, t0=T0 + 0.005, seed=7)[:2], node)
    cases = [
        (StartEstimation.Request.LINEAR, math.nan, 'must be finite and > 0'),
        (StartEstimation.Request.LINEAR, -1.0, 'must be finite and > 0'),
        (StartEstimation.Request.LINEAR, math.inf, 'must be finite and > 0'),
        (StartEstimation.Request.LIMIT_SURFACE, 1.0, 'not implemented'),
        (9, 1.0, 'unknown phase 9'),
        (StartEstimation.Request.ROTATIONAL, 1.0, 'needs a valid LINEAR result'),
        (StartEstimation.Request.ONLINE, 0.0, 'ONLINE estimation is disabled'),
    ]
    for phase, duration, text in cases:
        res = _start(harness, phase, duration)
        assert not res.accepted and text in res.message, (phase, duration, res.message)


def test_preset_from_parameters_is_published_as_preset(harness, tmp_path: Path) -> None:
    from slip_msgs.msg import ContactProperties
    preset = tmp_path / 'presets.yaml'
    preset.write_text('wood:\n  finger_1: {mu_c: 0.5, r: 0.004}\n'
                      '  finger_2: {mu_c: 0.45, r: 0.005}\n')
    _estimator(harness, preset_file=str(preset), preset_name='wood')
    props = _latched_props(harness)
    assert harness.spin_until(lambda: len(props) >= 1)
    p = props[-1]
    assert p.source == ContactProperties.SOURCE_PRESET and p.preset_name == 'wood'
    assert p.valid and p.finger_1.mu_c == pytest.approx(0.5)
    assert p.finger_1.n_linear == 0 and math.isnan(p.finger_1.mu_c_std)


def test_missing_preset_refuses_to_start(ros_context, tmp_path: Path) -> None:
    from rclpy.parameter import Parameter
    from slip_control.contact_estimator_node import ContactEstimatorNode
    from slip_cell_common.core.param_schema import ParameterError
    with pytest.raises(ParameterError, match='cannot load presets'):
        ContactEstimatorNode(context=ros_context, parameter_overrides=[
            Parameter('preset_file', value=str(tmp_path / 'none.yaml')),
            Parameter('preset_name', value='steel')])


def test_online_mode_refines_mu_c_during_controlled_slip(harness, tmp_path: Path) -> None:
    from slip_control.core.synthetic import controlled_slip
    from slip_msgs.msg import ContactProperties
    from slip_msgs.srv import StartEstimation
    preset = tmp_path / 'presets.yaml'
    preset.write_text('start:\n  finger_1: {mu_c: 0.55, r: 0.006}\n'
                      '  finger_2: {mu_c: 0.50, r: 0.005}\n')
    node = _estimator(harness, preset_file=str(preset), preset_name='start',
                      **{'online.enabled': True})
    props = _latched_props(harness)
    assert harness.spin_until(lambda: len(props) >= 1)
    res = _start(harness, StartEstimation.Request.ONLINE, 0.0)
    assert res.accepted, res.message
    harness.play(controlled_slip(TRUTH, t0=T0 + 0.005, seed=8), node)
    assert harness.spin_until(lambda: props[-1].online_updated)
    last = props[-1]
    assert last.source == ContactProperties.SOURCE_ESTIMATED and last.preset_name == 'start'
    for f, truth, start in ((last.finger_1, TRUTH[0], 0.55), (last.finger_2, TRUTH[1], 0.50)):
        assert abs(f.mu_c - truth.mu_c) < 0.25 * abs(start - truth.mu_c)   # moved to the truth
        assert f.linear_valid and math.isfinite(f.mu_c_std)
    n = len(props)
    res = _start(harness, StartEstimation.Request.IDLE, 0.0)           # stop: no more updates
    assert res.accepted and 'stopped ONLINE' in res.message
    harness.play(controlled_slip(TRUTH, t0=harness.t + 0.005, seed=9)[:60], node)
    assert len(props) == n
