# SPDX-License-Identifier: Apache-2.0
"""The model-based slip laws (control law ``model``): friction-model feed-forward against the
pre-computed limit surface, the slip observer, refusals with their reasons, control-law
selection, and closed loops on the toy plant (docs/model_slip_control.md)."""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np
import pytest

from friction_models.core.limit_surface import LimitSurface
from friction_models.core.surfaces import standard_surface
from slip_control.core.contact import ContactProperties, ContactSource, FingerContact
from slip_control.core.controllers import (ControlContact, ControlOutput, HoldController,
                                           LinearController, SlipMode)
from slip_control.core.mode_switch import (CONTROLLERS, ModeRequest, build_controller,
                                           resolve_control_law)
from slip_control.core.model_linear import ModelLinearController
from slip_control.core.model_rotational import ModelRotationalController
from slip_control.core.params import CONTROL_LAWS, PRESSURE_SHAPES, SlipControllerParams
from slip_control.core.signals import SensorSnapshot
from slip_control.core.slip_model import GRID_N, N_LS, PATCH_SIZE, ContactModel
from slip_control.core.slip_observer import ObserverNoise, SlipObserver
from slip_control.core.toy_plant import COUNT_M, ClosedLoop, ToyPlant, ToyPlantParams

DT = 1.0 / 120.0
LIN, ROT = int(SlipMode.LINEAR), int(SlipMode.ROTATIONAL)
Snap = Callable[..., SensorSnapshot]


def contact(mu_c: float = 0.4, mu_s: float | None = None, mu_v: float = 0.0,
            r: float = 0.005) -> ContactProperties:
    """Two identical fingers, ESTIMATED and valid."""
    f = FingerContact(mu_c=mu_c, mu_s=mu_c if mu_s is None else mu_s, mu_v=mu_v, r=r,
                      linear_valid=True, rotational_valid=True, static_valid=True,
                      viscous_valid=True)
    return ContactProperties(f, f, ContactSource.ESTIMATED)


# --- feed-forward: the friction model against the limit-surface table -------------------------

def test_translation_coefficient_is_the_stribeck_curve_of_both_pads() -> None:
    f1 = FingerContact(mu_c=0.5, mu_s=0.7, mu_v=2.0, r=0.006)
    f2 = FingerContact(mu_c=0.3, mu_s=0.45, mu_v=1.0, r=0.007)
    m = ContactModel(ContactProperties(f1, f2, ContactSource.ESTIMATED), 'circle', 1e-3)
    assert m.translation_coefficient(0.0) == pytest.approx(0.575)          # mean μ_s at rest
    v = 0.0125                                                              # 12 v_s: kinetic
    assert m.translation_coefficient(v) == pytest.approx(0.4 + 1.5 * v, rel=1e-6)
    # In between it falls monotonically (Stribeck), never below μ_c + μ_v·v.
    speeds = np.linspace(1e-5, 0.005, 40)
    c = [m.translation_coefficient(float(s)) for s in speeds]
    assert all(a >= b - 1e-12 for a, b in zip(c[:20], c[1:21]))
    assert all(ci >= 0.4 + 1.5 * s - 1e-9 for ci, s in zip(c, speeds))
    assert m.translation_force(2.0, v) == pytest.approx(2.0 / (0.4 + 1.5 * v), rel=1e-6)


@pytest.mark.parametrize('shape', ['circle', 'square', 'line'])
@pytest.mark.parametrize('ratio', [0.3, 1.0, 3.0])
def test_rotation_force_lies_on_the_limit_surface(shape: str, ratio: float) -> None:
    """The force and twist found carry the load exactly on the pre-computed limit surface:
    checked against the table's own lookup, with Coulomb friction (μ_s = μ_c, no viscous)."""
    mu, r = 0.5, 0.006
    m = ContactModel(contact(mu, r=r), shape, 1e-3)
    table = LimitSurface.build(standard_surface(shape, GRID_N, PATCH_SIZE), N_LS)
    f, tau = 1.0, ratio * 1.0 * r                       # per pad [N], [N·m]
    sol = m.rotation_force(f, tau, 0.2)
    w = 0.2
    v = r * w * math.tan(sol.psi)
    hx, hy, ht = table.lookup(v, 0.0, w, r_a=r)          # normalised, against the motion
    assert sol.force * mu * abs(hx) == pytest.approx(f, rel=0.01)
    assert sol.force * mu * r * abs(ht) == pytest.approx(tau, rel=0.01)
    assert sol.translation_per_rad == pytest.approx(r * math.tan(sol.psi))
    # The ellipsoidal approximation D/μ of the thesis HOLD is close on the circle and the
    # square; the line map's limit surface is not an ellipsoid (that is why the table is used).
    ellipse = math.hypot(f, tau / r) / mu
    if shape != 'line':
        assert sol.force == pytest.approx(ellipse, rel=0.12)


