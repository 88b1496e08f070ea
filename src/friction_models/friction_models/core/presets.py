# SPDX-License-Identifier: Apache-2.0
"""Object and contact presets of the simulated gripper cell (ROS-free).

An :class:`ObjectPreset` describes one rigid object held between the two pads and the friction
of each pad on it. Geometry is given in the **object frame**: origin at the object's nominal
grasp point ``G`` (the material point that sits at the gripper centre when the object stands on
the table at the pick-up pose), x across the object (``width``), y up along the object
(``height_below`` below G, ``height_above`` above G), z along the grasp axis (``thickness``,
the object's extent between the pads)::

        ┌───────────┐  y = +height_above
        │           │
        │     G ●   │  ← pads touch both faces here (grasp axis ⊥ the page)
        │     ✕ CoM │  com_offset = (x, y) from G
        │           │
        └───────────┘  y = −height_below (rests on the table at its two bottom corners)
        ← width →

Per-finger contact parameters (:class:`ContactPreset`) use the estimator's quantities
(control_and_estimation §3.1): Coulomb ``mu_c``, static ``mu_s`` (≥ mu_c), viscous
``mu_v`` [1/(m/s)] and the torsional radius ``r`` [m] of the ellipsoidal limit surface, which
is the characteristic radius ``r_a`` of the friction models (friction_models §6.1).

The four **reference objects** (plastic, wood, case, cardboard) are defined once, in the YAML
file ``reference_objects.yaml`` next to this module (`REFERENCE_FILE`, read by
:func:`reference_presets`). They carry the per-finger estimates of the reference data
(``docs/data/contact_estimates_reference.csv``; spec §3.9: simulation parameter sets, not
accuracy figures); their geometry is an assumption for the simulation (hand-sized boxes, CoM
at the box centre).

**Adding an object needs no code.** Write it as a YAML entry, either in the package's
``config/sim_presets.yaml`` (the ``sim_gripper`` node's default file) or in a file of your
own passed as the node's ``presets_file`` parameter or ``slip_evaluate --presets-file``.
:func:`load_presets` adds the file's objects to the reference objects (an entry with a
reference object's name replaces it), so nothing needs to be kept in sync.

User presets come from YAML (:func:`load_presets`)::

    presets:
      my_box:
        mass: 0.25                      # kg
        inertia: 3.0e-4                 # kg·m² about the CoM (omit: uniform box)
        com_offset: [0.0, -0.01]        # m, from the grasp point, object frame
        width: 0.06                     # m
        height_below: 0.07              # m
        height_above: 0.05              # m
        thickness: 0.04                 # m, along the grasp axis
        surface: circle                 # pad pressure shape (friction_models.core.surfaces)
        table_mu: 0.5                   # object–table friction coefficient
        finger_1: {mu_c: 0.4, mu_s: 0.45, mu_v: 1.0, r: 0.005}
        finger_2: {mu_c: 0.4, mu_s: 0.45, mu_v: 1.0, r: 0.005}
"""
from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from types import MappingProxyType
from typing import Any

import yaml

from .surfaces import STANDARD_SURFACES, standard_surface

__all__ = [
    'ContactPreset',
    'ObjectPreset',
    'PresetError',
    'REFERENCE_FILE',
    'load_presets',
    'preset_from_dict',
    'reference_presets',
    'select_preset',
]


class PresetError(ValueError):
    """An invalid or unknown preset; the message names the preset and the field."""


def _finite(name: str, value: float) -> list[str]:
    return [] if isinstance(value, (int, float)) and math.isfinite(value) else \
        [f'{name} = {value!r} is not a finite number']


@dataclass(frozen=True)
class ContactPreset:
    """Friction of one pad on the object (estimator quantities, SI).

    Attributes:
        mu_c: Coulomb (kinetic) friction coefficient [-], > 0.
        mu_s: Static friction coefficient [-], ≥ mu_c.
        mu_v: Viscous coefficient [1/(m/s)]; may be negative in estimates. The simulation uses
            ``σ2 = max(mu_v, 0)`` (a negative viscous term would inject energy).
        r: Torsional radius [m] (``τ_max = mu_c·r·f_n``); the pad surface is scaled so that
            its characteristic radius ``r_a`` equals it.
    """

    mu_c: float = field(default=0.4, metadata={'unit': '-', 'range': (1e-3, 5.0)})
    mu_s: float = field(default=0.44, metadata={'unit': '-', 'range': (1e-3, 5.0)})
    mu_v: float = field(default=0.0, metadata={'unit': '1/(m/s)', 'range': (-100.0, 100.0)})
    r: float = field(default=0.005, metadata={'unit': 'm', 'range': (1e-4, 0.1)})

    def problems(self, where: str) -> list[str]:
        """Reasons this contact is unusable (empty when valid)."""
        out: list[str] = []
        for f in fields(self):
            value = getattr(self, f.name)
            bad = _finite(f'{where}.{f.name}', value)
            if bad:
                out.extend(bad)
                continue
            lo, hi = f.metadata['range']
            if not lo <= value <= hi:
                out.append(f'{where}.{f.name} = {value!r} outside [{lo}, {hi}] '
                           f'{f.metadata["unit"]}')
        if not out and self.mu_s < self.mu_c:
            out.append(f'{where}.mu_s = {self.mu_s!r} is below mu_c = {self.mu_c!r} '
                       f'(static friction must be >= kinetic)')
        return out


