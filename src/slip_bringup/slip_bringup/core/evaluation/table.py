# SPDX-License-Identifier: Apache-2.0
"""The evaluation table of issue 7 item 4: every scenario per reference preset."""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from functools import partial
from typing import TypeVar

from slip_bringup.core.evaluation.estimation import EstimationOutcome, estimate
from slip_bringup.core.evaluation.hinge import HingeOutcome, hinge
from slip_bringup.core.evaluation.holding import (DEFAULT_PUSHES, HoldOutcome, PickUpOutcome,
                                                  hold_under_disturbance, pick_up)
from slip_bringup.core.evaluation.settings import (REFERENCE_PRESETS, EvalSettings,
                                                   EvaluationError)
from slip_bringup.core.evaluation.trajectories import (TrajectoryOutcome, linear_slip,
                                                       rotational_slip)
from slip_control.core.contact import ContactProperties

_T = TypeVar('_T')


@dataclass(frozen=True)
class PresetEvaluation:
    """Every scenario of the table for one preset (``None`` where skipped).

    Attributes:
        preset: Object preset.
        estimation: The exploration.
        properties_source: Where the controllers' properties came from.
        pick_up: Pick-up under HOLD.
        hold: Hold under disturbance.
        linear: LINEAR outcomes keyed by ``(distance [m], duration [s])``.
        rotational: ROTATIONAL outcomes keyed by ``(angle [rad], duration [s])``.
        hinge: Hinge through 60°.
        notes: Scenarios that could not run and why.
    """

    preset: str
    estimation: EstimationOutcome
    properties_source: str
    pick_up: PickUpOutcome | None
    hold: HoldOutcome | None
    linear: Mapping[tuple[float, float], TrajectoryOutcome]
    rotational: Mapping[tuple[float, float], TrajectoryOutcome]
    hinge: HingeOutcome | None
    notes: tuple[str, ...] = ()


#: LINEAR cases of the table (distance [m], duration [s]).
LINEAR_CASES: tuple[tuple[float, float], ...] = ((0.02, 2.0), (0.04, 5.0))
#: ROTATIONAL cases of the table (angle [rad], duration [s]).
ROTATIONAL_CASES: tuple[tuple[float, float], ...] = ((math.radians(20.0), 2.0),
                                                     (math.radians(45.0), 5.0))


def evaluate_preset(preset: str, settings: EvalSettings = EvalSettings(), *,
                    quick: bool = False, use_truth: bool = False,
                    progress: Callable[[str], None] | None = None) -> PresetEvaluation:
    """Run the estimation and every controller scenario for one preset.

    Args:
        preset: Object preset.
        settings: Cell and core settings.
        quick: Only the 2 s trajectories; no pick-up.
        use_truth: Give the controllers the true contact properties instead of the estimate.
        progress: Called with a short note before each scenario (CLI).
    """
    say = progress if progress is not None else (lambda _text: None)
    say(f'{preset}: estimation')
    est = estimate(preset, settings)
    notes: list[str] = []
    props: ContactProperties | None
    if use_truth:
        props, source = None, 'GROUND_TRUTH'
    elif est.valid:
        props, source = est.properties, 'ESTIMATED'
    else:
        props, source = None, 'GROUND_TRUTH'
        notes.append('estimate invalid: the controllers ran on the true properties')

    def attempt(name: str, fn: Callable[[], _T]) -> _T | None:
        say(f'{preset}: {name}')
        try:
            return fn()
        except EvaluationError as exc:
            notes.append(f'{name}: {exc}')
            return None

    pick = None if quick else attempt('pick-up', lambda: pick_up(preset, settings, props))
    hold = attempt('hold under disturbance',
                   lambda: hold_under_disturbance(preset, DEFAULT_PUSHES, settings, props))
    lin: dict[tuple[float, float], TrajectoryOutcome] = {}
    for d, T in LINEAR_CASES[:1] if quick else LINEAR_CASES:
        out = attempt(f'linear {d * 100:.0f} cm / {T:.0f} s',
                      partial(linear_slip, preset, d, T, settings, props))
        if out is not None:
            lin[(d, T)] = out
    rot: dict[tuple[float, float], TrajectoryOutcome] = {}
    for a, T in ROTATIONAL_CASES[:1] if quick else ROTATIONAL_CASES:
        out = attempt(f'rotational {math.degrees(a):.0f} deg / {T:.0f} s',
                      partial(rotational_slip, preset, a, T, settings, props))
        if out is not None:
            rot[(a, T)] = out
    hng = attempt('hinge 60 deg', lambda: hinge(preset, math.radians(60.0), settings, props))
    return PresetEvaluation(preset=preset, estimation=est, properties_source=source,
                            pick_up=pick, hold=hold, linear=lin, rotational=rot, hinge=hng,
                            notes=tuple(notes))


def evaluate_all(presets: Sequence[str] = REFERENCE_PRESETS,
                 settings: EvalSettings = EvalSettings(), *, quick: bool = False,
                 use_truth: bool = False, progress: Callable[[str], None] | None = None
                 ) -> tuple[PresetEvaluation, ...]:
    """`evaluate_preset` for each preset, in order."""
    return tuple(evaluate_preset(p, settings, quick=quick, use_truth=use_truth,
                                 progress=progress) for p in presets)
