# SPDX-License-Identifier: Apache-2.0
"""Population evaluation without simulation: set-up poses, scaled pushes, judges, report, CLI
argument errors (the simulated runs are in tests/test_population.py)."""
from __future__ import annotations

import math

import pytest

from slip_bringup import evaluate_cli
from slip_bringup.core.evaluation.estimation import EstimationOutcome, FingerEstimate
from slip_bringup.core.evaluation.hinge import HingeOutcome
from slip_bringup.core.evaluation.holding import (TAP_MAX_DURATION, HoldOutcome, scaled_pushes,
                                                  sustained)
from slip_bringup.core.evaluation.poses import (hanging_angle, hinge_start_turn,
                                                lever_horizontal_turn, path_sin_max)
from slip_bringup.core.evaluation.poses import gravity_in_middle
from slip_bringup.core.evaluation.trajectories import TrajectoryOutcome
from slip_bringup.population.report import format_table, summarise
from slip_bringup.population.results import ObjectResult, ScenarioResult
from slip_bringup.population.runner import (judge_estimation, judge_hinge, judge_hold,
                                            judge_trajectory, noise_seed)
from slip_control.core.contact import ContactProperties
from slip_control.core.controllers import SlipMode, SlipResult

DEG = math.pi / 180.0


def _gravity_torque_sign(com: tuple[float, float], turn: float) -> float:
    """Sign of gravity's torque about +z on a CoM at ``com`` after the gripper turned."""
    gx, gy = gravity_in_middle(turn)
    return math.copysign(1.0, com[0] * gy - com[1] * gx)


@pytest.mark.parametrize('angle_deg', [-170, -90, -45, 0, 30, 90, 135, 180])
def test_set_up_turns_put_the_lever_where_the_scenario_needs_it(angle_deg: float) -> None:
    a = angle_deg * DEG
    com = (0.02 * math.cos(a), 0.02 * math.sin(a))
    # Straight below the grasp point is hanging (γ = 0) at the pick-up pose.
    assert hanging_angle((0.0, -0.02)) == pytest.approx(0.0)
    turn, sign = lever_horizontal_turn(com)
    assert abs(turn) <= math.pi / 2 + 1e-9
    assert abs(hanging_angle(com, turn)) == pytest.approx(math.pi / 2)
    # Gravity then drives the object the way the slip angle's sign says.
    assert _gravity_torque_sign(com, turn) == sign
    start, hsign = hinge_start_turn(com, 60 * DEG)
    assert hanging_angle(com, start) == pytest.approx(hsign * 60 * DEG)
    assert abs(start) <= 120 * DEG + 1e-9


def test_reference_set_up_is_reproduced_for_a_com_below_the_grasp_point() -> None:
    # The preset table turns -90° for a +20° rotation, and +60° then +60° for the hinge.
    assert lever_horizontal_turn((0.0, -0.01)) == (pytest.approx(-math.pi / 2), 1)
    assert hinge_start_turn((0.0, -0.01)) == (pytest.approx(60 * DEG), 1)
    assert path_sin_max((0.0, -0.01), 60 * DEG) == pytest.approx(math.sin(60 * DEG))
    # CoM above the grasp point: on the way to 60° from hanging the lever passes horizontal.
    turn, _ = hinge_start_turn((0.0, 0.01))
    assert path_sin_max((0.0, 0.01), turn) == pytest.approx(1.0, abs=1e-3)


def test_scaled_pushes_follow_the_weight() -> None:
    pushes = scaled_pushes(2.0)
    held = sustained(pushes)
    taps = [p for p in pushes if p.duration < TAP_MAX_DURATION]
    assert [(p.fx, p.fy, p.torque) for p in held] == [
        (0.0, -0.5, 0.0), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, pytest.approx(0.01))]
    assert [(p.fx, p.fy) for p in taps] == [(0.0, -1.0), (0.0, -2.0), (0.0, -3.0), (-2.0, 0.0)]
    assert all(p.duration == pytest.approx(0.02) for p in taps)
    with pytest.raises(ValueError):
        scaled_pushes(0.0)


