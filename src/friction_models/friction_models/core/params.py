# SPDX-License-Identifier: Apache-2.0
"""Typed, immutable parameter sets of the friction models (spec ``friction_models.md`` §2, §9).

Three families:

* :class:`LuGreParams` -- the *amended* (normal-force-normalised) LuGre law of thesis
  eqs 2.8-2.10 and its Elasto-Plastic extension (eqs 2.11-2.13). Used by every planar model and
  by the 1-D :class:`~friction_models.core.one_d.AmendedLuGre` /
  :class:`~friction_models.core.one_d.ElastoPlastic`. Bristle stiffness ``sigma0`` is in 1/m
  because the bristle describes a friction *coefficient*; forces are ``(...)·f_n``.
* :class:`ClassicLuGreParams` and :class:`DahlParams` -- the original force-valued 1-D laws
  (thesis eqs 2.3-2.7), ``sigma0`` in N/m.
* :class:`StribeckParams` -- the static Stribeck curve (thesis eq 2.2).

Naming (spec §1): the Stribeck exponent is ``stribeck_exp`` (γ in the thesis), the elastic band
of the Elasto-Plastic model is ``r_ba = z_ba / z_max``. Every field carries metadata
(``unit``, ``range``, ``description``) in the project's parameter-schema format; instances are
validated on construction and never mutated.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from types import MappingProxyType
from collections.abc import Mapping
from typing import Any

__all__ = [
    'PARAMETER_SETS',
    'ClassicLuGreParams',
    'DahlParams',
    'LuGreParams',
    'StribeckParams',
    'validate_ranges',
]


def validate_ranges(instance: Any) -> None:
    """Check every float/int field of a parameter dataclass against its ``range`` metadata.

    Args:
        instance: A dataclass instance whose fields may carry ``metadata['range'] = (lo, hi)``
            (inclusive; ``None`` for an open end).

    Raises:
        ValueError: Listing every field that is non-finite or out of range.
    """
    problems: list[str] = []
    for f in fields(instance):
        value = getattr(instance, f.name)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            continue
        if not math.isfinite(value):
            problems.append(f'{f.name}={value!r} is not finite')
            continue
        lo, hi = f.metadata.get('range', (None, None))
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            unit = f.metadata.get('unit', '')
            problems.append(f'{f.name}={value!r} outside [{lo}, {hi}] {unit}')
    if problems:
        raise ValueError(f'invalid {type(instance).__name__}: ' + '; '.join(problems))


def _stribeck_checks(mu_c: float, mu_s: float) -> None:
    if mu_s < mu_c:
        raise ValueError(f'mu_s={mu_s!r} must be >= mu_c={mu_c!r} (static >= kinetic friction)')


@dataclass(frozen=True)
class LuGreParams:
    """Amended LuGre / Elasto-Plastic friction law (thesis eqs 2.8-2.13, spec §2, §5, §9).

    Defaults are the reference "class default" / "reduced vs distributed" set of spec §9
    (μ_C 1, μ_S 1.2, v_s 1 mm/s, γ 2, σ0 1e6 1/m, σ1 80 s/m, σ2 0.2 s/m, r_ba 0.9).
    """

    mu_c: float = field(default=1.0, metadata={
        'unit': '-', 'range': (1e-6, 10.0),
        'description': 'Coulomb (kinetic) friction coefficient (> 0: g divides the bristle rate)'})
    mu_s: float = field(default=1.2, metadata={
        'unit': '-', 'range': (0.0, 10.0), 'description': 'static friction coefficient (>= mu_c)'})
    v_s: float = field(default=1e-3, metadata={
        'unit': 'm/s', 'range': (1e-9, 10.0), 'description': 'Stribeck velocity'})
    stribeck_exp: float = field(default=2.0, metadata={
        'unit': '-', 'range': (0.1, 10.0), 'description': 'Stribeck exponent (gamma, eq 2.9)'})
    sigma0: float = field(default=1e6, metadata={
        'unit': '1/m', 'range': (1e-3, 1e12),
        'description': 'normalised bristle stiffness (force = sigma0 z f_n)'})
    sigma1: float = field(default=80.0, metadata={
        'unit': 's/m', 'range': (0.0, 1e9), 'description': 'normalised bristle damping'})
    sigma2: float = field(default=0.2, metadata={
        'unit': 's/m', 'range': (0.0, 1e6), 'description': 'normalised viscous coefficient'})
    r_ba: float = field(default=0.9, metadata={
        'unit': '-', 'range': (0.0, 0.999),
        'description': 'elasto-plastic breakaway ratio z_ba / z_max (eq 2.13)'})
    v_eps: float = field(default=1e-9, metadata={
        'unit': 'm/s', 'range': (1e-15, 1e-3),
        'description': 'speed regularisation of steady-state unit vectors (spec §13 pitfall 6)'})

    def __post_init__(self) -> None:
        """Validate ranges and μ_S ≥ μ_C."""
        validate_ranges(self)
        _stribeck_checks(self.mu_c, self.mu_s)


@dataclass(frozen=True)
class ClassicLuGreParams:
    """Force-valued 1-D LuGre law (thesis eqs 2.5-2.7): ``f_c = mu_c f_n``, ``f_s = mu_s f_n``."""

    mu_c: float = field(default=1.0, metadata={
        'unit': '-', 'range': (1e-6, 10.0), 'description': 'Coulomb friction coefficient'})
    mu_s: float = field(default=1.2, metadata={
        'unit': '-', 'range': (0.0, 10.0), 'description': 'static friction coefficient'})
    v_s: float = field(default=1e-3, metadata={
        'unit': 'm/s', 'range': (1e-9, 10.0), 'description': 'Stribeck velocity'})
    stribeck_exp: float = field(default=2.0, metadata={
        'unit': '-', 'range': (0.1, 10.0), 'description': 'Stribeck exponent (gamma)'})
    sigma0: float = field(default=1e6, metadata={
        'unit': 'N/m', 'range': (1e-3, 1e12), 'description': 'bristle stiffness'})
    sigma1: float = field(default=80.0, metadata={
        'unit': 'N·s/m', 'range': (0.0, 1e9), 'description': 'bristle damping'})
    sigma2: float = field(default=0.2, metadata={
        'unit': 'N·s/m', 'range': (0.0, 1e6), 'description': 'viscous coefficient'})

    def __post_init__(self) -> None:
        """Validate ranges and μ_S ≥ μ_C."""
        validate_ranges(self)
        _stribeck_checks(self.mu_c, self.mu_s)


@dataclass(frozen=True)
class DahlParams:
    """Dahl law (thesis eqs 2.3-2.4): ``ż = v − σ0·|v|·z/f_c``, ``f_c = mu_c f_n``."""

    mu_c: float = field(default=1.0, metadata={
        'unit': '-', 'range': (1e-6, 10.0), 'description': 'Coulomb friction coefficient'})
    sigma0: float = field(default=1e6, metadata={
        'unit': 'N/m', 'range': (1e-3, 1e12), 'description': 'rest stiffness'})

    def __post_init__(self) -> None:
        """Validate ranges."""
        validate_ranges(self)


@dataclass(frozen=True)
class StribeckParams:
    """Static Stribeck curve (thesis eq 2.2) with a linear viscous coefficient ``mu_v``."""

    mu_c: float = field(default=1.0, metadata={
        'unit': '-', 'range': (0.0, 10.0), 'description': 'Coulomb friction coefficient'})
    mu_s: float = field(default=1.2, metadata={
        'unit': '-', 'range': (0.0, 10.0), 'description': 'static friction coefficient'})
    v_s: float = field(default=1e-3, metadata={
        'unit': 'm/s', 'range': (1e-9, 10.0), 'description': 'Stribeck velocity'})
    stribeck_exp: float = field(default=2.0, metadata={
        'unit': '-', 'range': (0.1, 10.0), 'description': 'Stribeck exponent (gamma)'})
    mu_v: float = field(default=0.0, metadata={
        'unit': 's/m', 'range': (-1e3, 1e3),
        'description': 'viscous friction coefficient (per m/s; measured values may be < 0)'})
    v_eps: float = field(default=1e-9, metadata={
        'unit': 'm/s', 'range': (1e-15, 1e-3),
        'description': 'speeds below this count as sticking'})

    def __post_init__(self) -> None:
        """Validate ranges and μ_S ≥ μ_C."""
        validate_ranges(self)
        _stribeck_checks(self.mu_c, self.mu_s)


#: The reference "class default" set (spec §9); frozen, so safe as a default argument.
DEFAULT_PARAMS = LuGreParams()

#: Named amended-LuGre parameter sets of spec §9 (read-only mapping of frozen instances).
#: The integrator, limiter and Elasto-Plastic switches of the table are constructor
#: options of the models, not parameters of the law.
PARAMETER_SETS: Mapping[str, LuGreParams] = MappingProxyType({
    'class_default': DEFAULT_PARAMS,
    'reduced_vs_distributed': LuGreParams(sigma1=80.0),
    'reduced_vs_distributed_ode': LuGreParams(sigma1=800.0),
    'drift_lugre': LuGreParams(sigma1=800.0),
    'drift_elasto_plastic': LuGreParams(sigma1=80.0),
    'slip_stick': LuGreParams(sigma1=80.0),
    'convergence_p0': LuGreParams(mu_s=1.0, sigma1=800.0, sigma2=0.0),
    'convergence_p1': LuGreParams(sigma1=800.0),
    'speed_test': LuGreParams(sigma0=1e5, sigma1=20.0),
    'size_change': LuGreParams(mu_s=1.3, sigma0=1e5, sigma1=20.0, sigma2=0.4),
    'coulomb': LuGreParams(mu_s=1.0, sigma2=0.0),
})