def test_slide_force_with_a_torque_needs_more_than_the_force_alone() -> None:
    m = ContactModel(contact(0.5, r=0.006), 'circle', 1e-3)
    alone = m.slide_force(1.0, 0.0, 0.01)
    assert alone == pytest.approx(m.translation_force(1.0, 0.01))
    with_torque = [m.slide_force(1.0, k * 0.006, 0.01) for k in (0.1, 0.5, 1.0, 2.0)]
    assert alone < with_torque[0] < with_torque[1] < with_torque[2] < with_torque[3]
    assert with_torque[2] == pytest.approx(math.sqrt(2.0) / 0.5, rel=0.12)   # ≈ D/μ


def test_model_needs_mu_c_but_borrows_a_missing_r() -> None:
    f = FingerContact(mu_c=0.4, r=float('nan'))
    m = ContactModel(ContactProperties(f, f, ContactSource.ESTIMATED), 'circle', 1e-3,
                     fallback_r=0.004)
    assert not m.r_valid and m.r == pytest.approx(0.004)
    with pytest.raises(ValueError, match='mu_c'):
        ContactModel(ContactProperties(FingerContact(), f, ContactSource.ESTIMATED),
                     'circle', 1e-3)


def test_pressure_shapes_and_laws_are_the_known_ones() -> None:
    from friction_models.core.surfaces import STANDARD_SURFACES
    assert PRESSURE_SHAPES == STANDARD_SURFACES
    assert CONTROL_LAWS == ('thesis', 'model')


# --- observer ---------------------------------------------------------------------------------

def _chip_positions(v: Callable[[float], float], n: int, count_noise: float = 0.0,
                    seed: int = 0) -> list[tuple[float, float, float]]:
    """(t, travel, the sample's own rate) of a motion sampled like the chips: whole counts per
    sample, optionally with extra random counts (``count_noise`` 1-σ per sample)."""
    rng = np.random.default_rng(seed)
    out, x, counted = [], 0.0, 0
    travel = 0
    for i in range(1, n + 1):
        t = i * DT
        x += v(t) * DT
        counts = int(math.floor(x / COUNT_M)) - counted
        counted += counts
        counts += int(round(rng.normal(0.0, count_noise))) if count_noise else 0
        travel += counts
        out.append((t, travel * COUNT_M, counts * COUNT_M / DT))
    return out


@pytest.mark.parametrize('speed', [0.002, 0.0125])
def test_observer_gives_a_clean_rate_from_noisy_travel(speed: float) -> None:
    """With a count of noise per sample the chips' own rate jumps by ~1 mm/s; the filtered
    rate is cleaner, unbiased, and its position stays on the travel."""
    obs = SlipObserver(ObserverNoise(jerk_psd=0.01, position=1e-5))
    samples = _chip_positions(lambda t: speed, 360, count_noise=1.0)
    errors = []
    for i, (t, x, _rate) in enumerate(samples):
        est = obs.step(DT if i else 0.0, position=x)
        if t > 1.0:
            errors.append(est.rate - speed)
    raw = [s[2] - speed for s in samples[120:]]
    rms = float(np.sqrt(np.mean(np.square(errors))))
    assert rms < 0.7 * float(np.sqrt(np.mean(np.square(raw))))
    assert abs(float(np.mean(errors))) < 2e-4
    assert est.position == pytest.approx(samples[-1][1], abs=3e-5)


def test_observer_sees_the_start_of_motion_within_a_few_samples() -> None:
    obs = SlipObserver(ObserverNoise(jerk_psd=0.01, position=1e-5))
    onset = 0.2
    samples = _chip_positions(lambda t: 0.0 if t < onset else 0.02, 60)
    seen = None
    for i, (t, x, _rate) in enumerate(samples):
        est = obs.step(DT if i else 0.0, position=x)
        if seen is None and est.rate > 0.002:
            seen = t
        if t < onset:
            assert abs(est.rate) < 1e-3                  # at rest it reads rest
    assert seen is not None and seen - onset <= 3 * DT


