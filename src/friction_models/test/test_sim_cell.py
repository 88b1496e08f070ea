# SPDX-License-Identifier: Apache-2.0
"""SimCell contract: sensors (rates, units, frames, signs), inner loop, bias, homing, errors."""
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from slip_gripper_driver.core.force_control import BypassReason
from slip_cell_common.core.frames import FrameParams, planar_to_middle
from slip_cell_common.core.param_schema import ParameterError, flatten, from_flat
from slip_velocity_sensor.core.chip_model import ChipModelParams, CountQuantizer
from slip_velocity_sensor.core.fusion import FusionParams, RigidBodyFusion

from friction_models.core.harness import Harness
from friction_models.core.presets import (ContactPreset, ObjectPreset, PresetError,
                                          load_presets, preset_from_dict, reference_presets)
from friction_models.core.sensors import (FtSensorParams, MotorEncoder, SimEvents,
                                          VelocitySensor, VelocitySensorParams)
from friction_models.core.sim_cell import SimCell, SimParams

CONFIG = Path(__file__).resolve().parents[1] / 'config' / 'sim_presets.yaml'
CSV = Path(__file__).resolve().parents[3] / 'docs' / 'data' / 'contact_estimates_reference.csv'


def _cell(dt: float = 1e-3, preset: str = 'wood', **kw: object) -> SimCell:
    return SimCell(SimParams(physics_dt=dt, **kw), reference_presets(), preset)


def _grasped(dt: float = 1e-3, force: float = 10.0, **kw: object) -> Harness:
    h = Harness(_cell(dt, **kw))
    h.home()
    h.bias()
    h.command_force(force)
    h.run_for(1.5)
    return h


# ---------------------------------------------------------------------------- rates, stamps
def test_sensor_rates_and_stamps() -> None:
    cell = _cell(1e-4)
    cell.advance(0.1)
    ev = cell.advance(2.1)
    assert len(ev.telemetry) == pytest.approx(1000, abs=1)
    for k in (1, 2):
        ft = [e.stamp for e in ev.ft if e.finger == k]
        vel = [e.stamp for e in ev.velocity if e.finger == k]
        assert len(ft) == pytest.approx(2000, abs=1)
        assert len(vel) == pytest.approx(240, abs=1)
        assert all(b > a for a, b in zip(ft, ft[1:]))
        assert all(b > a for a, b in zip(vel, vel[1:]))
        periods = [b - a for a, b in zip(vel, vel[1:])]
        assert sum(periods) / len(periods) == pytest.approx(1.0 / 120.0, rel=0.01)
        assert max(periods) - min(periods) <= 1e-4 + 1e-9     # jitter ≤ one physics step
    stamps = [e.stamp for e in ev]
    assert stamps == sorted(stamps)
    assert ev.telemetry[0].stamp == pytest.approx(0.102)
    assert cell.t == pytest.approx(2.1)


def test_advance_is_step_aligned_and_idempotent_in_the_past() -> None:
    cell = _cell(1e-3)
    cell.advance(0.0105)
    assert cell.t == pytest.approx(0.010)
    assert len(cell.advance(0.005)) == 0
    with pytest.raises(ValueError, match='finite'):
        cell.advance(math.nan)


# ---------------------------------------------------------------------------- F/T
def test_bias_needs_a_window_and_removes_the_offsets() -> None:
    cell = _cell()
    ev = cell.advance(0.2)
    assert all(e.biased is None for e in ev.ft)
    assert not cell.ft_biased
    raw_fz = [e.raw[2] for e in ev.ft if e.finger == 1]
    assert sum(raw_fz) / len(raw_fz) == pytest.approx(FtSensorParams().offset_1[2], abs=0.01)
    ok, msg = cell.bias_ft()
    assert ok and 'completes' in msg
    assert cell.bias_ft()[0] is False           # already collecting
    cell.advance(0.25)
    assert not cell.ft_biased                   # 0.1 s window not over yet
    ev = cell.advance(0.5)
    assert cell.ft_biased
    later = [e for e in ev.ft if e.biased is not None]
    assert later
    for j in range(6):
        mean = sum(e.biased[j] for e in later) / len(later)
        assert abs(mean) < (0.01 if j < 3 else 2e-4)


