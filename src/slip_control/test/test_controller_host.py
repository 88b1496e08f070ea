# SPDX-License-Identifier: Apache-2.0
"""`ControllerHost`: the slip controller node's logic without ROS (inputs, stale debounce in the
node clock's domain — simulated time — or on a passed-in monotonic clock on hardware, mode
switching, parameters, state), and the node running it."""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace

import pytest

from slip_control.core.contact import ContactProperties
from slip_control.core.controller_host import (TRIGGER_FINGER, ControllerHost,
                                               ControllerState)
from slip_control.core.controllers import ControlOutput, SlipMode
from slip_control.core.mode_switch import ModeRequest
from slip_control.core.params import SlipControllerParams
from slip_control.core.signals import SensorSnapshot
from slip_control.core.trajectory import TrapezoidalTrajectory
from slip_cell_common.core.monitors import Level

DT = 1.0 / 120.0
T0 = 10.0


def feed(host: ControllerHost, snap: SensorSnapshot, *, wrenches: bool = True,
         twists: bool = True) -> bool:
    """Hand a snapshot's samples to the host as the subscriptions would (finger-1 twist last);
    returns whether a step is due."""
    due = False
    if wrenches:
        for k, w in ((1, snap.wrench_1), (2, snap.wrench_2)):
            if w is not None:
                host.on_wrench(k, w)
    if twists:
        for k, tw in ((2, snap.twist_2), (1, snap.twist_1)):
            if tw is not None:
                due = host.on_twist(k, tw) or due
    return due


def holding(make_props: Callable[..., ContactProperties], params: SlipControllerParams,
            snap: Callable[..., SensorSnapshot], log: list[tuple[str, str]] | None = None
            ) -> ControllerHost:
    """A host in HOLD after 0.1 s of fresh samples (object still, 5 N normal)."""
    host = ControllerHost(params, make_props(mu_c=0.45, r=0.006),
                          log=(lambda lv, text: log.append((lv, text))) if log is not None
                          else (lambda lv, text: None))
    assert host.switch(ModeRequest(int(SlipMode.HOLD)), T0).ok
    for i in range(1, 13):
        t = T0 + i * DT
        assert feed(host, snap(t, f=(0.0, 1.0), normal=5.0))
        out = host.step(t, steady=t)
        assert out is not None and out.force is not None and not out.safe_hold
    return host


def test_only_the_trigger_finger_twist_asks_for_a_step(make_props, snap) -> None:
    host = ControllerHost(SlipControllerParams(), make_props())
    s = snap(1.0)
    assert TRIGGER_FINGER == 1
    assert host.on_twist(2, s.twist_2) is False
    assert host.on_twist(1, s.twist_1) is True
    host.on_wrench(1, s.wrench_1)
    assert host.snapshot.twist_1 == s.twist_1 and host.snapshot.wrench_1 == s.wrench_1


def test_stopped_ft_stream_is_acted_on_after_the_other_stream_proves_it(
        make_props, params, snap) -> None:
    """F/T stops while twists keep coming; the steady clock does not advance (as when the
    process is fed but busy): the verdict waits for 4 twists of the other stream."""
    host = holding(make_props, params, snap)
    t_stop = T0 + 12 * DT
    outs: list[tuple[float, ControlOutput | None]] = []
    for i in range(1, 13):
        t = t_stop + i * DT
        feed(host, snap(t, f=(0.0, 1.0), normal=5.0), wrenches=False)
        outs.append((t, host.step(t, steady=t_stop)))
    stale = [(t, o) for t, o in outs if t - t_stop > params.ft_stale_after]
    assert stale[0][1] is None                       # first stale step: deferred
    held = [(t, o) for t, o in outs if o is not None and o.safe_hold]
    assert held and held[0][1].reason.startswith('F/T stale')
    # 2 twists per feed: the 4th twist after the first stale step comes 2 feeds later.
    assert [o for _, o in stale[:2]] == [None, None]
    assert held[0][0] == pytest.approx(stale[2][0])
    assert host.steps_deferred == 2 and host.safe_hold


