# SPDX-License-Identifier: Apache-2.0
"""Settings of the in-process evaluation and its error (SI units)."""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from friction_models.core.population import SensorVariation
from friction_models.core.presets import ObjectPreset

from slip_control.core.controller_host import WATCHDOG_PERIOD_S
from slip_control.core.params import (ContactEstimatorParams, ExperimentRunnerParams,
                                      SlipControllerParams)

#: The four reference objects of control_and_estimation §3.9, in table order.
REFERENCE_PRESETS: tuple[str, ...] = ('plastic', 'wood', 'case', 'cardboard')


class EvaluationError(RuntimeError):
    """A scenario could not be set up (a mode or a phase was refused; the message says why)."""


@dataclass(frozen=True)
class EvalSettings:
    """How the cell and the cores are run (SI).

    Attributes:
        physics_dt: Physics step [s]. 1 ms here (the node runs 0.1 ms): about 8× faster, and
            the outcomes differ from those at 0.1 ms by far less than the test tolerances
            (compared when this module was written; the cell is stable for any step).
        seed: Seed of the cell's sensor noise.
        velocity_model: ``'chips'`` (quantised device chain) or ``'ideal'``.
        chunk: Harness chunk [s]: the transport latency between a sensor event and a command.
        watchdog_period: Period of the controller's watchdog step [s] (the node's).
        settle: HOLD time before a controller scenario starts [s].
        reset_grasp_force: Grasp force the object is held with in the air before HOLD takes
            over [N] (the simulator's ``reset_grasp_force``); an object that needs more swings
            in the pads before HOLD catches it.
        presets_file: Extra presets YAML (friction_models format); '' = reference objects only.
        objects: Extra object presets by name (e.g. drawn by the population evaluation); they
            are added to the reference objects and those of ``presets_file``.
        sensors: F/T sensor imperfections of the cell (noise scale, offsets); ``None`` keeps
            the simulator's defaults.
        control_law: Control-law family put on every slip-mode request whose mode has it
            (``ModeRequest.control_law``, e.g. ``'model'``; the others keep the default law);
            '' sends the requests as built (the controller's default family).
        controller: Slip-controller parameters (``frames`` are replaced by the cell's).
        estimator: Estimator parameters.
        runner: Experiment-runner parameters (the sequences played on the cell).
    """

    physics_dt: float = 1.0e-3
    seed: int = 0
    velocity_model: str = 'chips'
    chunk: float = 1.0e-3
    watchdog_period: float = WATCHDOG_PERIOD_S
    settle: float = 1.0
    reset_grasp_force: float = 10.0
    presets_file: str = ''
    objects: Mapping[str, ObjectPreset] = field(default_factory=dict)
    sensors: SensorVariation | None = None
    control_law: str = ''
    controller: SlipControllerParams = field(default_factory=SlipControllerParams)
    estimator: ContactEstimatorParams = field(default_factory=ContactEstimatorParams)
    runner: ExperimentRunnerParams = field(default_factory=ExperimentRunnerParams)
