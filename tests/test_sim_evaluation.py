# SPDX-License-Identifier: Apache-2.0
"""Issue 7 item 4, in-process half: the contact estimator and the four slip controllers on the
simulated cell, judged by physical outcomes from the simulator truth.

Everything runs through `slip_bringup.core.evaluation` (the deployed cores as harness agents:
the slip controller node's host, the runner's exploration; sim time, no DDS). One full
evaluation per reference preset is shared by the tests of this module; the fault tests build
their own cells.

Tolerances (issue 7: "final linear error ≤ 2 mm, rotation ≤ 2°, no slip in hold"):

* μ_c: |error| ≤ 0.01 (≈ 2 % of μ_c). The exploration slides at ≈ 12.5 mm/s, far above the
  Stribeck speed (1 mm/s), so the linear fit's intercept is the Coulomb level; its own 1-σ is
  ≈ 0.001 (80 samples), velocity quantisation and F/T noise add no bias.
* r: |error| ≤ 10 % of r. The rotational samples (|ω| ≥ 0.1 rad/s) put the pad rim at 0.5–5 mm/s,
  i.e. on the Stribeck curve, so the intercept is biased upwards by a fraction of
  (μ_s/μ_c − 1); that is up to +7 % for the reference plastic (μ_s/μ_c = 1.19).
* LINEAR: final error ≤ 2 mm; ROTATIONAL: ≤ 2° (the issue's numbers).
* ROTATIONAL also keeps the grasp point: translation ≤ 20 mm over the turn (measured 3–15 mm
  with the translation-speed term of the rotational floor; 39 mm for case 45° without it).
* HOLD: slip ≤ 1 mm under sustained pulls/pushes/twists (a step load beyond the 2× margin slips
  until the next 120 Hz step and the inner loop's rise, ~20 ms); ≤ 3 mm under 20 ms taps of up
  to 6 N on 0.08–0.2 kg objects (the controller cannot act inside the tap); no fall.
* HINGE: the object keeps its world orientation while the gripper turns 60° about it:
  |relative rotation| within 6° (10 %) of 60°, world turn ≤ 6°; grasp-point translation ≤ 15 mm
  (measured 8–10 mm: the HINGE law's 40 % margin on ft/μ_c does not stop the grasp point from
  creeping along gravity while the pads slide in rotation — reported, see the closing note).
"""
from __future__ import annotations

import math

import pytest

from slip_bringup import evaluate_cli
from slip_control.core.contact import ContactSource
from slip_control.core.controllers import SlipMode
from slip_control.core.contact_estimator import EstimationPhase
from slip_control.core.controller_host import ControllerHost
from slip_control.core.mode_switch import ModeRequest
from slip_bringup.core.evaluation.agents import ControllerAgent, EstimatorAgent
from slip_bringup.core.evaluation.estimation import estimate_without_contact
from slip_bringup.core.evaluation.faults import stream_fault
from slip_bringup.core.evaluation.report import format_table
from slip_bringup.core.evaluation.scene import controller_params, make_harness
from slip_bringup.core.evaluation.settings import REFERENCE_PRESETS, EvalSettings
from slip_bringup.core.evaluation.sim_runner_cell import (SequenceAgent, SimRunnerCell,
                                                          run_sequence)
from slip_bringup.core.evaluation.table import (LINEAR_CASES, ROTATIONAL_CASES,
                                                PresetEvaluation, evaluate_preset)
from slip_bringup.core.evaluation.trajectories import linear_slip
from slip_bringup.core.evaluation.truth import TruthProbe

pytestmark = pytest.mark.slow

PRESETS = REFERENCE_PRESETS
DEG = math.pi / 180.0


@pytest.fixture(scope='module', params=PRESETS)
def evaluation(request: pytest.FixtureRequest) -> PresetEvaluation:
    """The full table row of one preset (estimate, pick-up, hold, slips, hinge)."""
    return evaluate_preset(request.param)


# --- estimation ------------------------------------------------------------------------------