def test_bias_is_refused_while_the_pads_may_be_loaded_as_by_the_driver() -> None:
    """Issue 16 item 1: a bias under load absorbed it (0 N then left 7.7 N on the pads)."""
    h = _grasped()                               # 10 N on the object
    ok, msg = h.cell.bias_ft()
    assert not ok and msg == f'bias refused: {h.cell.bridge.bias_refusal(h.t)}'
    assert '10.0 N is active' in msg and 'finger 1 F/T measures' in msg
    assert not h.cell.bias_in_progress
    h.stop()                                     # 0 V: the pads relax but still touch
    h.run_for(0.5)
    ok, msg = h.cell.bias_ft()
    assert not ok and 'touched something' in msg and 'active' not in msg
    h.release(rebias=False)                      # the runner's release: −8 N for 1 s
    ok, msg = h.cell.bias_ft()
    assert ok, msg
    h.run_until(lambda hh: not hh.cell.bias_in_progress, 1.0)
    ok, _ = h.cell.reset(object_on_table=False)  # held in the air at reset_grasp_force
    h.run_for(0.2)
    ok, msg = h.cell.bias_ft()
    assert not ok and 'squeezing grasp-force target' in msg


def test_squeezing_gives_negative_fz_on_both_sensors_and_the_loop_converges() -> None:
    h = _grasped()
    ev = h.cell.advance(h.t + 0.5)
    for k in (1, 2):
        fz = [e.biased[2] for e in ev.ft if e.finger == k]
        assert sum(fz) / len(fz) == pytest.approx(-10.0, abs=0.1)
    tel = [e.motor for e in ev.telemetry]
    assert all(t.closed_loop and t.bypass_reason == BypassReason.NONE for t in tel)
    measured = sum(t.measured_force for t in tel) / len(tel)
    assert measured == pytest.approx(10.0, abs=0.05)
    assert h.state().normal_force_1 == pytest.approx(10.0, abs=0.1)   # true force, offsets gone
    st = h.cell.status()
    assert st.in_contact and st.ft_biased and st.homed
    assert st.measured_grasp_force == pytest.approx(10.0, abs=0.2)
    assert st.opening == pytest.approx(h.cell.preset.thickness - 10.0 / 2e4, abs=3e-5)
    assert st.voltage_cmd < 0.0                  # negative volts close


def test_unbiased_loop_runs_open_at_the_stall_calibration() -> None:
    cell = _cell()
    cell.home()
    cell.command_grasp_force(10.0, 0.0, 0.0)
    ev = cell.advance(1.5)
    last = ev.telemetry[-1].motor
    assert not last.closed_loop and last.bypass_reason == BypassReason.NOT_BIASED
    assert last.voltage_cmd == pytest.approx(-2.55)            # round(−10/3.9166, 2)
    assert cell.state().normal_force_1 == pytest.approx(3.9166 * 2.55, rel=1e-3)
    assert math.isnan(cell.status().measured_grasp_force)


def test_back_emf_lowers_the_force_while_the_fingers_move() -> None:
    cell = _cell(preset='wood')
    cell.home()
    cell.command_grasp_force(10.0, 0.0, 0.0)
    cell.advance(0.2)
    rate = cell.plant.actuator.rate
    # Free closing at −2.55 V: D ẋ = k_FV V with D = c + k_FV k_e / k_open.
    a = cell.params.actuator
    damp = a.guide_damping + a.newton_per_volt * a.back_emf / a.opening_per_rad
    assert rate == pytest.approx(a.newton_per_volt * -2.55 / damp, rel=1e-6)
    st = cell.status()
    assert st.opening_rate == pytest.approx(rate, rel=0.05)    # observer tracks it