def test_quiet_streams_are_acted_on_after_stale_confirm_of_node_clock_time(
        make_props, params, snap) -> None:
    """Simulated time (no ``steady``): the verdict waits ``stale_confirm`` of that time."""
    host = holding(make_props, params, snap)
    t_last = T0 + 12 * DT
    t = t_last + params.velocity_stale_after + 0.001     # both streams stale, nothing new
    assert host.step(t) is None
    assert host.step(t) is None                          # simulated time stands still
    assert host.step(t + params.stale_confirm / 2) is None
    pending = host.inputs_report(t + params.stale_confirm / 2)
    assert pending.level == Level.WARN and 'not acted on (yet)' in pending.message
    out = host.step(t + params.stale_confirm + 1e-9)
    assert out is not None and out.safe_hold
    assert host.steps_deferred == 3
    acted = host.inputs_report(t + params.stale_confirm + 1e-9)
    assert acted.level == Level.ERROR and acted.message.endswith('safe hold')


def test_quiet_streams_are_acted_on_after_stale_confirm_on_the_passed_clock(
        make_props, params, snap) -> None:
    """System clock (hardware): confirmed on the monotonic clock the node passes in."""
    host = holding(make_props, params, snap)
    t_last = T0 + 12 * DT
    t = t_last + params.velocity_stale_after + 0.001     # both streams stale, nothing new
    assert host.step(t, steady=0.0) is None
    assert host.step(t + 0.005, steady=params.stale_confirm / 2) is None
    out = host.step(t + 0.010, steady=params.stale_confirm)
    assert out is not None and out.safe_hold
    assert host.steps_deferred == 2


def _linear_slip_with_backlog(make_props, snap, stale_confirm: float,
                              wall_per_tick: float | None, clock_per_sample: float = 0.0
                              ) -> tuple[list, ControllerHost]:
    """A 20 mm LINEAR slip whose node falls 83 ms behind its queues once: its clock (simulated
    time, from the depth-1 ``/clock``) jumps to the newest time while the samples queued with
    it are still on their way, and stays there while the node drains them (8 watchdog ticks).

    ``wall_per_tick`` None: the host confirms on the node clock (use_sim_time). Otherwise a
    steady clock is passed that advances by this much per step (a starved process: wall time
    races while simulated time stands still). ``clock_per_sample``: newer ``/clock`` messages
    arrive between the queued samples, so the node clock moves on by this much per sample
    while the node drains them.
    """
    params = replace(SlipControllerParams(), stale_confirm=stale_confirm)
    host = ControllerHost(params, make_props(mu_c=0.45, r=0.006))
    outcome = host.switch(ModeRequest(int(SlipMode.LINEAR), duration=1.0, distance=0.02,
                                      direction=(0.0, -1.0, 0.0)), T0)
    assert outcome.ok and host.mode == SlipMode.LINEAR
    traj = TrapezoidalTrajectory(0.02, 1.0)
    snaps = []
    for i in range(1, 157):
        t = T0 + i * DT
        _, v = traj.sample(t - T0)
        snaps.append(snap(t, f=(0.0, 0.45 * 5.0 if v > 0.0 else 1.5), v=(0.0, -v),
                          ft_stamp=t - 0.001))
    results = []
    wall = [0.0]

    def run(s: SensorSnapshot, t: float) -> None:
        if wall_per_tick is None:
            out = host.step(t)
        else:
            wall[0] += wall_per_tick
            out = host.step(t, steady=wall[0])
        if out is not None and out.result is not None:
            results.append(out.result)

    for s in snaps[:30]:
        feed(host, s)
        run(s, s.twist_1.stamp)
    t_ahead = snaps[39].twist_1.stamp
    for _ in range(8):                                  # watchdog ticks, clock ahead
        run(snaps[29], t_ahead)
    for k, s in enumerate(snaps[30:]):
        feed(host, s)
        run(s, max(t_ahead + k * clock_per_sample, s.twist_1.stamp))
    assert results
    return results, host