def test_noise_seed_is_deterministic_and_in_range() -> None:
    assert noise_seed(11, 3) == noise_seed(11, 3)
    assert noise_seed(11, 3) != noise_seed(11, 4)
    assert all(0 <= noise_seed(s, i) < 2 ** 31 for s in range(5) for i in range(50))


def _finger(k: int, mu_err: float, r_rel: float, mu_std: float = 0.002,
            r_std_rel: float = 0.02) -> FingerEstimate:
    return FingerEstimate(finger=k, mu_c=0.5 + mu_err, mu_c_true=0.5, mu_c_std=mu_std,
                          r=0.005 * (1 + r_rel), r_true=0.005, r_std=0.005 * r_std_rel,
                          n_linear=80, n_rotational=90, linear_valid=True,
                          rotational_valid=True)


def _estimation(f1: FingerEstimate, f2: FingerEstimate) -> EstimationOutcome:
    return EstimationOutcome(preset='x', fingers=(f1, f2), properties=ContactProperties(),
                             valid=True, messages=(), slide=0.01, twist=0.17, dropped=False)


def test_estimation_judge_counts_fingers_and_coverage() -> None:
    ok = judge_estimation(_estimation(_finger(1, 0.001, 0.01), _finger(2, -0.002, -0.02)))
    assert ok.success and ok.metric('fingers_ok') == 1.0
    assert ok.metric('mu_c_covered') == 1.0 and ok.metric('r_covered') == 1.0
    assert ok.metric('mu_c_error') == pytest.approx(-0.002)
    # r 15 % high on finger 2, 3 σ away: a failure the estimator called valid.
    bad = judge_estimation(_estimation(_finger(1, 0.001, 0.01), _finger(2, 0.0, 0.15,
                                                                       r_std_rel=0.05)))
    assert not bad.success and bad.failure.startswith('reported success but r error')
    assert bad.metric('fingers_ok') == 0.5 and bad.metric('r_covered') == 0.5
    assert bad.metric('r_error_rel') == pytest.approx(0.15)


def _trajectory(final_error: float, rms: float, result_time: float, message: str = 'done',
                dropped: bool = False) -> TrajectoryOutcome:
    result = SlipResult(SlipMode.LINEAR, message == 'done', message, 0.02, 0.0, result_time)
    return TrajectoryOutcome(preset='x', mode=SlipMode.LINEAR, target=0.02, duration=2.0,
                             achieved=0.02 - final_error, final_error=final_error,
                             off_axis=0.0005, tracking_rms=rms, tracking_max=2 * rms,
                             result=result, result_time=result_time, force_min=0.6,
                             force_max=3.0, dropped=dropped, trajectory_rms=rms,
                             trajectory_max=2 * rms)


def test_trajectory_judge_applies_every_criterion() -> None:
    assert judge_trajectory(_trajectory(0.0005, 0.0008, 2.1)).success
    late = judge_trajectory(_trajectory(0.0005, 0.0008, 1.5))
    assert not late.success and late.failure.startswith('reported success but duration')
    assert late.metric('duration_error_rel') == pytest.approx(-0.25)
    short = judge_trajectory(_trajectory(0.004, 0.0008, 2.0))
    assert short.failure.startswith('reported success but final error')
    lag = judge_trajectory(_trajectory(0.0005, 0.003, 2.0, message='timeout'))
    assert lag.failure.startswith('tracking') and lag.reported == 'timeout'
    assert judge_trajectory(_trajectory(0.0, 0.0, 2.0, dropped=True)).failure.endswith(
        'dropped')