# ---------------------------------------------------------------------------- velocity
@pytest.mark.parametrize('model', ['ideal', 'chips'])
def test_gravity_slip_reads_down_in_gripper_middle_for_both_fingers(model: str) -> None:
    frames = FrameParams()
    cell = _cell(1e-3, velocity_sensor=VelocitySensorParams(model=model),
                 reset_grasp_force=10.0)
    h = Harness(cell)
    h.home()
    h.bias()
    h.reset(object_on_table=False)
    h.command_force(10.0)
    h.run_for(0.3)
    h.command_force(1.5)                         # below m g / (2 μ): slides down
    assert h.run_until(lambda hh: hh.state().vy < -0.03, 1.0)
    truth: list[tuple[float, float]] = []
    samples = []
    for _ in range(40):
        samples.extend(cell.advance(cell.t + 1e-3).velocity)
        truth.append((cell.t, cell.state().vy))
    assert cell.state().in_grasp
    period = 1.0 / cell.params.velocity_sensor.rate
    for k in (1, 2):
        e = [s for s in samples if s.finger == k][-1]
        vx, vy, om = planar_to_middle(frames, k, e.vx, e.vy, e.omega)
        mean = [v for t, v in truth if e.stamp - period < t <= e.stamp + 1e-9]
        assert vy < -0.02                        # object moves down relative to the pads
        assert vy == pytest.approx(sum(mean) / len(mean), abs=0.003)   # period mean
        assert abs(vx) < 0.003 and abs(om) < 0.1


def _push_samples(model: str) -> list:
    cell = _cell(1e-3, preset='wood', velocity_sensor=VelocitySensorParams(model=model))
    h = Harness(cell)
    h.home()
    h.bias()
    h.command_force(10.0)
    h.run_for(1.5)
    h.command_force(5.0)
    h.move(lift=-0.01, duration=0.8, wait=False)
    return cell.advance(cell.t + 1.0).velocity


def test_chip_model_quantises_like_the_device() -> None:
    # Same script, same physics: the ideal sensor gives the true mean twist of each period.
    frames = FrameParams()
    chips, ideal = _push_samples('chips'), _push_samples('ideal')
    assert [e.stamp for e in chips] == [e.stamp for e in ideal]
    period = 1.0 / 120.0
    for k in (1, 2):
        c = [planar_to_middle(frames, k, e.vx, e.vy, e.omega) for e in chips if e.finger == k]
        i = [planar_to_middle(frames, k, e.vx, e.vy, e.omega) for e in ideal if e.finger == k]
        err = [a[1] - b[1] for a, b in zip(c, i)]
        # One count per chip and period is ≈ 0.95 mm/s raw, ≈ 1.0–1.4 mm/s after ÷ b.
        assert max(abs(x) for x in err) < 2.5e-3
        assert max(abs(x) for x in err) > 3e-4           # really quantised
        # Remainders are carried: the integrated displacement is exact to a few counts.
        assert abs(sum(err) * period) < 3 * 7.9375e-6 / 0.7
        assert sum(b[1] for b in i) * period == pytest.approx(0.01, rel=0.02)


# ---------------------------------------------------------------------------- determinism
def _trace(seed: int) -> list[tuple[float, ...]]:
    cell = _cell(1e-3, seed=seed)
    cell.home()
    cell.bias_ft()
    cell.advance(0.2)
    cell.command_grasp_force(8.0, 0.0, 0.0)
    ev = cell.advance(0.6)
    return ([e.raw for e in ev.ft]
            + [(e.status.voltage_cmd, e.status.motor_angle) for e in ev.telemetry]
            + [(e.vx, e.vy, e.omega) for e in ev.velocity])


def test_deterministic_with_a_seed() -> None:
    a, b, c = _trace(3), _trace(3), _trace(4)
    assert a == b
    assert a != c


# ---------------------------------------------------------------------------- telemetry
def test_motor_angle_is_encoder_quantised_and_printed_with_four_decimals() -> None:
    enc = MotorEncoder(4096)
    q = 2.0 * math.pi / 4096
    for angle in (-9.2215, 0.0, 1.23456789, 3.0):
        r = enc.read(angle)
        assert r == round(r, 4)
        assert abs(r - angle) <= q / 2 + 5e-5
    cell = _cell()
    ev = cell.advance(0.05)
    assert ev.telemetry[0].status.motor_angle == 0.0     # power-up at the open stop