@dataclass(frozen=True)
class ObjectPreset:
    """A rigid object and its two pad contacts (see the module docstring for the frame).

    Attributes:
        name: Preset name.
        mass: Mass [kg], > 0.
        inertia: Moment of inertia about the CoM, about the grasp axis [kg·m²], > 0.
        com_offset: CoM position relative to the grasp point, object frame [m].
        width: Extent along the object x [m].
        height_below: Extent below the grasp point [m] (the bottom rests on the table).
        height_above: Extent above the grasp point [m].
        thickness: Extent along the grasp axis [m]: the pads touch when the opening equals it.
        surface: Pad pressure shape (a :data:`~friction_models.core.surfaces.STANDARD_SURFACES`
            name).
        finger_1: Contact of finger 1's pad.
        finger_2: Contact of finger 2's pad.
        table_mu: Object–table Coulomb coefficient [-].
    """

    name: str
    mass: float
    inertia: float
    com_offset: tuple[float, float]
    width: float
    height_below: float
    height_above: float
    thickness: float
    surface: str = 'circle'
    finger_1: ContactPreset = field(default_factory=ContactPreset)
    finger_2: ContactPreset = field(default_factory=ContactPreset)
    table_mu: float = 0.5

    def problems(self) -> list[str]:
        """Reasons the preset is unusable (empty when valid); each names its field."""
        w = f'preset {self.name!r}'
        out: list[str] = []
        for name in ('mass', 'inertia', 'width', 'height_below', 'height_above', 'thickness',
                     'table_mu'):
            out.extend(_finite(f'{w}: {name}', getattr(self, name)))
        if out:
            return out
        for name, unit in (('mass', 'kg'), ('inertia', 'kg·m²'), ('width', 'm'),
                           ('thickness', 'm')):
            value = getattr(self, name)
            if not value > 0.0:
                out.append(f'{w}: {name} = {value!r} {unit} must be > 0')
        for name in ('height_below', 'height_above', 'table_mu'):
            value = getattr(self, name)
            if value < 0.0:
                out.append(f'{w}: {name} = {value!r} must be >= 0')
        if self.height_below + self.height_above <= 0.0:
            out.append(f'{w}: height_below + height_above must be > 0 m')
        if len(self.com_offset) != 2:
            out.append(f'{w}: com_offset must have 2 components (x, y) [m]')
        else:
            for i, c in enumerate(self.com_offset):
                out.extend(_finite(f'{w}: com_offset[{i}]', c))
        try:
            standard_surface(self.surface, 3)
        except (ValueError, KeyError):
            out.append(f'{w}: surface = {self.surface!r} is not one of '
                       f'{", ".join(STANDARD_SURFACES)}')
        out.extend(self.finger_1.problems(f'{w}: finger_1'))
        out.extend(self.finger_2.problems(f'{w}: finger_2'))
        return out

    def validate(self) -> None:
        """Raise :class:`PresetError` (a ValueError) listing every problem."""
        problems = self.problems()
        if problems:
            raise PresetError('; '.join(problems))

    def contact(self, finger: int) -> ContactPreset:
        """Contact of finger 1 or 2."""
        if finger == 1:
            return self.finger_1
        if finger == 2:
            return self.finger_2
        raise ValueError(f'finger must be 1 or 2, got {finger!r}')

    @property
    def height(self) -> float:
        """Total height [m]."""
        return self.height_below + self.height_above


def _box_inertia(mass: float, width: float, height: float) -> float:
    """Uniform box about its centre, axis along the thickness: ``m (w² + h²)/12`` [kg·m²]."""
    return mass * (width * width + height * height) / 12.0


#: The file that defines the reference objects (installed with the package).
REFERENCE_FILE = Path(__file__).with_name('reference_objects.yaml')


@functools.cache
def _reference_objects() -> Mapping[str, ObjectPreset]:
    """The reference objects of `REFERENCE_FILE`, read once (immutable)."""
    return MappingProxyType(load_presets(REFERENCE_FILE, include_reference=False))


def reference_presets() -> dict[str, ObjectPreset]:
    """A fresh dict of the four reference objects (plastic, wood, case, cardboard), as
    defined in `REFERENCE_FILE` — their only definition.

    Raises:
        PresetError: The installed file is missing or invalid.
    """
    return dict(_reference_objects())


_OBJECT_KEYS = {'mass', 'inertia', 'com_offset', 'width', 'height_below', 'height_above',
                'thickness', 'surface', 'finger_1', 'finger_2', 'table_mu'}
_CONTACT_KEYS = {'mu_c', 'mu_s', 'mu_v', 'r'}


