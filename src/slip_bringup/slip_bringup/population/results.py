# SPDX-License-Identifier: Apache-2.0
"""Result records of a population run (plain dataclasses of floats and strings, picklable)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

#: Scenarios of a population run, in report order.
SCENARIOS = ('estimation', 'hold', 'linear', 'rotational', 'hinge')


@dataclass(frozen=True)
class ScenarioResult:
    """One scenario on one object, judged by the simulator truth.

    Attributes:
        scenario: One of `SCENARIOS`.
        controller: Control-law family (``thesis`` or ``model``; ``-`` for estimation).
        feasible: The scenario is physically possible for this object (`feasibility`).
        infeasible_reason: Why not ('' when feasible).
        success: Every criterion met (only meaningful when feasible).
        failure: The first criterion missed, or the error that stopped the run ('' on success).
        metrics: Measured quantities, SI (m, rad, s, N); names documented in docs/evaluation.md.
        reported: What the controller or estimator itself reported (e.g. ``done``).
    """

    scenario: str
    controller: str
    feasible: bool
    infeasible_reason: str
    success: bool
    failure: str
    metrics: dict[str, float] = field(default_factory=dict)
    reported: str = ''

    def metric(self, name: str) -> float:
        """A metric, NaN when absent."""
        return self.metrics.get(name, math.nan)


@dataclass(frozen=True)
class ObjectResult:
    """Every scenario of one object, with the parameters that describe the object."""

    seed: int
    index: int
    name: str
    parameters: dict[str, float]
    surface: str
    scenarios: tuple[ScenarioResult, ...]
    cpu_seconds: float

    def get(self, scenario: str, controller: str) -> ScenarioResult | None:
        """The result of one scenario and controller family, if it ran."""
        for s in self.scenarios:
            if s.scenario == scenario and s.controller in (controller, '-'):
                return s
        return None
