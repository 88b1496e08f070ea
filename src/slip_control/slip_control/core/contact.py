# SPDX-License-Identifier: Apache-2.0
"""Contact properties of the two finger pads (control_and_estimation §3.1, §3.7; CE-4).

Immutable mirrors of ``slip_msgs/FingerContact`` and ``slip_msgs/ContactProperties``. Values a
fit did not produce are NaN, never a placeholder number; every set carries its ``source`` and
per-finger validity flags, and ``valid`` is derived from the flags so it cannot disagree with
them.

Per finger (SI):

* ``mu_c`` [-] Coulomb coefficient, ``mu_s = a_mu_s · mu_c`` [-], ``mu_v`` [1/(m/s)];
* ``r`` [m] torsional radius (``τ_max = mu_c · r · f_n``), ``u`` [m²] torsional viscous term;
* ``mu_c_std`` [-], ``r_std`` [m]: 1-σ uncertainty (NaN if unknown).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from enum import IntEnum


class ContactSource(IntEnum):
    """Where a property set came from (mirrors ``ContactProperties.SOURCE_*``)."""

    DEFAULT = 0
    ESTIMATED = 1
    PRESET = 2
    GROUND_TRUTH = 3


NAN = float('nan')


@dataclass(frozen=True, slots=True)
class FingerContact:
    """Contact properties of one pad (fields and units as ``slip_msgs/FingerContact``)."""

    mu_c: float = NAN
    mu_s: float = NAN
    mu_v: float = NAN
    r: float = NAN
    u: float = NAN
    mu_c_std: float = NAN
    r_std: float = NAN
    n_linear: int = 0
    n_static: int = 0
    n_rotational: int = 0
    linear_residual_rms: float = NAN
    rotational_residual_rms: float = NAN
    linear_valid: bool = False
    viscous_valid: bool = False
    static_valid: bool = False
    rotational_valid: bool = False

    def without_rotational(self) -> FingerContact:
        """Copy with the rotational result cleared (NaN, invalid): it depends on ``mu_c``."""
        return replace(self, r=NAN, u=NAN, r_std=NAN, n_rotational=0,
                       rotational_residual_rms=NAN, rotational_valid=False)


@dataclass(frozen=True, slots=True)
class ContactProperties:
    """Contact properties of both fingers (mirrors ``slip_msgs/ContactProperties``).

    Attributes:
        finger_1: Properties of finger 1's pad.
        finger_2: Properties of finger 2's pad.
        source: Origin of the set (`ContactSource`).
        preset_name: Preset or object name; empty otherwise.
        online_updated: ``mu_c`` and ``r`` were refined by the online estimator.
    """

    finger_1: FingerContact = field(default_factory=FingerContact)
    finger_2: FingerContact = field(default_factory=FingerContact)
    source: ContactSource = ContactSource.DEFAULT
    preset_name: str = ''
    online_updated: bool = False

    @property
    def valid(self) -> bool:
        """Both fingers ``linear_valid`` and ``rotational_valid``; always false for DEFAULT."""
        if self.source == ContactSource.DEFAULT:
            return False
        return all(f.linear_valid and f.rotational_valid for f in (self.finger_1, self.finger_2))

    @property
    def linear_valid(self) -> bool:
        """Both fingers have a valid ``mu_c`` (and the set is not DEFAULT)."""
        if self.source == ContactSource.DEFAULT:
            return False
        return self.finger_1.linear_valid and self.finger_2.linear_valid

    def finger(self, k: int) -> FingerContact:
        """Properties of finger ``k`` (1 or 2)."""
        if k == 1:
            return self.finger_1
        if k == 2:
            return self.finger_2
        raise ValueError(f'finger must be 1 or 2, got {k!r}')

    def mean_mu_c(self) -> float:
        """``(mu_c1 + mu_c2)/2`` [-] as the slip controllers use it (§1.2)."""
        return 0.5 * (self.finger_1.mu_c + self.finger_2.mu_c)

    def mean_r(self) -> float:
        """``(r1 + r2)/2`` [m] as the slip controllers use it (§1.2)."""
        return 0.5 * (self.finger_1.r + self.finger_2.r)

    @staticmethod
    def default() -> ContactProperties:
        """The reference's initial values (§3.7), source DEFAULT and never valid.

        ``mu_c = 1``, ``mu_s = mu_c`` (``a_mu_s = 1``), ``mu_v = 0.1`` 1/(m/s), ``r = 0.01`` m,
        ``u = r²``; all flags false. Exists so a node has something typed to publish before any
        estimate; no consumer may treat it as a measurement.
        """
        f = FingerContact(mu_c=1.0, mu_s=1.0, mu_v=0.1, r=0.01, u=1e-4)
        return ContactProperties(finger_1=f, finger_2=f, source=ContactSource.DEFAULT)

    def describe(self) -> str:
        """One line for logs and service messages."""
        def one(f: FingerContact) -> str:
            return (f'mu_c={f.mu_c:.3f} mu_s={f.mu_s:.3f} mu_v={f.mu_v:.2f} '
                    f'r={_mm(f.r)}mm [{"L" if f.linear_valid else "l"}'
                    f'{"R" if f.rotational_valid else "r"}]')
        name = f' {self.preset_name!r}' if self.preset_name else ''
        online = ' online' if self.online_updated else ''
        return (f'{self.source.name}{name}{online} valid={self.valid}: '
                f'f1 {one(self.finger_1)}; f2 {one(self.finger_2)}')


def _mm(r: float) -> str:
    return 'nan' if not math.isfinite(r) else f'{1000.0 * r:.2f}'