@pytest.mark.parametrize('stale_confirm', [0.02, 0.0])
def test_clock_ahead_of_queued_samples_is_a_backlog(make_props, snap,
                                                     stale_confirm: float) -> None:
    """Simulated time: deferred while the node drains its queue (its clock does not move),
    then the samples make the inputs fresh and the slip finishes. Acting at once
    (``stale_confirm`` 0) ends the slip as "velocity stale"."""
    results, host = _linear_slip_with_backlog(make_props, snap, stale_confirm, None)
    if stale_confirm > 0.0:
        assert results[0].message == 'done' and results[0].success, results
        assert host.steps_deferred >= 8
    else:
        assert results[0].message == 'velocity stale'


def test_a_backlog_drained_behind_a_moving_clock_is_not_a_stopped_stream(
        make_props, snap) -> None:
    """Newer ``/clock`` messages arrive while the node drains the queued twists (5 ms of node
    clock per sample, 20 ms after four): the stale stream keeps delivering newer samples, so
    on node-clock time each one starts the verdict over and the slip finishes. The same
    clock passed as a monotonic clock (hardware rule) confirms it and ends the slip."""
    stale_confirm = SlipControllerParams().stale_confirm
    results, _ = _linear_slip_with_backlog(make_props, snap, stale_confirm, None, 0.005)
    assert results[0].message == 'done' and results[0].success, results
    results, _ = _linear_slip_with_backlog(make_props, snap, stale_confirm, 0.005)
    assert results[0].message == 'velocity stale'


def test_a_starved_host_ends_the_slip_only_when_confirming_on_wall_time(
        make_props, snap) -> None:
    """The same backlog on a starved host: 10 ms of wall time pass per step while simulated
    time stands still. Confirming on that wall clock (the former rule for every node) ends the
    slip as "velocity stale"; confirming on simulated time (the rule under use_sim_time) does
    not."""
    stale_confirm = SlipControllerParams().stale_confirm
    on_wall, _ = _linear_slip_with_backlog(make_props, snap, stale_confirm, 0.010)
    assert on_wall[0].message == 'velocity stale'
    on_sim, host = _linear_slip_with_backlog(make_props, snap, stale_confirm, None)
    assert on_sim[0].message == 'done' and on_sim[0].success, on_sim
    assert host.steps_deferred >= 8


def test_switch_validates_swaps_and_hands_over(make_props, params, snap) -> None:
    log: list[tuple[str, str]] = []
    host = holding(make_props, params, snap, log)
    hold = host.controller
    bad = host.switch(ModeRequest(int(SlipMode.LINEAR), duration=2.0, distance=5.0), T0 + 1)
    assert not bad.ok and 'beyond the grasp' in bad.message
    assert host.controller is hold and log[-1][0] == 'warn'
    off = host.switch(ModeRequest(int(SlipMode.OFF)), T0 + 1)
    assert off.ok and host.mode == SlipMode.OFF and off.preempted is None
    assert off.final_force == pytest.approx(hold.last_force)   # handed over, valid until replaced
    lin = host.switch(ModeRequest(int(SlipMode.LINEAR), duration=2.0, distance=0.02), T0 + 1)
    assert lin.ok and lin.preempted is None and host.mode == SlipMode.LINEAR
    again = host.switch(ModeRequest(int(SlipMode.HINGE)), T0 + 1.5)
    assert again.ok and host.mode == SlipMode.HINGE
    assert again.preempted is not None and again.preempted.message == 'preempted'
    assert any('trajectory ended: preempted' in text for _, text in log)


