# SPDX-License-Identifier: Apache-2.0
"""Random objects drawn from the simulator's supported ranges (population studies, ROS-free).

`draw_object(seed, index)` returns the same `PopulationObject` for the same ``(seed, index)``
on any machine and in any process: every object has its own generator seeded with
``(seed, index)`` (numpy ``SeedSequence``), so a population split across worker processes or a
Dask cluster is the population drawn in one loop.

The ranges (`PopulationRanges`, all SI) are documented in docs/evaluation.md. Draws:

* mass: log-uniform in ``mass`` [kg] (light objects are as common as heavy ones per decade);
* per finger, independently: Coulomb ``mu_c`` uniform in ``mu_c``; ``mu_s = mu_c·k`` with
  ``k`` uniform in ``static_ratio``; viscous ``mu_v`` uniform in ``mu_v`` [1/(m/s)];
  torsional radius ``r = r_object·(1 + δ)`` with ``r_object`` uniform in ``r`` [m] (one contact
  size per object: both pads press the same object) and ``δ`` uniform in ±``r_finger_spread``;
* pressure map: one of ``surfaces`` (equal odds; ``line_grad`` has its centre of pressure off
  the pad centre along y, ``line_grad_x`` along x);
* centre-of-mass offset from the grasp point: length uniform in ``com_offset`` [m], direction
  uniform in the object plane; the box grows to contain it with ``com_margin`` to spare;
* box size: ``width``, ``height_below``, ``height_above``, ``thickness`` uniform in their
  ranges (inertia of a uniform box about its centre of mass);
* object–table friction uniform in ``table_mu``;
* sensors: F/T noise scaled by a factor uniform in ``noise_scale``; each F/T offset component
  uniform in ±``ft_force_offset`` [N] / ±``ft_torque_offset`` [N·m].
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .presets import ContactPreset, ObjectPreset

__all__ = ['PopulationObject', 'PopulationRanges', 'SensorVariation', 'draw_object',
           'draw_population']

Range = tuple[float, float]


@dataclass(frozen=True)
class PopulationRanges:
    """Bounds of every randomised quantity (SI; see the module docstring for the draws)."""

    mass: Range = (0.05, 1.0)                 # kg (log-uniform)
    mu_c: Range = (0.15, 1.2)                 # -
    static_ratio: Range = (1.0, 1.6)          # mu_s / mu_c
    mu_v: Range = (0.0, 5.0)                  # 1/(m/s)
    r: Range = (0.003, 0.009)                 # m, torsional radius of the object's contact
    r_finger_spread: float = 0.15             # relative, per finger
    surfaces: tuple[str, ...] = ('square', 'circle', 'line', 'line_grad', 'line_grad_x')
    com_offset: Range = (0.0, 0.040)          # m, length of the CoM offset from the grasp point
    com_margin: float = 0.010                 # m, box edge beyond the CoM
    width: Range = (0.04, 0.10)               # m
    height_below: Range = (0.05, 0.10)        # m
    height_above: Range = (0.03, 0.08)        # m
    thickness: Range = (0.02, 0.07)           # m (stroke 0.08 m)
    table_mu: Range = (0.3, 0.8)              # -
    noise_scale: Range = (0.5, 2.0)           # × the simulator's default F/T noise
    ft_force_offset: float = 1.5              # N, per component
    ft_torque_offset: float = 0.015           # N·m, per component

    def problems(self) -> list[str]:
        """Reasons the ranges are unusable (empty when valid)."""
        out = []
        for name in ('mass', 'mu_c', 'static_ratio', 'mu_v', 'r', 'com_offset', 'width',
                     'height_below', 'height_above', 'thickness', 'table_mu', 'noise_scale'):
            lo, hi = getattr(self, name)
            if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
                out.append(f'{name} = ({lo}, {hi}) is not a finite range low <= high')
        if self.mass[0] <= 0.0:
            out.append('mass must be > 0 kg')
        if self.static_ratio[0] < 1.0:
            out.append('static_ratio must be >= 1 (mu_s >= mu_c)')
        if not self.surfaces:
            out.append('surfaces is empty')
        return out


@dataclass(frozen=True)
class SensorVariation:
    """Per-object F/T sensor imperfections (applied to the simulator's ``ft`` group)."""

    noise_scale: float
    offset_1: tuple[float, ...]
    offset_2: tuple[float, ...]


@dataclass(frozen=True)
class PopulationObject:
    """One drawn object: its preset, its sensors, and the seed that reproduces it."""

    seed: int
    index: int
    preset: ObjectPreset
    sensors: SensorVariation

    @property
    def name(self) -> str:
        """Preset name, ``pop-<seed>-<index>``."""
        return self.preset.name


def _uniform(rng: np.random.Generator, bounds: Range) -> float:
    return float(rng.uniform(bounds[0], bounds[1]))


def draw_object(seed: int, index: int,
                ranges: PopulationRanges = PopulationRanges()) -> PopulationObject:
    """Object ``index`` of population ``seed`` (deterministic, independent of other objects)."""
    problems = ranges.problems()
    if problems:
        raise ValueError('; '.join(problems))
    if seed < 0 or index < 0:
        raise ValueError(f'seed and index must be >= 0, got {seed}, {index}')
    rng = np.random.default_rng(np.random.SeedSequence([seed, index]))
    mass = math.exp(_uniform(rng, (math.log(ranges.mass[0]), math.log(ranges.mass[1]))))
    r_object = _uniform(rng, ranges.r)

    def contact() -> ContactPreset:
        mu_c = _uniform(rng, ranges.mu_c)
        mu_s = mu_c * _uniform(rng, ranges.static_ratio)
        r = r_object * (1.0 + _uniform(rng, (-ranges.r_finger_spread, ranges.r_finger_spread)))
        return ContactPreset(mu_c=mu_c, mu_s=mu_s, mu_v=_uniform(rng, ranges.mu_v), r=r)

    finger_1, finger_2 = contact(), contact()
    surface = ranges.surfaces[int(rng.integers(len(ranges.surfaces)))]
    length = _uniform(rng, ranges.com_offset)
    direction = _uniform(rng, (-math.pi, math.pi))
    com = (length * math.cos(direction), length * math.sin(direction))
    margin = ranges.com_margin
    width = max(_uniform(rng, ranges.width), 2.0 * (abs(com[0]) + margin))
    below = max(_uniform(rng, ranges.height_below), -com[1] + margin)
    above = max(_uniform(rng, ranges.height_above), com[1] + margin)
    thickness = _uniform(rng, ranges.thickness)
    table_mu = _uniform(rng, ranges.table_mu)
    # A box of uniform density about its centre, taken at the CoM (the offset models a heavy
    # part off the grasp point, not a lopsided box).
    inertia = mass * (width ** 2 + (below + above) ** 2) / 12.0
    preset = ObjectPreset(name=f'pop-{seed}-{index}', mass=mass, inertia=inertia,
                          com_offset=com, width=width, height_below=below, height_above=above,
                          thickness=thickness, surface=surface, finger_1=finger_1,
                          finger_2=finger_2, table_mu=table_mu)
    preset.validate()
    f_off, t_off = ranges.ft_force_offset, ranges.ft_torque_offset

    def offset() -> tuple[float, ...]:
        return tuple(float(v) for v in np.concatenate(
            [rng.uniform(-f_off, f_off, 3), rng.uniform(-t_off, t_off, 3)]))

    sensors = SensorVariation(noise_scale=_uniform(rng, ranges.noise_scale),
                              offset_1=offset(), offset_2=offset())
    return PopulationObject(seed=seed, index=index, preset=preset, sensors=sensors)


def draw_population(seed: int, count: int,
                    ranges: PopulationRanges = PopulationRanges()) -> list[PopulationObject]:
    """Objects ``0 … count−1`` of population ``seed``."""
    if count < 1:
        raise ValueError(f'count must be >= 1, got {count}')
    return [draw_object(seed, i, ranges) for i in range(count)]