def test_stop_applies_zero_volts_and_clears_the_target() -> None:
    h = _grasped()
    h.stop()
    ev = h.cell.advance(h.t + 0.1)
    assert all(t.motor.voltage_cmd == 0.0 and t.motor.bypass_reason == BypassReason.SAFE_STATE
               and t.status.safe_state for t in ev.telemetry)
    h.run_for(0.5)
    assert h.state().normal_force_1 < 0.05       # the fingers were pushed open passively


# ---------------------------------------------------------------------------- homing
def test_home_refuses_on_contact_and_with_an_active_target() -> None:
    h = _grasped()
    ok, msg = h.cell.home()
    assert not ok and 'grasp-force command' in msg
    h.command_force(0.0)                 # no active squeeze, but the pads still press
    ok, msg = h.cell.home()
    assert not ok and 'contact' in msg


def test_homing_sequence_finds_the_stroke_of_an_empty_gripper() -> None:
    cell = _cell(1e-3, homing_mode='sequence')
    cell.reset('wood')
    cell.plant.arm.place(0.0, 0.5, 0.0)           # gripper away from the object
    h = Harness(cell)
    assert not cell.homed
    h.home(timeout=20.0)
    assert cell.homed
    # Resting at the open stop; the zero was taken with the pads squeezed (≈ 16 µm at 4 V)
    # and the encoder resolves 13 µm of opening.
    assert cell.plant.actuator.x == pytest.approx(0.08)
    assert cell.status().opening == pytest.approx(0.08, abs=4e-5)
    # A stop aborts a running sequence (and homing is then invalid until redone).
    cell.home()
    h.run_for(0.2)
    assert cell.homing_active and not cell.homed
    cell.stop()
    h.run_for(0.1)
    assert not cell.homing_active and not cell.homed
    assert cell.status().voltage_cmd == 0.0


# ---------------------------------------------------------------------------- arm, reset
def test_arm_moves_with_a_smooth_profile_and_refuses_while_moving() -> None:
    cell = _cell()
    ok, msg, end = cell.move_gripper(0.1, 0.02, 0.3, 1.0)
    assert ok and end == pytest.approx(1.0)
    assert cell.arm_moving
    assert cell.move_gripper(0.1, 0.0, 0.0, 1.0)[0] is False
    cell.advance(0.5)
    s = cell.state()
    assert s.arm_height == pytest.approx(cell.preset.height_below + 0.05, abs=1e-9)
    assert s.arm_angle == pytest.approx(0.15, abs=1e-9)
    cell.advance(1.1)
    s = cell.state()
    assert not s.arm_moving and s.arm_lateral == pytest.approx(0.02)
    assert s.arm_angle == pytest.approx(0.3)


def test_reset_keeps_time_and_places_the_scene() -> None:
    h = _grasped()
    h.move(lift=0.1)
    t = h.t
    ok, msg = h.cell.reset('case')
    assert ok and 'case' in msg
    s = h.state()
    assert s.stamp == pytest.approx(t) and s.scenario_time == 0.0
    assert s.on_table and not s.in_grasp and s.preset == 'case'
    assert s.opening == pytest.approx(0.08) and s.arm_height == pytest.approx(0.09)
    assert h.cell.ft_biased and h.cell.homed
    ok, _ = h.cell.reset(object_on_table=False)
    h.run_for(0.5)
    s = h.state()
    assert ok and s.in_grasp and not s.on_table
    assert s.normal_force_1 == pytest.approx(10.0, abs=0.2)
    assert h.cell.true_contact() == (h.cell.preset.finger_1, h.cell.preset.finger_2)


