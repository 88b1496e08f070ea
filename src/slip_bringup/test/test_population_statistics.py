# SPDX-License-Identifier: Apache-2.0
"""Population statistics, feasibility criteria and the local backend (no ROS)."""
from __future__ import annotations

import dataclasses
import math

import pytest

from friction_models.core.population import PopulationRanges, draw_object, draw_population
from friction_models.core.presets import ContactPreset, ObjectPreset

from slip_bringup.population.backends import run_local
from slip_bringup.population.feasibility import assess, hold_force_needed, hold_force_needed_held
from slip_bringup.population.statistics import best_split, distribution, wilson_interval


def test_wilson_interval_matches_known_values() -> None:
    r = wilson_interval(97, 100)
    assert r.value == pytest.approx(0.97)
    # Wilson 95 % interval of 97/100 (textbook value 0.9155-0.9897).
    assert r.low == pytest.approx(0.9155, abs=5e-4)
    assert r.high == pytest.approx(0.9897, abs=5e-4)
    assert wilson_interval(0, 10).low == 0.0
    assert wilson_interval(10, 10).high == pytest.approx(1.0)
    assert wilson_interval(0, 10).high == pytest.approx(0.2775, abs=5e-4)
    with pytest.raises(ValueError):
        wilson_interval(11, 10)


def test_distribution_ignores_nan_and_uses_magnitudes() -> None:
    d = distribution([0.1, -0.3, math.nan, 0.2])
    assert d.count == 3 and d.median == pytest.approx(0.2) and d.max == pytest.approx(0.3)
    assert distribution([]).count == 0


def test_best_split_finds_the_separating_parameter() -> None:
    mass = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6]
    noise = [0.3, 0.1, 0.6, 0.2, 0.5, 0.4]
    failed = [False, False, False, False, True, True]
    split = best_split({'mass': mass, 'noise': noise}, failed)
    assert split is not None and split.parameter == 'mass' and split.failures_above
    assert 0.4 < split.threshold < 0.5 and split.accuracy == 1.0
    assert best_split({'mass': mass}, [False] * 6) is None


def test_population_is_deterministic_and_index_independent() -> None:
    a = draw_population(7, 5)
    assert draw_object(7, 3) == a[3]
    assert draw_object(8, 3) != a[3]
    for o in a:
        o.preset.validate()
        assert 0.05 <= o.preset.mass <= 1.0
        assert math.hypot(*o.preset.com_offset) <= 0.040 + 1e-12


def test_population_rejects_bad_ranges() -> None:
    with pytest.raises(ValueError, match='static_ratio'):
        draw_object(1, 0, PopulationRanges(static_ratio=(0.8, 1.2)))
    with pytest.raises(ValueError, match='seed'):
        draw_object(-1, 0)


def _box(mass: float, mu: float, r: float, com: tuple[float, float]) -> ObjectPreset:
    c = ContactPreset(mu_c=mu, mu_s=mu, mu_v=0.0, r=r)
    return ObjectPreset(name='box', mass=mass, inertia=1e-4, com_offset=com, width=0.1,
                        height_below=0.08, height_above=0.06, thickness=0.04, finger_1=c,
                        finger_2=c)


def test_feasibility_criteria() -> None:
    light = _box(0.05, 1.2, 0.005, (0.0, -0.02))
    f = assess(light, [])
    assert f.hold == '' and 'static friction' in f.linear
    heavy = _box(1.0, 0.15, 0.005, (0.0, -0.03))
    assert hold_force_needed(heavy, []) == pytest.approx(9.81 / 0.3)
    assert 'gripper gives' in assess(heavy, [(0.0, -5.0, 0.0)]).hold
    short = _box(0.3, 0.5, 0.008, (0.0, -0.004))
    f = assess(short, [])
    assert 'lever' in f.rotational and 'drags' in f.hinge
    long = _box(0.2, 0.6, 0.005, (0.0, -0.03))
    f = assess(long, [])
    assert (f.hold, f.linear, f.rotational, f.hinge) == ('', '', '', '')


