# SPDX-License-Identifier: Apache-2.0
"""Parameter dataclasses: frozen, validated, metadata complete (spec §9)."""
from __future__ import annotations

import dataclasses

import pytest

from friction_models.core.params import (PARAMETER_SETS, ClassicLuGreParams, DahlParams,
                                         LuGreParams, StribeckParams)

ALL = (LuGreParams, ClassicLuGreParams, DahlParams, StribeckParams)


@pytest.mark.parametrize('cls', ALL)
def test_every_field_has_unit_and_description(cls: type) -> None:
    for f in dataclasses.fields(cls):
        assert 'unit' in f.metadata and f.metadata.get('description'), f.name


@pytest.mark.parametrize('cls', ALL)
def test_frozen(cls: type) -> None:
    p = cls()
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.mu_c = 0.5  # type: ignore[misc]


def test_class_default_matches_spec_table() -> None:
    p = LuGreParams()
    assert (p.mu_c, p.mu_s, p.v_s, p.stribeck_exp) == (1.0, 1.2, 1e-3, 2.0)
    assert (p.sigma0, p.sigma1, p.sigma2, p.r_ba) == (1e6, 80.0, 0.2, 0.9)


@pytest.mark.parametrize('kwargs, fragment', [
    ({'sigma0': -1.0}, 'sigma0'),
    ({'mu_c': float('nan')}, 'not finite'),
    ({'r_ba': 1.0}, 'r_ba'),
    ({'mu_c': 1.0, 'mu_s': 0.5}, 'mu_s'),
    ({'v_s': 0.0}, 'v_s'),
])
def test_invalid_values_are_rejected(kwargs: dict[str, float], fragment: str) -> None:
    with pytest.raises(ValueError, match=fragment):
        LuGreParams(**kwargs)


def test_parameter_sets_are_read_only_and_valid() -> None:
    assert PARAMETER_SETS['speed_test'].sigma0 == 1e5
    assert PARAMETER_SETS['drift_lugre'].sigma1 == 800.0
    with pytest.raises(TypeError):
        PARAMETER_SETS['new'] = LuGreParams()  # type: ignore[index]