# ---------------------------------------------------------------------------- bad input
def test_bad_commands_are_rejected_with_a_message() -> None:
    cell = _cell()
    for value, text in ((math.nan, 'finite'), (math.inf, 'finite'), (500.0, 'range')):
        ok, msg = cell.command_grasp_force(value, 0.0, 0.0)
        assert not ok and text in msg
    assert 'timeout' in cell.command_grasp_force(5.0, 0.0, -1.0)[1]
    assert 'future' in cell.command_grasp_force(5.0, 10.0, 0.0)[1]
    assert cell.command_grasp_force(5.0, 0.0, 0.0) == (True, 'accepted')
    assert cell.move_gripper(math.nan, 0.0, 0.0, 1.0)[0] is False
    assert cell.move_gripper(0.0, 0.0, 0.0, 0.0)[0] is False
    assert cell.apply_disturbance(1.0, math.inf, 0.0, 1.0)[0] is False
    assert cell.apply_disturbance(1.0, 0.0, 0.0, -1.0)[0] is False
    ok, msg = cell.reset('unobtainium')
    assert not ok and 'wood' in msg and 'unobtainium' in msg
    assert cell.state().preset == 'wood'


def test_unknown_preset_lists_the_known_ones() -> None:
    with pytest.raises(KeyError, match='cardboard.*case.*plastic.*wood'):
        SimCell(SimParams(), reference_presets(), 'glass')


def test_invalid_presets_name_the_field() -> None:
    good = reference_presets()['wood']
    bad = ObjectPreset(**{**good.__dict__, 'mass': -0.2})
    with pytest.raises(PresetError, match='mass'):
        SimCell(SimParams(), {'bad': bad}, 'bad')
    with pytest.raises(PresetError, match='mu_s'):
        ObjectPreset(**{**good.__dict__, 'finger_1': ContactPreset(0.5, 0.4, 0.0, 0.005)}
                     ).validate()
    with pytest.raises(PresetError, match='thickness'):
        preset_from_dict('x', {'mass': 0.1, 'width': 0.05, 'height_below': 0.05,
                               'height_above': 0.05, 'thickness': 0.0,
                               'finger_1': {'mu_c': 0.4, 'r': 0.005},
                               'finger_2': {'mu_c': 0.4, 'r': 0.005}})
    with pytest.raises(PresetError, match='unknown keys'):
        preset_from_dict('x', {'mass': 0.1, 'colour': 'red'})


def test_invalid_params_name_the_field() -> None:
    with pytest.raises(ParameterError, match='physics_dt'):
        SimParams(physics_dt=-1e-4).validate()
    with pytest.raises(ParameterError, match='model'):
        SimParams(model='magic').validate()
    with pytest.raises(ParameterError, match='rates.ft'):
        SimParams(physics_dt=2e-3).validate()
    with pytest.raises(ParameterError, match='ft.offset_1'):
        SimParams(ft=FtSensorParams(offset_1=(0.0, 0.0))).validate()
    with pytest.raises(ParameterError, match='surface'):
        SimParams(surface='blob').validate()


def test_params_round_trip_through_the_parameter_schema() -> None:
    flat = flatten(SimParams())
    assert flat['ft.noise_std'] == 0.02 and flat['velocity_sensor.model'] == 'chips'
    assert flat['force_control.kp'] == 2.0 and flat['frames.pad_offset'] == 0.0078
    params = from_flat(SimParams, {**flat, 'physics_dt': 5e-4, 'actuator.model': 'first_order'})
    assert params.physics_dt == 5e-4 and params.actuator.model == 'first_order'
    with pytest.raises(ParameterError, match='velocity_sensor.model'):
        from_flat(SimParams, {'velocity_sensor.model': 'laser'})


def test_first_order_actuator_follows_the_command() -> None:
    from friction_models.core.plant import SimActuatorParams
    h = _grasped(actuator=SimActuatorParams(model='first_order'))
    assert h.state().normal_force_1 == pytest.approx(10.0, abs=0.1)
    h.command_force(20.0)
    h.run_for(0.5)
    assert h.state().normal_force_1 == pytest.approx(20.0, abs=0.2)