def test_hold_force_needed_counts_the_lever_of_a_push() -> None:
    # CoM 30 mm beside the grasp point: the weight alone twists with 9.81 N·kg⁻¹ x 0.03 m.
    side = _box(1.0, 0.5, 0.005, (0.03, 0.0))
    w = 9.81
    assert hold_force_needed(side, []) == pytest.approx(math.hypot(w, w * 0.03 / 0.005) / 1.0)
    # A sideways push at a CoM straight below the grasp point is a twist too.
    below = _box(1.0, 0.5, 0.005, (0.0, -0.02))
    need = hold_force_needed(below, [(2.0, 0.0, 0.0)])
    assert need == pytest.approx(math.hypot(2.0, w, 2.0 * 0.02 / 0.005))
    # A pure torque adds to the weight's own torque with its sign.
    assert hold_force_needed(side, [(0.0, 0.0, w * 0.03)]) == pytest.approx(
        hold_force_needed(side, []))
    assert hold_force_needed(side, [(0.0, 0.0, -w * 0.03)]) == pytest.approx(
        math.hypot(w, 2 * w * 0.03 / 0.005))


def test_feasibility_reasons_name_their_category() -> None:
    light = _box(0.05, 1.2, 0.005, (0.0, -0.02))
    assert assess(light, []).linear.startswith('too light to slide: ')
    heavy = _box(1.0, 0.15, 0.005, (0.0, -0.03))
    assert assess(heavy, [(0.0, -5.0, 0.0)]).hold.startswith('gripper too weak: ')
    short = _box(0.3, 0.5, 0.008, (0.0, -0.004))
    assert assess(short, []).rotational.startswith('lever too short: ')


def _square(x: int) -> int:
    return x * x


def test_local_backend_keeps_item_order_with_workers() -> None:
    seen: list[tuple[int, int]] = []
    out = run_local(_square, list(range(7)), workers=2,
                    progress=lambda done, total: seen.append((done, total)))
    assert out == [i * i for i in range(7)]
    assert seen[-1] == (7, 7) and len(seen) == 7


def test_hold_need_follows_the_pose_the_object_is_held_in() -> None:
    # CoM 30 mm straight below: upright the weight has no lever; turned 90° in the pads the
    # lever is horizontal and the need is the weight's full twist.
    below = _box(1.0, 0.5, 0.005, (0.0, -0.03))
    w = 9.81
    assert hold_force_needed(below, [], rotation=0.0) == pytest.approx(w)
    assert hold_force_needed(below, [], rotation=math.pi / 2) == pytest.approx(
        math.hypot(w, w * 0.03 / 0.005))
    # Held after turning 90°: the weight is counted on the way there (the horizontal lever is
    # the worst pose), the loads where the object is.
    held = hold_force_needed_held(below, [(0.0, -1.0, 0.0)], math.pi / 2)
    assert held == pytest.approx(math.hypot(w + 1.0, (w + 1.0) * 0.03 / 0.005))
    halfway = hold_force_needed_held(below, [], math.pi / 4)
    assert halfway == pytest.approx(hold_force_needed(below, [], rotation=math.pi / 4))


def test_hinge_feasibility_counts_the_rotation_centre_of_both_maps() -> None:
    # The same short lever is feasible on centred maps and not on a gradient map whose
    # centre of rotation lies off the grasp point.
    c = ContactPreset(mu_c=0.5, mu_s=0.55, mu_v=0.0, r=0.008)
    base = ObjectPreset(name='h', mass=0.15, inertia=1e-4, com_offset=(0.0, -0.014),
                        width=0.05, height_below=0.08, height_above=0.06, thickness=0.03,
                        surface='circle', finger_1=c, finger_2=c)
    assert assess(base, []).hinge == ''
    gradient = dataclasses.replace(base, surface='line_grad')
    assert assess(gradient, []).hinge.startswith('lever too short: ')