def test_observer_fuses_an_acceleration_measurement() -> None:
    noise = ObserverNoise(jerk_psd=0.01, position=1e-5)
    with_acc, without = SlipObserver(noise), SlipObserver(noise)
    a = 0.5                     # a break-away at 0.5 m/s², seen for 3 samples (whole counts)
    for i in range(1, 4):
        x = math.floor(0.5 * a * (i * DT) ** 2 / COUNT_M) * COUNT_M
        without.step(DT, position=x)
        est = with_acc.step(DT, position=x, accel=a, accel_std=0.05)
    assert est.accel == pytest.approx(a, rel=0.25)
    assert abs(est.accel - a) < 0.5 * abs(without.estimate.accel - a)
    assert abs(est.rate - a * 3 * DT) < abs(without.estimate.rate - a * 3 * DT)
    with pytest.raises(ValueError):
        with_acc.update_accel(1.0, 0.0)


# --- control-law selection and refusals --------------------------------------------------------

def _loaded(snap: Snap, f: tuple[float, float] = (0.0, -1.0), tz: float = 0.0,
            normal: float = 5.0) -> SensorSnapshot:
    """Two samples (so the travel has a reference) of a held, loaded object at rest."""
    snap(0.99, f=f, tz=tz, normal=normal)
    return snap(1.0, f=f, tz=tz, normal=normal)


def test_control_law_selection(snap: Snap) -> None:
    p = SlipControllerParams()
    props = contact(0.4, 0.5)
    inputs = _loaded(snap)
    thesis = build_controller(ModeRequest(LIN, 2.0, 0.02, latch_direction=True), props, p,
                              1.0, inputs=inputs)
    assert thesis.ok and isinstance(thesis.controller, LinearController)
    assert thesis.control_law == 'thesis'
    model = build_controller(ModeRequest(LIN, 2.0, 0.02, latch_direction=True,
                                         control_law='model'), props, p, 1.0, inputs=inputs)
    assert model.ok and isinstance(model.controller, ModelLinearController)
    assert model.control_law == 'model' and '(model law)' in model.message
    # The parameter default applies to requests that name no law.
    pm = replace(p, default_control_law='model')
    by_default = build_controller(ModeRequest(LIN, 2.0, 0.02), props, pm, 1.0, inputs=inputs)
    assert isinstance(by_default.controller, ModelLinearController)
    named = build_controller(ModeRequest(LIN, 2.0, 0.02, control_law='thesis'), props, pm, 1.0,
                             inputs=inputs)
    assert isinstance(named.controller, LinearController)
    bad = build_controller(ModeRequest(LIN, 2.0, 0.02, control_law='pid'), props, p, 1.0,
                           inputs=inputs)
    assert not bad.ok and "unknown control_law 'pid'" in bad.message
    # Every mode has its thesis law; the dispatch table is keyed by (mode, law).
    assert all((m, 'thesis') in CONTROLLERS for m in SlipMode if m != SlipMode.OFF)
    assert {(SlipMode.LINEAR, 'model'), (SlipMode.ROTATIONAL, 'model')} <= set(CONTROLLERS)


def test_every_mode_resolves_the_law_it_is_asked_for() -> None:
    p = replace(SlipControllerParams(), default_control_law='model')
    for mode in SlipMode:
        for law in CONTROL_LAWS:
            assert resolve_control_law(ModeRequest(int(mode), control_law=law), p) == (law, '')
        assert resolve_control_law(ModeRequest(int(mode)), p) == ('model', '')
    law, why = resolve_control_law(ModeRequest(LIN, control_law='Model'), p)
    assert law == '' and "unknown control_law 'Model'" in why