# ---------------------------------------------------------------------------- presets
def test_config_presets_add_to_the_reference_objects_without_copying_them() -> None:
    """One definition: the reference objects live in core/reference_objects.yaml only; the
    node's config file adds objects (nothing there to keep in sync)."""
    from friction_models.core.presets import REFERENCE_FILE
    own = load_presets(CONFIG, include_reference=False)
    ref = reference_presets()
    assert sorted(ref) == ['cardboard', 'case', 'plastic', 'wood']
    assert ref == load_presets(REFERENCE_FILE, include_reference=False)
    assert not set(own) & set(ref), 'config/sim_presets.yaml redefines a reference object'
    assert 'offset_box' in own
    assert load_presets(CONFIG) == {**ref, **own}
    # The reference geometry: uniform boxes with the CoM at the box centre.
    card = ref['cardboard']
    assert card.inertia == pytest.approx(0.08 * (0.08 ** 2 + 0.14 ** 2) / 12.0)
    assert card.com_offset == pytest.approx((0.0, -0.01))


def test_reference_contacts_match_the_csv() -> None:
    ref = reference_presets()
    with CSV.open() as f:
        for row in csv.DictReader(f):
            c = ref[row['object']].contact(int(row['finger']))
            assert c.mu_c == pytest.approx(float(row['mu_c']), abs=1e-6)
            assert c.mu_s == pytest.approx(float(row['mu_s']), abs=1e-4)
            assert c.mu_v == pytest.approx(float(row['mu_v_per_m_per_s']), abs=1e-5)
            if (row['object'], row['finger']) == ('wood', '2'):
                assert float(row['r_m']) < 0.001 and c.r == ref['wood'].finger_1.r
            else:
                assert c.r == pytest.approx(float(row['r_m']), abs=1e-6)


def test_load_presets_reports_the_file(tmp_path: Path) -> None:
    bad = tmp_path / 'bad.yaml'
    bad.write_text('presets:\n  x: {mass: -1, width: 0.05, height_below: 0.05, '
                   'height_above: 0.05, thickness: 0.04, finger_1: {mu_c: 0.4, r: 0.005}, '
                   'finger_2: {mu_c: 0.4, r: 0.005}}\n')
    with pytest.raises(PresetError, match=r'bad\.yaml.*mass'):
        load_presets(bad)
    (tmp_path / 'empty.yaml').write_text('{}\n')
    with pytest.raises(PresetError, match='presets'):
        load_presets(tmp_path / 'empty.yaml')


def test_events_merge_in_time_order() -> None:
    ev = SimEvents()
    assert list(ev) == [] and len(ev) == 0
    cell = _cell()
    ev = cell.advance(0.02)
    kinds = [type(e).__name__ for e in ev if e.stamp == pytest.approx(0.002)]
    assert kinds == ['FtSample', 'FtSample', 'LineResult']


@pytest.mark.parametrize('noise', [0.0, 0.8])
def test_chip_counts_follow_the_count_quantizer(noise: float) -> None:
    # The sensor feeds b·A·(x, y, θ) of each chip axis to the package's counter model
    # (carried remainders, saturation, count noise): same counts as its array interface.
    params = VelocitySensorParams(count_noise_std=noise, poll_period=0.004)
    sensor = VelocitySensor(1, params, (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0),
                            np.random.default_rng(3))
    polls = max(1, int(round(sensor.period / params.poll_period)))
    chip = ChipModelParams(max_counts=127 * polls, count_noise_std=noise,
                           poll_period=params.poll_period)
    quantizer = CountQuantizer(6, chip, np.random.default_rng(3) if noise else None)
    a = RigidBodyFusion(FusionParams(radius=params.radius)).matrix
    gains = np.asarray(params.chip_gains_1)
    rng = np.random.default_rng(5)
    saturated = 0
    for k in range(3000):
        d = rng.normal(scale=[5e-5, 5e-5, 2e-3]) * (10.0 ** rng.integers(-3, 3))
        expected = quantizer.read(gains * (a @ d))
        saturated += int(np.any(np.abs(expected) == chip.max_counts))
        assert sensor._read_counts(*d.tolist()) == expected.tolist(), k
    assert saturated > 0
