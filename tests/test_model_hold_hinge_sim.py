# SPDX-License-Identifier: Apache-2.0
"""The ``model`` HOLD and HINGE laws on drawn objects in the simulated cell, judged by the truth
(issue 15 items 5 and 6).

Each object runs through the population evaluation's own path
(`slip_bringup.population.runner.evaluate_object`: the ``slip_controller`` node's host, the
scaled pushes and taps, the hinge set-up 60° from hanging) with the simulator's true contact
properties, and must meet the population targets:

* HOLD: no drop, slip ≤ 1 mm and rotation ≤ 2° under the pushes and taps, peak commanded
  force ≤ 1.5 × the force the sustained loads need + 1 N;
* HINGE: no drop, relative rotation 60 ± 6°, grasp-point translation over the turn ≤ 10 mm.

The objects span light and heavy, a line, a circle and gradient pressure maps (centre of
pressure off the pad centre), μ_s/μ_c up to 1.6 and centre-of-mass levers of 15–33 mm.
"""
from __future__ import annotations

import pytest

from slip_bringup.population.runner import PopulationTask, evaluate_object

pytestmark = pytest.mark.slow

SEED = 11
#: Drawn objects of population 11 (index: what it covers).
OBJECTS = {
    1: 'light (92 g), circle map, mu_s/mu_c 1.6, lever 33 mm',
    2: 'heavy (735 g), gradient map along y, mu_s/mu_c 1.5',
    6: 'light (107 g), line map, lever 32 mm',
    11: '309 g, gradient map, fingers mu_c 0.61 / 0.37, lever 15 mm',
}


@pytest.fixture(scope='module')
def results() -> dict[tuple[int, str], object]:
    out = {}
    for index in OBJECTS:
        task = PopulationTask(seed=SEED, index=index, controllers=('model',),
                              scenarios=('estimation', 'hold', 'hinge'),
                              truth_properties=True)
        for s in evaluate_object(task).scenarios:
            out[(index, f'{s.scenario}/{s.controller}')] = s
    return out


@pytest.mark.parametrize('index', sorted(OBJECTS))
@pytest.mark.parametrize('scenario', ['hold', 'hinge'])
def test_model_law_meets_the_targets(results: dict, index: int, scenario: str) -> None:
    s = results[(index, f'{scenario}/model')]
    assert s.feasible, s.infeasible_reason
    m = s.metrics
    assert s.success, f'object {index} ({OBJECTS[index]}): {s.failure}; {m}'
    if scenario == 'hold':
        assert m['slip_peak'] <= 0.001 and m['rotation_peak'] <= 0.0349066
        assert m['force_peak'] <= 1.5 * m['force_needed'] + 1.0
    else:
        assert abs(abs(m['relative_rotation']) - 1.0471976) <= 0.1047198
        assert m['translation_turn'] <= 0.010