def test_estimation_recovers_mu_c_and_r(evaluation: PresetEvaluation) -> None:
    est = evaluation.estimation
    assert est.valid and est.properties.source == ContactSource.ESTIMATED, est.messages
    assert not est.dropped
    assert est.slide == pytest.approx(0.010, abs=0.001)          # the 1 cm descent slid
    assert est.twist == pytest.approx(10.0 * DEG, abs=1.0 * DEG)  # the pads twisted on it
    for f in est.fingers:
        assert f.linear_valid and f.rotational_valid
        assert f.n_linear >= 20 and f.n_rotational >= 20
        assert abs(f.mu_c_error) <= 0.01, f
        assert abs(f.r_error) <= 0.10 * f.r_true, f
        # The reported 1-σ is honest about its size (not zero, not huge).
        assert 0.0 < f.mu_c_std < 0.01 and 0.0 < f.r_std < 0.5e-3


def test_controllers_ran_on_the_estimate(evaluation: PresetEvaluation) -> None:
    assert evaluation.properties_source == 'ESTIMATED'
    assert not evaluation.notes


# --- HOLD ------------------------------------------------------------------------------------

def test_pick_up_under_hold_does_not_slip(evaluation: PresetEvaluation) -> None:
    pu = evaluation.pick_up
    assert pu is not None and not pu.dropped
    assert pu.lift == pytest.approx(0.20, abs=1e-3)
    assert pu.slip_peak <= 0.5e-3 and pu.rotation_peak <= 0.5 * DEG
    assert pu.force_min >= 4.0 - 1e-9          # 2 × the 2 N floor: never below it


def test_hold_under_disturbance(evaluation: PresetEvaluation) -> None:
    ho = evaluation.hold
    assert ho is not None and not ho.dropped
    assert ho.sustained_slip <= 1.0e-3, ho.push_slip
    assert ho.tap_slip <= 3.0e-3, ho.push_slip
    assert ho.rotation_peak <= 3.0 * DEG
    assert ho.force_max > 2.0 * ho.force_min   # it did react to the loads


# --- LINEAR and ROTATIONAL ------------------------------------------------------------------

@pytest.mark.parametrize('case', LINEAR_CASES, ids=lambda c: f'{c[0] * 100:.0f}cm_{c[1]:.0f}s')
def test_linear_slip_reaches_the_distance(evaluation: PresetEvaluation,
                                          case: tuple[float, float]) -> None:
    o = evaluation.linear[case]
    assert not o.dropped
    assert abs(o.final_error) <= 2e-3, o                     # truth
    assert o.off_axis <= 1e-3                                 # slid straight down
    assert o.result is not None and o.result.success and o.result.message == 'done'
    assert abs(o.result.final_error) <= 2e-3                  # the controller's own view
    assert o.result_time <= case[1] + 0.5                     # ended near T
    assert o.tracking_max <= 3e-3                             # followed the trapezoid


@pytest.mark.parametrize('case', ROTATIONAL_CASES,
                         ids=lambda c: f'{math.degrees(c[0]):.0f}deg_{c[1]:.0f}s')
def test_rotational_slip_reaches_the_angle(evaluation: PresetEvaluation,
                                           case: tuple[float, float]) -> None:
    o = evaluation.rotational[case]
    assert not o.dropped
    assert abs(o.final_error) <= 2.0 * DEG, o                 # truth
    assert o.result is not None and o.result.success and o.result.message == 'done'
    assert abs(o.result.final_error) <= 2.0 * DEG
    assert o.tracking_max <= 3.0 * DEG
    assert o.off_axis <= 20e-3, o                             # the grasp point stayed


# --- HINGE -----------------------------------------------------------------------------------

def test_hinge_lets_the_gripper_turn_about_the_object(evaluation: PresetEvaluation) -> None:
    hg = evaluation.hinge
    assert hg is not None and not hg.dropped
    assert hg.relative_rotation == pytest.approx(-60.0 * DEG, abs=6.0 * DEG)
    assert abs(hg.object_turn) <= 6.0 * DEG
    assert hg.translation_turn <= 15e-3