@pytest.mark.parametrize('request_, props, inputs_kw, text', [
    # 0.5 N per pad against μ_s·min_force = 1.2 · 0.6 N: static friction holds it.
    (ModeRequest(LIN, 2.0, 0.02, latch_direction=True, control_law='model'),
     contact(1.0, 1.2), {'f': (0.0, -0.5)}, 'cannot overcome static friction 0.72 N'),
    # Commanded sideways, the load pulls down.
    (ModeRequest(LIN, 2.0, 0.02, direction=(1.0, 0.0, 0.0), control_law='model'),
     contact(0.4, 0.5), {'f': (0.0, -1.0)}, 'points 90 deg away from the requested direction'),
    # Holding 20 N per pad at μ_c 0.4 needs 50 N.
    (ModeRequest(LIN, 2.0, 0.02, latch_direction=True, control_law='model'),
     contact(0.4, 0.5), {'f': (0.0, -20.0), 'normal': 30.0}, 'more than the maximum force'),
    # The torque turns the object the other way.
    (ModeRequest(ROT, 2.0, angle=0.35, control_law='model'), contact(0.4, 0.5, r=0.005),
     {'f': (0.0, -1.0), 'tz': -0.02}, 'turns the object the other way'),
    # A 1 mm lever against r = 8 mm: the grasp point would slide far while it turns.
    (ModeRequest(ROT, 2.0, angle=0.35, control_law='model'), contact(0.4, 0.5, r=0.008),
     {'f': (0.0, -1.0), 'tz': 0.001}, 'too short for the torsional radius'),
    # A light torque that static torsional friction holds at the minimum force.
    (ModeRequest(ROT, 2.0, angle=0.35, control_law='model'), contact(1.0, 1.2, r=0.008),
     {'f': (0.0, -0.1), 'tz': 0.003}, 'cannot overcome static torsional friction'),
    # No contact: the pads measure no grasp force.
    (ModeRequest(LIN, 2.0, 0.02, latch_direction=True, control_law='model'),
     contact(0.4, 0.5), {'f': (0.0, -1.0), 'normal': 0.0}, 'no contact'),
])
def test_infeasible_requests_are_refused_with_the_reason(
        snap: Snap, request_: ModeRequest, props: ContactProperties, inputs_kw: dict,
        text: str) -> None:
    p = SlipControllerParams()
    previous = HoldController(p, ControlContact.from_properties(props), initial_force=7.0)
    out = build_controller(request_, props, p, 1.0, previous=previous,
                           inputs=_loaded(snap, **inputs_kw))
    assert not out.ok and out.controller is None
    assert text in out.message and 'refused' in out.message
    assert previous.last_force == 7.0                    # nothing changed


def test_model_law_refuses_without_sensor_samples() -> None:
    out = build_controller(ModeRequest(LIN, 2.0, 0.02, control_law='model'),
                           contact(0.4, 0.5), SlipControllerParams(), 1.0, inputs=None)
    assert not out.ok and 'no F/T samples' in out.message


def test_feasible_requests_take_their_direction_from_the_load(snap: Snap) -> None:
    p = SlipControllerParams()
    inputs = _loaded(snap, f=(0.6, -0.8), tz=0.01)
    lin = build_controller(ModeRequest(LIN, 2.0, 0.02, latch_direction=True,
                                       control_law='model'), contact(0.4, 0.5), p, 1.0,
                           inputs=inputs).controller
    assert isinstance(lin, ModelLinearController)
    assert lin.direction == pytest.approx((0.6, -0.8))
    assert lin.mass == pytest.approx(2.0 * 1.0 / 9.81)
    rot = build_controller(ModeRequest(ROT, 2.0, angle=0.35, latch_direction=True,
                                       control_law='model'), contact(0.4, 0.5), p, 1.0,
                           inputs=inputs).controller
    assert isinstance(rot, ModelRotationalController) and rot.sign == 1.0


# --- closed loops on the toy plant ------------------------------------------------------------

class _Record:
    """Outputs and the plant's true position when each was produced."""

    def __init__(self, plant: ToyPlant | None = None) -> None:
        self.plant = plant
        self.outputs: list[tuple[float, ControlOutput]] = []
        self.truth: list[float] = []

    def __call__(self, t: float, out: ControlOutput) -> None:
        self.outputs.append((t, out))
        self.truth.append(self.plant.state.pos if self.plant is not None else math.nan)


def _held(seed: int, pp: ToyPlantParams, kind: str = 'linear'
          ) -> tuple[ToyPlant, ClosedLoop, ContactProperties]:
    plant = ToyPlant(pp, kind=kind, seed=seed)
    f = FingerContact(mu_c=pp.mu_c, mu_s=pp.mu_s, mu_v=pp.mu_v, r=pp.r, linear_valid=True,
                      rotational_valid=True, static_valid=True, viscous_valid=True)
    props = ContactProperties(f, f, ContactSource.ESTIMATED)
    loop = ClosedLoop(plant)
    loop.run(HoldController(SlipControllerParams(), ControlContact.from_properties(props),
                            initial_force=pp.initial_force), 1.0)
    return plant, loop, props


