# SPDX-License-Identifier: Apache-2.0
"""Counts ↔ SI of a Net F/T box: unit names and counts per unit (ROS-free).

``F = counts / cfgcpf`` in the box's force unit (``scfgfu``), ``T = counts / cfgcpt`` in its
torque unit (``scfgtu``), converted to N and N·m. Never assume the counts per unit: read
``netftapi2.xml`` (`netft_config`) or take them as parameters (HW-7).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from collections.abc import Sequence

#: A wrench: (Fx, Fy, Fz [N], Tx, Ty, Tz [N·m]) in the sensor frame.
Wrench = tuple[float, float, float, float, float, float]

FORCE_UNITS_TO_N: dict[str, float] = {
    'lbf': 4.4482216152605, 'klbf': 4448.2216152605, 'kgf': 9.80665, 'kn': 1000.0, 'n': 1.0}
TORQUE_UNITS_TO_NM: dict[str, float] = {
    'lbfin': 0.1129848290276167, 'lbfft': 1.3558179483314004, 'nmm': 0.001,
    'kgfcm': 0.0980665, 'knm': 1000.0, 'nm': 1.0}


def normalise_unit(unit: str) -> str:
    """Lower-case a unit and drop separators: ``'N-m'``, ``'N m'``, ``'Nm'`` → ``'nm'``."""
    return ''.join(ch for ch in unit.strip().lower() if ch.isalnum())


def force_unit_factor(unit: str) -> float:
    """Newtons per box force unit.

    Raises:
        ValueError: Unknown unit (the message lists the known ones).
    """
    key = normalise_unit(unit)
    if key not in FORCE_UNITS_TO_N:
        raise ValueError(f'unknown force unit {unit!r}; known: lbf, klbf, kgf, kN, N')
    return FORCE_UNITS_TO_N[key]


def torque_unit_factor(unit: str) -> float:
    """N·m per box torque unit.

    Raises:
        ValueError: Unknown unit (the message lists the known ones).
    """
    key = normalise_unit(unit)
    if key not in TORQUE_UNITS_TO_NM:
        raise ValueError(f'unknown torque unit {unit!r}; known: lbf-in, lbf-ft, N-mm, kgf-cm, '
                         f'kN-m, N-m')
    return TORQUE_UNITS_TO_NM[key]


@dataclass(frozen=True)
class ForceTorqueScale:
    """Counts → SI conversion of one box.

    Attributes:
        counts_per_force: ``cfgcpf`` [counts per force unit], > 0.
        counts_per_torque: ``cfgcpt`` [counts per torque unit], > 0.
        force_unit: ``scfgfu`` (e.g. ``'N'``, ``'lbf'``).
        torque_unit: ``scfgtu`` (e.g. ``'N-m'``, ``'Nm'``, ``'lbf-in'``).
    """

    counts_per_force: float
    counts_per_torque: float
    force_unit: str = 'N'
    torque_unit: str = 'N-m'

    def __post_init__(self) -> None:
        for name in ('counts_per_force', 'counts_per_torque'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f'{name} must be finite and > 0, got {value!r}')
        force_unit_factor(self.force_unit)
        torque_unit_factor(self.torque_unit)

    @property
    def newton_per_count(self) -> float:
        """[N/count]."""
        return force_unit_factor(self.force_unit) / self.counts_per_force

    @property
    def newton_metre_per_count(self) -> float:
        """[N·m/count]."""
        return torque_unit_factor(self.torque_unit) / self.counts_per_torque

    def to_si(self, counts: Sequence[int]) -> Wrench:
        """Wrench in N and N·m from six counts."""
        f = self.newton_per_count
        m = self.newton_metre_per_count
        return (counts[0] * f, counts[1] * f, counts[2] * f,
                counts[3] * m, counts[4] * m, counts[5] * m)

    def to_counts(self, wrench: Sequence[float]) -> tuple[int, int, int, int, int, int]:
        """Six counts (rounded) from a wrench in N and N·m (the emulator's side)."""
        f = self.newton_per_count
        m = self.newton_metre_per_count
        return (round(wrench[0] / f), round(wrench[1] / f), round(wrench[2] / f),
                round(wrench[3] / m), round(wrench[4] / m), round(wrench[5] / m))

