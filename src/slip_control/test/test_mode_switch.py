# SPDX-License-Identifier: Apache-2.0
"""Mode-request validation and atomic switching (§4.1, CE-1, CE-2, CE-4)."""
from __future__ import annotations

import math
from collections.abc import Callable

import pytest

from slip_control.core.contact import ContactProperties, ContactSource
from slip_control.core.controllers import (HingeController, HoldController, LinearController,
                                           OffController, RotationalController, SlipMode)
from slip_control.core.mode_switch import ModeRequest, build_controller, validate_request
from slip_control.core.params import SlipControllerParams
from slip_control.core.signals import SensorSnapshot

NAN, INF = float('nan'), float('inf')
LIN, ROT = int(SlipMode.LINEAR), int(SlipMode.ROTATIONAL)
MakeProps = Callable[..., ContactProperties]


@pytest.mark.parametrize('request_, text', [
    (ModeRequest(LIN, duration=NAN, distance=0.02), 'duration = nan'),
    (ModeRequest(LIN, duration=2.0, distance=INF), 'distance = inf'),
    (ModeRequest(ROT, duration=2.0, angle=-INF), 'angle = -inf'),
    (ModeRequest(int(SlipMode.HOLD), duration=NAN), 'duration = nan'),
    (ModeRequest(LIN, duration=2.0, distance=0.02, direction=(NAN, 0.0, 0.0)), 'direction.x'),
    (ModeRequest(LIN, duration=-1.0, distance=0.02), 'duration = -1.0'),
    (ModeRequest(LIN, duration=0.0, distance=0.02), 'duration = 0.0'),
    (ModeRequest(ROT, duration=1e6, angle=0.3), 'duration'),
    (ModeRequest(LIN, duration=2.0, distance=0.0), 'distance = 0.0 m must be > 0'),
    (ModeRequest(LIN, duration=2.0, distance=-0.02), 'must be > 0'),
    (ModeRequest(LIN, duration=2.0, distance=0.5), 'beyond the grasp'),
    (ModeRequest(ROT, duration=2.0, angle=0.0), 'non-zero'),
    (ModeRequest(ROT, duration=2.0, angle=-7.0), 'max_angle'),
    (ModeRequest(7), 'unknown mode 7'),
    (ModeRequest(-1), 'unknown mode'),
])
def test_bad_requests_are_rejected(request_: ModeRequest, text: str, make_props: MakeProps,
                                   params: SlipControllerParams) -> None:
    ok, msg = validate_request(request_, make_props(), params)
    assert not ok and text in msg
    out = build_controller(request_, make_props(), params, 0.0)
    assert not out.ok and out.controller is None and text in out.message


@pytest.mark.parametrize('mode', [SlipMode.HOLD, SlipMode.ROTATIONAL, SlipMode.LINEAR,
                                  SlipMode.HINGE])
def test_no_properties_rejected(mode: SlipMode, params: SlipControllerParams) -> None:
    req = ModeRequest(int(mode), duration=2.0, distance=0.02, angle=0.3)
    for props, text in ((None, 'no contact properties'),
                        (ContactProperties.default(), 'DEFAULT')):
        ok, msg = validate_request(req, props, params)
        assert not ok and text in msg


def test_properties_needed_per_mode(make_props: MakeProps,
                                    params: SlipControllerParams) -> None:
    no_r = make_props(rotational_valid=False)
    hold = ModeRequest(int(SlipMode.HOLD))
    ok, msg = validate_request(hold, no_r, params)
    assert not ok and 'finger 1 r' in msg
    assert not validate_request(ModeRequest(ROT, duration=2.0, angle=0.3), no_r, params)[0]
    assert validate_request(ModeRequest(LIN, duration=2.0, distance=0.02), no_r, params)[0]
    assert validate_request(ModeRequest(int(SlipMode.HINGE)), no_r, params)[0]
    no_mu = make_props(linear_valid=False)
    ok, msg = validate_request(ModeRequest(int(SlipMode.HINGE)), no_mu, params)
    assert not ok and 'mu_c' in msg
    assert validate_request(ModeRequest(int(SlipMode.OFF)), None, params)[0]


def test_presets_need_explicit_permission(make_props: MakeProps) -> None:
    preset = make_props(source=ContactSource.PRESET, name='wood')
    req = ModeRequest(int(SlipMode.HOLD))
    ok, msg = validate_request(req, preset, SlipControllerParams())
    assert not ok and 'allow_preset_properties' in msg
    out = build_controller(req, preset, SlipControllerParams(allow_preset_properties=True), 0.0)
    assert out.ok and out.preset_in_use and "preset 'wood'" in out.message