@pytest.mark.parametrize('seed, mu_s', [(0, 0.44), (1, 0.6), (2, 0.64)])
def test_model_linear_tracks_the_whole_trapezoid_and_ends_on_time(seed: int,
                                                                  mu_s: float) -> None:
    """Static friction up to 1.6 μ_c: break-away, then the whole trajectory, ending at T."""
    pp = ToyPlantParams(mu_s=mu_s, actuator_tau=0.01)      # the cell's loop: ~10 ms to 90 %
    plant, loop, props = _held(seed, pp)
    p = SlipControllerParams()
    x0, t0 = plant.state.pos, plant.state.t
    out = build_controller(ModeRequest(LIN, 2.0, 0.02, latch_direction=True,
                                       control_law='model'), props, p, t0,
                           inputs=loop.snapshot)
    assert out.ok, out.message
    rec = _Record(plant)
    loop.run(out.controller, 3.5, on_output=rec)
    results = [o.result for _, o in rec.outputs if o.result is not None]
    assert len(results) == 1 and results[0].message == 'done' and results[0].success
    assert results[0].elapsed == pytest.approx(2.0, abs=0.2)           # on time (±10 %)
    slid = plant.state.pos - x0
    assert slid == pytest.approx(0.02, abs=0.001)                       # plant truth
    rows = [(o.tracking, x - x0) for (_, o), x in zip(rec.outputs, rec.truth)
            if o.tracking is not None]
    err = np.array([tr.ref_pos - x for tr, x in rows])
    assert float(np.sqrt(np.mean(err ** 2))) <= 0.001
    assert max(o.force for _, o in rec.outputs if o.force is not None) <= 40.0


def test_model_linear_ends_no_slip_when_the_contact_holds_better_than_estimated() -> None:
    """The estimate says it slides at 0.6 N; the real contact holds it even there."""
    pp = ToyPlantParams(mass=0.05, mu_c=1.0, mu_s=1.2, initial_force=2.0)
    plant, loop, props = _held(0, pp)
    weak = contact(0.2, 0.22, mu_v=pp.mu_v, r=pp.r)
    p = SlipControllerParams()
    out = build_controller(ModeRequest(LIN, 2.0, 0.02, latch_direction=True,
                                       control_law='model'), weak, p, plant.state.t,
                           inputs=loop.snapshot)
    assert out.ok, out.message
    rec = _Record()
    loop.run(out.controller, 3.5, on_output=rec)
    results = [o.result for _, o in rec.outputs if o.result is not None]
    assert len(results) == 1 and not results[0].success
    assert results[0].message.startswith('no slip at minimum force: 0.0 of 20.0 mm')


def test_thesis_law_reports_a_stall_instead_of_done() -> None:
    """Before issue 15 this ended "done" at T with 0 of 20 mm (settled = done)."""
    pp = ToyPlantParams(mass=0.05, mu_c=1.0, mu_s=1.2, initial_force=2.0)
    plant, loop, props = _held(0, pp)
    p = SlipControllerParams()
    ctrl = LinearController(p, ControlContact.from_properties(props), 0.02, 2.0,
                            plant.state.t, direction=(0.0, -1.0))
    rec = _Record()
    loop.run(ctrl, 3.5, on_output=rec)
    results = [o.result for _, o in rec.outputs if o.result is not None]
    assert len(results) == 1 and not results[0].success
    assert results[0].message == 'stalled at the minimum force: 0.0 of 20.0 mm'
    assert results[0].elapsed == pytest.approx(3.0, abs=2 * DT)       # T + settle_timeout


# --- plumbing: the runner names its law on every slip request; messages carry it --------------

@pytest.mark.parametrize('law', ['', 'model', 'thesis'])
def test_runner_names_its_control_law_on_every_slip_request(law: str) -> None:
    from slip_control.core.params import ExperimentRunnerParams
    from slip_control.core.runner_sequences import build_sequence
    from slip_control.core.runner_steps import Action
    seq = build_sequence('demo', replace(ExperimentRunnerParams(), control_law=law))
    requests = [s.args['request'] for s in (*seq.steps, *seq.cleanup)
                if s.action == Action.SET_SLIP_MODE]
    assert len(requests) >= 6
    assert {r.control_law for r in requests} == {law}
    # A request that names its own law keeps it.
    from slip_control.core.runner_steps import StepBuilder
    step = StepBuilder(replace(ExperimentRunnerParams(), control_law='model')).mode(
        'x', ModeRequest(LIN, 2.0, 0.02, control_law='thesis'))
    assert step.args['request'].control_law == 'thesis'


def test_slip_messages_carry_the_control_law() -> None:
    from slip_msgs.action import ExecuteSlip
    from slip_msgs.srv import SetSlipMode
    from slip_control.slip_msgs_conv import mode_request
    req = SetSlipMode.Request(mode=LIN, duration=2.0, distance=0.02, control_law='model')
    assert mode_request(req).control_law == 'model'
    goal = ExecuteSlip.Goal(mode=ROT, duration=2.0, angle=0.3)
    assert mode_request(goal).control_law == ''