def test_hold_and_hinge_judges() -> None:
    hold = HoldOutcome(preset='x', pushes=(), slip_peak=0.0004, rotation_peak=1.0 * DEG,
                       slip_final=0.0002, push_slip=(), sustained_slip=0.0003,
                       tap_slip=0.0004, force_min=2.0, force_max=6.0, dropped=False,
                       force_max_settle=9.0)
    assert judge_hold(hold, 6.0).success                    # 9 N ≤ 1.5 × 6 + 1
    bad = judge_hold(hold, 5.0)                             # 9 N > 8.5 N
    assert bad.failure.startswith('force peak') and bad.metric('force_peak') == 9.0
    hinge = HingeOutcome(preset='x', gripper_turn=60 * DEG, swing=-58 * DEG,
                         relative_rotation=-57 * DEG, object_turn=3 * DEG,
                         translation_peak=0.012, translation_turn=0.006, force_min=0.6,
                         force_max=2.0, dropped=False)
    assert judge_hinge(hinge).success
    dragged = judge_hinge(HingeOutcome(**{**hinge.__dict__, 'relative_rotation': -50 * DEG}))
    assert dragged.failure.startswith('rotation')


def _object(index: int, scenarios: tuple[ScenarioResult, ...]) -> ObjectResult:
    return ObjectResult(seed=1, index=index, name=f'pop-1-{index}',
                        parameters={'mass': 0.1 * (index + 1)}, surface='square',
                        scenarios=scenarios, cpu_seconds=1.0)


def test_report_counts_fingers_infeasible_claims_and_names_the_worst() -> None:
    est = [ScenarioResult('estimation', '-', True, '', f == 1.0,
                          '' if f == 1.0 else 'r error: finger 1 +12 %',
                          {'fingers_ok': f, 'r_error_rel': 0.12 * (1 - f), 'mu_c_covered': 1.0,
                           'r_covered': 0.5})
           for f in (1.0, 0.5, 1.0)]
    lin = [ScenarioResult('linear', 'thesis', True, '', True, '', {'final_error': 0.0002}),
           ScenarioResult('linear', 'thesis', False, 'too light to slide: weight …', False,
                          'reported success but final error: +9 mm',
                          {'final_error': 0.009, 'claimed_success': 1.0}, 'done'),
           ScenarioResult('linear', 'thesis', True, '', False, 'final error: +3 mm',
                          {'final_error': 0.003, 'claimed_success': 0.0}, 'timeout')]
    results = [_object(i, (est[i], lin[i])) for i in range(3)]
    summaries = {s.scenario: s for s in summarise(results)}
    e = summaries['estimation']
    assert e.finger_rate is not None and (e.finger_rate.successes, e.finger_rate.trials) == (5, 6)
    assert e.coverage['r_covered'] == pytest.approx(0.5)
    li = summaries['linear']
    assert (li.infeasible, li.infeasible_claimed) == (1, 1)
    assert li.infeasible_reasons == {'too light to slide': 1}
    assert (li.rate.successes, li.rate.trials) == (1, 2)
    assert li.worst[0]['index'] == 2 and li.worst[0]['success'] is False
    text = format_table(list(summaries.values()), 1.0, 3.0, 3)
    assert 'fingers within tolerance: 5/6' in text
    assert '--object 1:2' in text
    assert 'reported success on 1 of them' in text


@pytest.mark.parametrize('argv, needle', [
    (['--population', '0'], 'argument --population: must be an integer >= 1'),
    (['--population', '3', '--scheduler', 'not an address'], 'bad scheduler address'),
    (['--population', '3', '--scheduler', 'tcp://host'], 'bad scheduler address'),
    (['--population', '3', '--controllers', 'thesis,pid'], 'unknown controller pid'),
    (['--object', '11-3'], '--object expects SEED:INDEX'),
    (['--population', '3', '--workers', '-1'], 'argument --workers: must be an integer >= 0'),
])
def test_population_cli_refuses_bad_arguments_in_one_line(
        argv: list[str], needle: str, capsys: pytest.CaptureFixture[str], tmp_path) -> None:
    try:
        code = evaluate_cli.main([*argv, '--out', str(tmp_path / 'out')])
    except SystemExit as exc:                # argparse's own type checks exit with 2
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('slip_evaluate: error: ') and needle in err[0]
    assert not (tmp_path / 'out').exists()