def _number(where: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise PresetError(f'{where} = {value!r} is not a number')
    return float(value)


def _contact_from_dict(where: str, data: Any) -> ContactPreset:
    if not isinstance(data, Mapping):
        raise PresetError(f'{where} must be a mapping with {sorted(_CONTACT_KEYS)}')
    unknown = set(data) - _CONTACT_KEYS
    if unknown:
        raise PresetError(f'{where}: unknown keys {sorted(unknown)} '
                          f'(allowed: {sorted(_CONTACT_KEYS)})')
    missing = {'mu_c', 'r'} - set(data)
    if missing:
        raise PresetError(f'{where}: missing {sorted(missing)}')
    mu_c = _number(f'{where}.mu_c', data['mu_c'])
    mu_s = _number(f'{where}.mu_s', data.get('mu_s', mu_c))
    return ContactPreset(mu_c=mu_c, mu_s=mu_s, mu_v=_number(f'{where}.mu_v', data.get('mu_v', 0.0)),
                         r=_number(f'{where}.r', data['r']))


def preset_from_dict(name: str, data: Mapping[str, Any]) -> ObjectPreset:
    """Build and validate one preset from a YAML mapping (see the module docstring).

    ``inertia`` defaults to a uniform box, ``com_offset`` to the box centre, ``surface`` to
    ``circle``, ``table_mu`` to 0.5, ``mu_s`` to ``mu_c`` and ``mu_v`` to 0.

    Raises:
        PresetError: Unknown or missing keys, non-numbers, or invalid values (all named).
    """
    where = f'preset {name!r}'
    if not isinstance(data, Mapping):
        raise PresetError(f'{where} must be a mapping')
    unknown = set(data) - _OBJECT_KEYS
    if unknown:
        raise PresetError(f'{where}: unknown keys {sorted(unknown)} '
                          f'(allowed: {sorted(_OBJECT_KEYS)})')
    missing = {'mass', 'width', 'height_below', 'height_above', 'thickness', 'finger_1',
               'finger_2'} - set(data)
    if missing:
        raise PresetError(f'{where}: missing {sorted(missing)}')
    num = {k: _number(f'{where}: {k}', data[k])
           for k in ('mass', 'width', 'height_below', 'height_above', 'thickness')}
    if 'com_offset' in data:
        com = data['com_offset']
        if not isinstance(com, (list, tuple)) or len(com) != 2:
            raise PresetError(f'{where}: com_offset must be a list [x, y] in m, got {com!r}')
        com_offset = (_number(f'{where}: com_offset[0]', com[0]),
                      _number(f'{where}: com_offset[1]', com[1]))
    else:
        com_offset = (0.0, 0.5 * (num['height_above'] - num['height_below']))
    inertia = (_number(f'{where}: inertia', data['inertia']) if 'inertia' in data else
               _box_inertia(num['mass'], num['width'], num['height_below'] + num['height_above']))
    surface = data.get('surface', 'circle')
    if not isinstance(surface, str):
        raise PresetError(f'{where}: surface must be a string, got {surface!r}')
    preset = ObjectPreset(
        name=name, mass=num['mass'], inertia=inertia, com_offset=com_offset,
        width=num['width'], height_below=num['height_below'],
        height_above=num['height_above'], thickness=num['thickness'], surface=surface,
        finger_1=_contact_from_dict(f'{where}: finger_1', data['finger_1']),
        finger_2=_contact_from_dict(f'{where}: finger_2', data['finger_2']),
        table_mu=_number(f'{where}: table_mu', data.get('table_mu', 0.5)))
    preset.validate()
    return preset


def load_presets(yaml_path: str | Path, *,
                 include_reference: bool = True) -> dict[str, ObjectPreset]:
    """Load presets from a YAML file with a top-level ``presets:`` mapping.

    Args:
        yaml_path: File path.
        include_reference: Start from the four reference objects; file entries with the same
            name replace them.

    Returns:
        ``{name: preset}``.

    Raises:
        PresetError: The file is unreadable, malformed, or a preset is invalid (the message
            names the file and the preset).
    """
    path = Path(yaml_path)
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise PresetError(f'cannot read presets from {path}: {exc}') from exc
    if not isinstance(data, Mapping) or not isinstance(data.get('presets'), Mapping):
        raise PresetError(f'{path}: expected a top-level "presets:" mapping')
    out = reference_presets() if include_reference else {}
    for name, entry in data['presets'].items():
        try:
            out[str(name)] = preset_from_dict(str(name), entry)
        except PresetError as exc:
            raise PresetError(f'{path}: {exc}') from exc
    return out


def select_preset(presets: Mapping[str, ObjectPreset], name: str) -> ObjectPreset:
    """Return ``presets[name]`` or raise a KeyError listing the known names."""
    try:
        return presets[name]
    except KeyError:
        known = ', '.join(sorted(presets)) or '(none)'
        raise KeyError(f'unknown preset {name!r}; known presets: {known}') from None