def test_switch_builds_complete_controllers(make_props: MakeProps,
                                            params: SlipControllerParams) -> None:
    p = make_props(mu_c=0.4, r=0.006)
    kinds = {SlipMode.HOLD: HoldController, SlipMode.HINGE: HingeController,
             SlipMode.LINEAR: LinearController, SlipMode.ROTATIONAL: RotationalController,
             SlipMode.OFF: OffController}
    for mode, cls in kinds.items():
        out = build_controller(ModeRequest(int(mode), duration=2.0, distance=0.02, angle=-0.3),
                               p, params, 5.0)
        assert out.ok and type(out.controller) is cls, mode
        assert out.controller.mode == mode
        if mode != SlipMode.OFF:
            assert out.controller.contact.mu_c == pytest.approx(0.4)
    lin = build_controller(ModeRequest(LIN, duration=2.0, distance=0.02,
                                       direction=(0.0, 2.0, 0.0)), p, params, 5.0).controller
    assert isinstance(lin, LinearController) and lin.direction == pytest.approx((0.0, 1.0))
    assert lin.trajectory.peak_speed == pytest.approx(0.0125)
    latched = build_controller(ModeRequest(LIN, duration=2.0, distance=0.02), p, params,
                               5.0).controller
    assert isinstance(latched, LinearController) and latched.direction is None
    rot = build_controller(ModeRequest(ROT, duration=2.0, angle=-0.3), p, params,
                           5.0).controller
    assert isinstance(rot, RotationalController) and rot.sign == -1.0


def test_rejected_request_leaves_running_trajectory_untouched(
        make_props: MakeProps, params: SlipControllerParams,
        snap: Callable[..., SensorSnapshot]) -> None:
    p = make_props()
    running = build_controller(ModeRequest(LIN, duration=2.0, distance=0.02), p, params,
                               0.0).controller
    assert running is not None
    running.step(snap(0.01, f=(0.0, -1.0)), 0.01)
    bad = build_controller(ModeRequest(LIN, duration=NAN, distance=0.02), p, params, 0.02,
                           previous=running)
    assert not bad.ok and bad.preempted is None and running.goal_active
    good = build_controller(ModeRequest(int(SlipMode.HOLD)), p, params, 0.02,
                            previous=running)
    assert good.ok and good.preempted is not None and good.preempted.message == 'preempted'
    assert not running.goal_active
    # HOLD starts from the preempted controller's last force (no step down at the switch).
    assert isinstance(good.controller, HoldController)
    assert good.controller.last_force == running.last_force


def test_off_hands_over_the_last_force(make_props: MakeProps, params: SlipControllerParams,
                                       snap: Callable[..., SensorSnapshot]) -> None:
    hold = build_controller(ModeRequest(int(SlipMode.HOLD)), make_props(), params,
                            0.0).controller
    assert hold is not None
    f = hold.step(snap(0.0, f=(0.0, 2.0)), 0.0).force
    off = build_controller(ModeRequest(int(SlipMode.OFF)), None, params, 0.01, previous=hold)
    assert off.ok and off.final_force == pytest.approx(f)
    assert isinstance(off.controller, OffController)
    first = build_controller(ModeRequest(int(SlipMode.OFF)), None, params, 0.0)
    assert first.ok and first.final_force is None


def test_finished_trajectory_publishes_hold_in_the_same_step(
        make_props: MakeProps, params: SlipControllerParams,
        snap: Callable[..., SensorSnapshot]) -> None:
    ctrl = build_controller(ModeRequest(LIN, duration=0.5, distance=0.001,
                                        direction=(1.0, 0.0, 0.0)), make_props(), params,
                            0.0).controller
    assert ctrl is not None
    out = None
    for i in range(1, 100):
        t = i / 120.0
        out = ctrl.step(snap(t, f=(1.0, 0.0), v=(0.01, 0.0)), t)
        if out.result is not None:
            break
    assert out is not None and out.result is not None and out.result.success
    assert out.mode == SlipMode.HOLD and isinstance(out.next_controller, HoldController)
    # 2·max(1/0.4, 2) + 100·0.01 = 6 N, rising at once above the slip force.
    assert out.force == pytest.approx(6.0)
    assert math.isclose(out.tracking.force_cmd, 6.0)


def test_with_params_rebuilds_idle_modes_and_defers_trajectories(
        make_props: MakeProps, params: SlipControllerParams,
        snap: Callable[..., SensorSnapshot]) -> None:
    from dataclasses import replace

    from slip_control.core.mode_switch import hold_successor, with_params
    props = make_props()
    new = replace(params, hold=replace(params.hold, margin=3.0))
    hold = build_controller(ModeRequest(int(SlipMode.HOLD)), props, params, 0.0).controller
    assert hold is not None
    hold.step(snap(0.0, f=(1.0, 0.0)), 0.001)
    rebuilt = with_params(hold, new)
    assert isinstance(rebuilt, HoldController) and rebuilt.params.hold.margin == 3.0
    assert rebuilt.last_force == hold.last_force               # no drop at the swap
    hinge = with_params(HingeController(params, hold.contact, initial_force=7.0), new)
    assert isinstance(hinge, HingeController) and hinge.last_force == 7.0
    assert isinstance(with_params(OffController(params), new), OffController)
    lin = build_controller(ModeRequest(LIN, duration=2.0, distance=0.02), props, params,
                           0.0).controller
    assert lin is not None and with_params(lin, new) is None   # running: keep the snapshot

    succ, result = hold_successor(lin, 'canceled', 0.5)
    assert isinstance(succ, HoldController) and succ.params is params
    assert result is not None and result.message == 'canceled' and not lin.goal_active
    assert hold_successor(hold, 'canceled', 0.5)[1] is None
