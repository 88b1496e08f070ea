# SPDX-License-Identifier: Apache-2.0
"""Contact-property presets: per-finger values from a CSV or YAML file (source PRESET).

Flags come from the estimator's plausibility limits (``mu_c_max``, ``r_min``, ``r_max``), so a
preset outside them is marked invalid exactly like an estimate would be.
"""
from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

import yaml

from slip_control.core.contact import NAN, ContactProperties, ContactSource, FingerContact
from slip_control.core.params import ContactEstimatorParams


def preset_finger(values: dict[str, Any], params: ContactEstimatorParams) -> FingerContact:
    """One finger of a preset, flags from the plausibility limits (sample counts are 0).

    Args:
        values: ``mu_c`` and ``r`` [m] required; ``mu_s`` (or ``mu_s_over_mu_c``), ``mu_v``
            [1/(m/s)], ``u`` [m²] optional.
        params: Estimator parameters (limits).
    """
    mu_c = float(values['mu_c'])
    r = float(values['r'])
    if 'mu_s' in values:
        mu_s = float(values['mu_s'])
    elif 'mu_s_over_mu_c' in values:
        mu_s = float(values['mu_s_over_mu_c']) * mu_c
    else:
        mu_s = NAN
    mu_v = float(values.get('mu_v', NAN))
    u = float(values.get('u', r * r))
    lin = math.isfinite(mu_c) and 0.0 < mu_c <= params.mu_c_max
    static = lin and math.isfinite(mu_s) and mu_s >= mu_c
    return FingerContact(
        mu_c=mu_c, mu_s=mu_s if static else mu_c, mu_v=mu_v if math.isfinite(mu_v) else 0.0,
        r=r, u=u, linear_valid=lin, viscous_valid=lin and math.isfinite(mu_v),
        static_valid=static,
        rotational_valid=lin and math.isfinite(r) and params.r_min <= r <= params.r_max)


def load_presets(path: str | Path, params: ContactEstimatorParams) -> dict[str, ContactProperties]:
    """Read contact presets (source PRESET) from a CSV or YAML file.

    CSV: the columns of ``data/contact_estimates_reference.csv`` (``object``, ``finger``,
    ``mu_c``, ``mu_s`` or ``mu_s_over_mu_c``, ``mu_v_per_m_per_s``, ``r_m``), one row per object
    and finger. YAML: ``{name: {finger_1: {mu_c, r, mu_s?, mu_v?, u?}, finger_2: {...}}}``,
    optionally under a top-level ``presets`` key.

    Raises:
        ValueError: on a missing finger or column.
    """
    path = Path(path)
    rows: dict[str, dict[int, dict[str, Any]]] = {}
    if path.suffix.lower() == '.csv':
        with path.open(newline='') as fh:
            for row in csv.DictReader(fh):
                vals: dict[str, Any] = {'mu_c': row['mu_c'], 'r': row['r_m']}
                if row.get('mu_s'):
                    vals['mu_s'] = row['mu_s']
                elif row.get('mu_s_over_mu_c'):
                    vals['mu_s_over_mu_c'] = row['mu_s_over_mu_c']
                if row.get('mu_v_per_m_per_s'):
                    vals['mu_v'] = row['mu_v_per_m_per_s']
                rows.setdefault(row['object'], {})[int(row['finger'])] = vals
    else:
        data = yaml.safe_load(path.read_text())
        if isinstance(data, dict) and 'presets' in data:
            data = data['presets']
        if not isinstance(data, dict):
            raise ValueError('expected a mapping of preset names')
        for name, fingers in data.items():
            rows[str(name)] = {1: dict(fingers['finger_1']), 2: dict(fingers['finger_2'])}
    out: dict[str, ContactProperties] = {}
    for name, fingers in rows.items():
        if set(fingers) != {1, 2}:
            raise ValueError(f'preset {name!r} needs fingers 1 and 2, has {sorted(fingers)}')
        out[name] = ContactProperties(preset_finger(fingers[1], params),
                                      preset_finger(fingers[2], params),
                                      ContactSource.PRESET, preset_name=name)
    return out