def test_table_has_every_cell(evaluation: PresetEvaluation) -> None:
    table = format_table([evaluation])
    row = next(line for line in table.splitlines()
               if line.startswith(evaluation.preset) and 'ESTIMATED' in line)
    assert 'n/a' not in row and row.split()[-1] == '0'       # no missing cell, no drop


def test_cli_prints_the_table(evaluation: PresetEvaluation, monkeypatch: pytest.MonkeyPatch,
                              capsys: pytest.CaptureFixture[str]) -> None:
    seen = {}

    def fake(presets: list[str], settings: EvalSettings, **kw: object) -> tuple:
        seen.update(presets=presets, quick=kw.get('quick'), dt=settings.physics_dt)
        return (evaluation,)

    monkeypatch.setattr(evaluate_cli, 'evaluate_all', fake)
    assert evaluate_cli.main(['--preset', f'{evaluation.preset},x', '--quick',
                              '--physics-dt', '5e-4']) == 0
    assert seen == {'presets': [evaluation.preset, 'x'], 'quick': True, 'dt': 5e-4}
    assert 'Contact estimation' in capsys.readouterr().out


def test_cli_reports_an_unknown_preset(capsys: pytest.CaptureFixture[str]) -> None:
    assert evaluate_cli.main(['--preset', 'glass']) == 1
    assert "unknown preset 'glass'" in capsys.readouterr().err


# --- faults ----------------------------------------------------------------------------------

#: Cut instants into a 2 cm / 2 s LINEAR slip [s]; the commanded force moves between the
#: 0.6 N floor and ≈ 2 N there, so both low and high last outputs are covered.
CUTS = (0.3, 0.6, 0.9, 1.2, 1.5)


@pytest.fixture(scope='module')
def ft_faults() -> dict:
    return {at: stream_fault('cardboard', 'ft', at) for at in CUTS}


def test_ft_stream_stop_mid_slip_goes_to_safe_hold_within_100_ms(ft_faults: dict) -> None:
    for at, o in ft_faults.items():
        assert o.result is not None and o.result.message == 'F/T stale', at
        assert o.reaction <= 0.100, (at, o.reaction)
        assert o.deferred_steps >= 1, at          # the node's stale debounce ran
        assert o.mode_after == SlipMode.HOLD


def test_ft_stream_stop_mid_slip_keeps_the_object(ft_faults: dict) -> None:
    for at, o in ft_faults.items():
        assert not o.dropped, at
        assert o.slip_after <= 5e-3 and o.creep <= 0.1e-3, (at, o.slip_after, o.creep)


@pytest.mark.parametrize('at', (0.45, 0.9, 1.35))
def test_velocity_stream_stop_mid_slip_goes_to_safe_hold(at: float) -> None:
    o = stream_fault('cardboard', 'velocity', at)
    assert o.result is not None and o.result.message == 'velocity stale'
    assert o.reaction <= 0.100
    assert o.deferred_steps >= 1                  # the node's stale debounce ran
    assert o.mode_after == SlipMode.HOLD
    assert not o.dropped
    assert o.force_after >= 4.0 - 1e-9          # HOLD law on fresh F/T, slip term 0
    assert o.slip_after <= 5e-3 and o.creep <= 0.1e-3


def test_estimator_without_contact_fails_clearly_and_publishes_nothing() -> None:
    o = estimate_without_contact('cardboard')
    assert not o.in_grasp
    assert not o.start_accepted and o.start_message.startswith('no contact')
    assert not o.core_success and not o.core_changed
    assert 'no contact' in o.core_message and 'properties unchanged' in o.core_message
    assert o.source == ContactSource.DEFAULT and not o.valid     # placeholder, never valid


def test_slip_modes_are_refused_after_a_failed_exploration() -> None:
    h = make_harness('cardboard')
    est = EstimatorAgent()
    h.add_agent(est)
    h.move(lift=0.2, duration=1.0)
    h.run_for(0.2)
    assert not est.start(h, EstimationPhase.LINEAR, 1.0).accepted
    ctl = ControllerAgent(EvalSettings().controller, est.estimator.properties)
    h.add_agent(ctl)
    for request in (ModeRequest(int(SlipMode.HOLD)),
                    ModeRequest(int(SlipMode.LINEAR), duration=2.0, distance=0.02)):
        out = ctl.set_mode(h, request)
        assert not out.ok and 'DEFAULT' in out.message
    h.run_for(0.1)
    assert ctl.commands == [] and ctl.mode == SlipMode.OFF


