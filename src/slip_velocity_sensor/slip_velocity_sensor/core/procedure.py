# SPDX-License-Identifier: Apache-2.0
"""Stop-to-stop calibration procedure as data, and synthetic recordings of it (ROS-free).

Procedure (hardware_protocols §3.7): a flat surface slides under the sensor between two
hard stops ``distance`` apart (100 mm). With the chip under test in single-chip mode, an
operator moves the surface stop-to-stop on timed prompts: one traverse in each direction at
each of 6 speed levels (≈ 10, 5, 3, 2, 1 and < 1 s per traverse), with pauses of 15, 15, 10,
10, 8, 8, 7, 7, 6, 6, 5, 5 s before the traverses and a final rest: 12 traverses and 13 rest
plateaus. One recording per sensor × chip × axis (``Sensor<N>chip<k><x|y>``).

`schedule` gives the prompt sequence the recorder shows; `synthesize_recording` produces what
a chip axis with a known true calibration would report during the procedure (120 Hz lines of
raw speed, 3200-CPI counts, ±127 saturation per 1.7 ms poll, 4-decimal mm/s printing), for
testing the offline fit.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from slip_velocity_sensor.core import calibration as cal_mod
from slip_velocity_sensor.core import protocol
from slip_velocity_sensor.core.calibration import AxisCalibration, SpeedTerm
from slip_velocity_sensor.core.chip_model import ChipModelParams, quantize_series


@dataclass(frozen=True)
class ProcedureParams:
    """Timing and geometry of the stop-to-stop procedure (SI)."""

    distance: float = field(default=0.1, metadata={
        'unit': 'm', 'range': (0.001, 10.0), 'description': 'distance between the hard stops'})
    traverse_durations: tuple[float, ...] = field(default=(10.0, 5.0, 3.0, 2.0, 1.0, 0.7),
                                                  metadata={
        'unit': 's', 'range': (0.05, 600.0),
        'description': 'traverse duration per speed level (each level: both directions)'})
    pauses: tuple[float, ...] = field(default=(15.0, 15.0, 10.0, 10.0, 8.0, 8.0, 7.0, 7.0, 6.0,
                                               6.0, 5.0, 5.0), metadata={
        'unit': 's', 'range': (0.0, 600.0), 'description': 'rest before each traverse'})
    final_rest: float = field(default=5.0, metadata={
        'unit': 's', 'range': (0.0, 600.0), 'description': 'rest after the last traverse'})

    def validate(self) -> None:
        """Raise ValueError unless there is one pause per traverse."""
        if len(self.pauses) != 2 * len(self.traverse_durations):
            raise ValueError(f'{len(self.pauses)} pauses for {2 * len(self.traverse_durations)} '
                             'traverses: need one pause before each traverse')


class StepKind(str, Enum):
    """Kind of procedure step."""

    REST = 'rest'
    TRAVERSE = 'traverse'


@dataclass(frozen=True)
class ProcedureStep:
    """One prompt of the procedure.

    Attributes:
        index: Position in the schedule (0-based).
        kind: Rest or traverse.
        start: Start time from the beginning of the procedure [s].
        duration: [s].
        direction: +1 towards the far stop, -1 back, 0 for rests.
        level: Speed level 0..5 for traverses, -1 for rests.
        position: Surface position at the end of the step [m] (0 = near stop).
        prompt: Operator instruction.
    """

    index: int
    kind: StepKind
    start: float
    duration: float
    direction: int
    level: int
    position: float
    prompt: str

    @property
    def end(self) -> float:
        """End time [s]."""
        return self.start + self.duration


def schedule(params: ProcedureParams | None = None) -> tuple[ProcedureStep, ...]:
    """The prompt schedule: rest, traverse, rest, traverse, ..., final rest (25 steps).

    Traverses alternate direction, starting away from the near stop; each speed level is run
    once in each direction.
    """
    p = params if params is not None else ProcedureParams()
    p.validate()
    steps: list[ProcedureStep] = []
    t = 0.0
    position = 0.0
    for k, pause in enumerate(p.pauses):
        steps.append(ProcedureStep(len(steps), StepKind.REST, t, pause, 0, -1, position,
                                   f'hold still at the {"far" if position else "near"} stop '
                                   f'for {pause:g} s'))
        t += pause
        level = k // 2
        duration = p.traverse_durations[level]
        direction = 1 if k % 2 == 0 else -1
        position = p.distance if direction > 0 else 0.0
        steps.append(ProcedureStep(
            len(steps), StepKind.TRAVERSE, t, duration, direction, level, position,
            f'move to the {"far" if direction > 0 else "near"} stop in {duration:g} s '
            f'(level {level + 1}/{len(p.traverse_durations)})'))
        t += duration
    steps.append(ProcedureStep(len(steps), StepKind.REST, t, p.final_rest, 0, -1, position,
                               f'hold still for {p.final_rest:g} s; done'))
    return tuple(steps)


def step_at(steps: tuple[ProcedureStep, ...], t: float) -> ProcedureStep | None:
    """The step active at time ``t`` [s] since the start, or None after the end."""
    for step in steps:
        if step.start <= t < step.end:
            return step
    return None


def scaled(params: ProcedureParams, time_scale: float) -> ProcedureParams:
    """The procedure with every duration multiplied by ``time_scale`` (> 0), same distance.

    For rehearsals and tests; speeds grow by 1/time_scale, so keep it near 1 on hardware.
    """
    if not time_scale > 0.0:
        raise ValueError(f'time_scale must be > 0, got {time_scale!r}')
    return ProcedureParams(
        distance=params.distance,
        traverse_durations=tuple(d * time_scale for d in params.traverse_durations),
        pauses=tuple(d * time_scale for d in params.pauses),
        final_rest=params.final_rest * time_scale)


class Prompt(NamedTuple):
    """One operator prompt: when to show it [s since the start] and the text."""

    t: float
    text: str


def prompt_schedule(steps: tuple[ProcedureStep, ...], warn_before: float = 3.0
                    ) -> tuple[Prompt, ...]:
    """Timed prompts of a schedule: each step at its start, and a warning before traverses.

    Args:
        steps: The procedure (`schedule`).
        warn_before: Lead of the "get ready" warning before each traverse [s]; shown only
            when the preceding rest is longer than that (0 disables it).

    Returns:
        Prompts in time order.
    """
    n_traverses = sum(1 for s in steps if s.kind is StepKind.TRAVERSE)
    prompts: list[Prompt] = []
    done = 0
    for prev, step in zip((None,) + steps[:-1], steps):
        if step.kind is StepKind.TRAVERSE:
            done += 1
            if warn_before > 0.0 and prev is not None and prev.duration > warn_before:
                prompts.append(Prompt(step.start - warn_before,
                                      f'get ready: traverse {done}/{n_traverses} in '
                                      f'{warn_before:g} s'))
            prompts.append(Prompt(step.start, f'GO   traverse {done}/{n_traverses}: '
                                              f'{step.prompt}'))
        else:
            prompts.append(Prompt(step.start, f'REST {step.prompt}'))
    prompts.append(Prompt(steps[-1].end, 'procedure finished'))
    return tuple(sorted(prompts, key=lambda p: p.t))


def traverse_velocity(tau: NDArray[np.float64], duration: float, distance: float,
                      profile: str = 'trapezoid',
                      ramp_fraction: float = 0.1) -> NDArray[np.float64]:
    """Speed profile of one traverse (positive), zero outside ``0 <= tau <= duration``.

    Args:
        tau: Time since the traverse started [s].
        duration: Traverse duration [s].
        distance: Distance covered [m] (the integral of the profile).
        profile: ``constant``, ``trapezoid`` (linear ramps of ``ramp_fraction·duration``) or
            ``minimum_jerk`` (the smooth bell of a human reach).
        ramp_fraction: Ramp share of the duration for ``trapezoid`` (0 < r <= 0.5).
    """
    s = np.clip(tau / duration, 0.0, 1.0)
    inside = (tau >= 0.0) & (tau <= duration)
    if profile == 'constant':
        v = np.full_like(s, distance / duration)
    elif profile == 'trapezoid':
        r = ramp_fraction
        if not 0.0 < r <= 0.5:
            raise ValueError('ramp_fraction must be in (0, 0.5]')
        peak = distance / (duration * (1.0 - r))
        v = peak * np.minimum(np.minimum(s / r, (1.0 - s) / r), 1.0)
    elif profile == 'minimum_jerk':
        v = distance / duration * 30.0 * s ** 2 * (1.0 - s) ** 2
    else:
        raise ValueError(f'unknown profile {profile!r}')
    return np.where(inside, v, 0.0)


def traverse_position(tau: NDArray[np.float64], duration: float, distance: float,
                      profile: str = 'trapezoid',
                      ramp_fraction: float = 0.1) -> NDArray[np.float64]:
    """Distance covered [m] at ``tau`` [s] into a traverse (exact integral of the profile)."""
    s = np.clip(tau / duration, 0.0, 1.0)
    if profile == 'constant':
        return distance * s
    if profile == 'trapezoid':
        r = ramp_fraction
        if not 0.0 < r <= 0.5:
            raise ValueError('ramp_fraction must be in (0, 0.5]')
        # In units of distance: ramp up s²/(2r(1-r)), cruise (s - r/2)/(1-r), mirrored ramp down.
        up = s ** 2 / (2.0 * r * (1.0 - r))
        cruise = (s - 0.5 * r) / (1.0 - r)
        down = 1.0 - (1.0 - s) ** 2 / (2.0 * r * (1.0 - r))
        return distance * np.where(s < r, up, np.where(s > 1.0 - r, down, cruise))
    if profile == 'minimum_jerk':
        return distance * (10.0 * s ** 3 - 15.0 * s ** 4 + 6.0 * s ** 5)
    raise ValueError(f'unknown profile {profile!r}')


def true_position(t: NDArray[np.float64], steps: tuple[ProcedureStep, ...], distance: float,
                  profile: str = 'trapezoid', ramp_fraction: float = 0.1) -> NDArray[np.float64]:
    """True surface position along the tested axis at times ``t`` [s] [m] (0 = near stop)."""
    x = np.zeros_like(t, dtype=np.float64)
    for step in steps:
        if step.kind is StepKind.TRAVERSE:
            x += step.direction * traverse_position(t - step.start, step.duration, distance,
                                                    profile, ramp_fraction)
    return x


class Recording(NamedTuple):
    """A chip-axis recording: acquisition stamps [s] and raw speed [m/s] (single-chip mode)."""

    t: NDArray[np.float64]
    v: NDArray[np.float64]


@dataclass(frozen=True)
class SynthesisParams:
    """How a synthetic recording is produced."""

    output_period: float = 1.0 / 120.0  #: serial line period [s]
    profile: str = 'trapezoid'  #: traverse speed profile (see `traverse_velocity`)
    ramp_fraction: float = 0.1  #: ramp share of a trapezoid traverse
    truth_speed_term: str = SpeedTerm.ABS.value  #: how the true a-term enters
    chip: ChipModelParams = field(default_factory=ChipModelParams)
    lead_in: float = 1.0  #: rest recorded before the procedure starts [s]
    print_decimals: int = 4  #: decimals of the mm/s values in the ``v`` lines


def synthesize_recording(truth: AxisCalibration, procedure: ProcedureParams | None = None,
                         synthesis: SynthesisParams | None = None,
                         rng: np.random.Generator | None = None) -> Recording:
    """What one chip axis with calibration ``truth`` reports during the procedure.

    The chip reads ``raw = b·v/(1 − a·term(v))`` (so that ``truth`` corrects it exactly), with
    v the exact mean true speed over each poll interval; its motion is counted per poll, and
    the counts of the polls in each output period become one line ``counts·(25.4/3200)/dt``
    in mm/s printed with 4 decimals, converted to m/s.

    Args:
        truth: True chip behaviour (a [1/(m/s)], b).
        procedure: Procedure timing; defaults when omitted.
        synthesis: Line rate, profile and chip model; defaults when omitted.
        rng: Random generator (needed for count noise).
    """
    p = procedure if procedure is not None else ProcedureParams()
    s = synthesis if synthesis is not None else SynthesisParams()
    steps = schedule(p)
    total = s.lead_in + steps[-1].end
    poll = s.chip.poll_period
    n_polls = int(total / poll)
    poll_end = (np.arange(n_polls) + 1.0) * poll
    x_true = true_position(np.concatenate(([0.0], poll_end)) - s.lead_in, steps, p.distance,
                           s.profile, s.ramp_fraction)
    v_true = np.diff(x_true) / poll
    v_raw = cal_mod.raw_speed(v_true, truth, s.truth_speed_term)
    counts = quantize_series(v_raw * poll, s.chip, rng)
    t_out = np.arange(1, int(total / s.output_period) + 1, dtype=np.float64) * s.output_period
    # Counts of every poll finished before an output instant belong to that line.
    cum = np.concatenate(([0], np.cumsum(counts)))
    idx = np.searchsorted(poll_end, t_out, side='right')
    line_counts = np.diff(np.concatenate(([0], cum[idx])))
    dt = np.diff(np.concatenate(([0.0], t_out)))
    v_mm_s = np.round(line_counts * s.chip.metres_per_count * protocol.MM_PER_M / dt,
                      s.print_decimals)
    return Recording(t_out, v_mm_s / protocol.MM_PER_M)