def test_cancel_hands_over_to_hold(make_props, params, snap) -> None:
    host = holding(make_props, params, snap)
    assert host.cancel('canceled', T0 + 1.0) is None and host.mode == SlipMode.HOLD
    host.switch(ModeRequest(int(SlipMode.ROTATIONAL), duration=2.0, angle=0.3), T0 + 1.0)
    result = host.cancel('canceled', T0 + 1.2)
    assert result is not None and result.message == 'canceled' and not result.success
    assert host.mode == SlipMode.HOLD


def test_new_parameters_wait_for_a_running_trajectory(make_props, params,
                                                      snap) -> None:
    log: list[tuple[str, str]] = []
    host = holding(make_props, params, snap, log)
    tuned = replace(params, hold=replace(params.hold, margin=3.0), stale_confirm=0.05)
    host.set_params(tuned)
    assert host.controller.params.hold.margin == 3.0 and log[-1][1].startswith('parameters')
    host.switch(ModeRequest(int(SlipMode.LINEAR), duration=2.0, distance=0.02), T0 + 1.0)
    host.set_params(replace(tuned, hold=replace(tuned.hold, margin=4.0)))
    assert host.controller.params.hold.margin == 3.0      # the trajectory keeps its snapshot
    host.cancel('canceled', T0 + 1.1)
    host.step(T0 + 1.1, steady=0.0)                         # applied between steps
    assert host.mode == SlipMode.HOLD and host.controller.params.hold.margin == 4.0
    assert host.params.stale_confirm == 0.05


def test_state_is_reported_when_it_changes(make_props, params, snap) -> None:
    host = ControllerHost(params)
    first = host.state_update(T0, 'started: OFF', force=True)
    assert first == ControllerState(SlipMode.OFF, False, False, False, False, False,
                                    'started: OFF')
    assert host.state_update(T0, 'again') is None          # unchanged
    reason = host.set_properties(make_props(mu_c=0.45, r=0.006))
    st = host.state_update(T0, reason, force=True)
    assert st is not None and st.contact_valid and 'ESTIMATED' in st.reason
    assert host.contact_report().level == Level.OK
    assert host.inputs_report(T0).level == Level.WARN       # nothing received, not controlling


def test_backwards_clock_resets_the_controller_timing(make_props, params, snap) -> None:
    log: list[tuple[str, str]] = []
    host = holding(make_props, params, snap, log)
    assert host.observe_time(T0 + 1.0) == 0.0
    assert host.step(T0 + 1.0) is None                      # stale verdict pending at T0 + 1
    assert host.observe_time(T0) == pytest.approx(1.0)
    assert 'jumped backwards' in log[-1][1]
    # The pending verdict restarts at the new time instead of waiting until T0 + 1 again.
    t = T0 + 12 * DT + params.velocity_stale_after + 0.001
    assert host.step(t) is None
    out = host.step(t + params.stale_confirm + 1e-9)
    assert out is not None and out.safe_hold


def test_the_host_reads_no_clock(make_props, params, snap,
                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """Every time is an argument: reading a process clock anywhere in a step fails."""
    def forbidden() -> float:
        raise AssertionError('the host read a clock')
    for name in ('time', 'monotonic', 'perf_counter', 'monotonic_ns', 'time_ns'):
        monkeypatch.setattr(time, name, forbidden)
    host = holding(make_props, params, snap)
    t = T0 + 1.0
    assert host.step(t, steady=0.0) is None                  # stale: deferred
    out = host.step(t, steady=1.0)
    assert out is not None and out.safe_hold


@pytest.mark.ros
def test_the_node_runs_a_controller_host(ros_context) -> None:
    from slip_control.slip_controller_node import SlipControllerNode
    node = SlipControllerNode(context=ros_context)
    try:
        assert type(node.host) is ControllerHost
        assert node.controller is node.host.controller
        assert node.snapshot is node.host.snapshot
    finally:
        node.destroy_node()