# --- the deployed code ----------------------------------------------------------------------

@pytest.mark.ros
def test_the_evaluation_and_the_node_run_the_same_controller_host(ros_context) -> None:
    from slip_control.slip_controller_node import SlipControllerNode
    node = SlipControllerNode(context=ros_context)
    try:
        agent = ControllerAgent(EvalSettings().controller, None)
        assert type(agent.host) is type(node.host) is ControllerHost
    finally:
        node.destroy_node()


@pytest.mark.parametrize(('preset', 'dt'), [('wood', 1e-4), ('wood', 1e-3), ('plastic', 1e-3),
                                         ('case', 1e-3), ('cardboard', 1e-3)])
def test_the_runners_exploration_slides_and_twists_the_pads_on_the_object(
        preset: str, dt: float) -> None:
    """``est_contact`` of the experiment runner, step machine and all, on the simulated cell:
    the moves are the runner's (control_and_estimation §3.8); the table holds the object, so
    it slides 10 mm up between the pads during the descent and the pads twist ≈ 10° on it; the
    estimate is valid and the flags and pose are as after a real run."""
    settings = EvalSettings(physics_dt=dt)
    h = make_harness(preset, settings)
    est = EstimatorAgent(settings.estimator)
    ctl = ControllerAgent(controller_params(settings, h.cell), est.estimator.properties)
    probe = TruthProbe()
    seq = SequenceAgent()
    for a in (est, ctl, probe, seq):
        h.add_agent(a)
    cell = SimRunnerCell(h, est, ctl)
    runner = run_sequence(h, seq, cell, 'est_contact', settings.runner)
    prog = runner.progress()
    assert prog.success, prog.log
    e = settings.runner.estimation
    descent, twist, back = cell.moves[:3]
    assert [(m.lift, m.rotation, round(m.t_end - m.t_start, 6)) for m in cell.moves[:3]] == [
        (-e.descent, 0.0, e.descent_time), (0.0, e.twist_angle, e.twist_time),
        (0.0, -e.twist_angle, e.twist_time)]
    assert cell.moves[-1].lift == pytest.approx(e.descent)          # back to the pick-up pose
    i0, i1 = probe.at(descent.t_start), probe.at(descent.t_end)
    assert probe.y[i1] - probe.y[i0] == pytest.approx(e.descent, rel=0.02)    # slid up
    assert abs(probe.x[i1] - probe.x[i0]) < 1e-4
    assert max(abs(probe.object_y[i] - probe.object_y[i0]) for i in range(i0, i1 + 1)) < 1e-4
    j0 = probe.at(twist.t_start)
    rel = [probe.theta[i] - probe.theta[j0] for i in probe.indices(twist.t_start, back.t_end)]
    assert max(rel, key=abs) == pytest.approx(-e.twist_angle, abs=0.01)   # pads turn on it
    assert abs(rel[-1]) < 0.005
    assert max(abs(probe.object_theta[i] - probe.object_theta[j0])
               for i in probe.indices(twist.t_start, back.t_end)) < 0.005
    assert not probe.dropped[probe.at(back.t_end)]
    assert prog.estimate is not None and prog.estimate.valid
    assert runner.flags.contact_estimated and runner.flags.gripper_open
    assert [r.phase for r in est.reports] == [EstimationPhase.LINEAR, EstimationPhase.ROTATIONAL]
    assert any('HOLD on (if allowed): failed (ignored)' in line for line in prog.log)


# --- determinism -----------------------------------------------------------------------------

def test_same_settings_same_outcome() -> None:
    settings = EvalSettings(seed=3, settle=0.3)
    a = linear_slip('case', 0.01, 1.0, settings)
    b = linear_slip('case', 0.01, 1.0, settings)
    assert a == b
    assert abs(a.final_error) <= 2e-3
