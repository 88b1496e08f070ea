# SPDX-License-Identifier: Apache-2.0
"""Planar twists and wrenches in the pad contact frame, and their transport (spec §1).

Frame: x right, y up, z out of the pad towards the object; torque positive counter-clockwise
about +z. A **twist** ``(vx, vy, ω)`` is the sliding velocity of the *object relative to the
pad* at a named reference point; a material point at offset ρ from it moves with
``v(ρ) = (vx − ω ρy, vy + ω ρx)``. A **wrench** ``(fx, fy, τ)`` is the friction acting *on the
object*. Transport between reference points a and b:

    twist:   v_b = v_a + ω ẑ × (b − a)
    wrench:  τ_b = τ_a + (a − b) × f,      a × f = ax·fy − ay·fx.

The functions accept floats or numpy arrays (broadcast element-wise), so batches of contacts
transport with the same code.
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import Literal, NamedTuple, TypeVar

import numpy as np
from numpy.typing import NDArray

__all__ = [
    'BatchWrench',
    'Frame',
    'Twist',
    'Wrench',
    'centre_of_rotation',
    'transport_twist',
    'transport_wrench',
]

_T = TypeVar('_T', float, NDArray[np.float64])

#: Reference point of a twist passed to a planar model: the pad centre (grid origin) or the
#: centre of pressure.
Frame = Literal['pad', 'cop']


class Twist(NamedTuple):
    """Planar sliding twist of the object relative to the pad at a reference point.

    Attributes:
        vx: Linear velocity along x [m/s].
        vy: Linear velocity along y [m/s].
        omega: Angular velocity about +z [rad/s].
    """

    vx: float
    vy: float
    omega: float


class Wrench(NamedTuple):
    """Planar friction wrench on the object, returned by the planar models' ``step``.

    The force is the same at every reference point; the torque is given about both the pad
    centre (grid origin) and the centre of pressure.

    Attributes:
        fx: Force along x [N].
        fy: Force along y [N].
        tau: Torque about +z at the pad centre [N·m].
        tau_cop: Torque about +z at the centre of pressure [N·m].
    """

    fx: float
    fy: float
    tau: float
    tau_cop: float

    def at_pad(self) -> tuple[float, float, float]:
        """Return ``(fx, fy, τ)`` about the pad centre [N, N, N·m]."""
        return (self.fx, self.fy, self.tau)

    def at_cop(self) -> tuple[float, float, float]:
        """Return ``(fx, fy, τ)`` about the centre of pressure [N, N, N·m]."""
        return (self.fx, self.fy, self.tau_cop)


class BatchWrench(NamedTuple):
    """Friction wrenches of N independent contacts; every field has shape (N,).

    Attributes:
        fx: Forces along x [N].
        fy: Forces along y [N].
        tau: Torques about each contact's pad centre [N·m].
        tau_cop: Torques about each contact's centre of pressure [N·m].
    """

    fx: NDArray[np.float64]
    fy: NDArray[np.float64]
    tau: NDArray[np.float64]
    tau_cop: NDArray[np.float64]

    def at_pad(self) -> NDArray[np.float64]:
        """Return an (N, 3) array ``(fx, fy, τ)`` about the pad centres."""
        return np.stack((self.fx, self.fy, self.tau), axis=-1)

    def at_cop(self) -> NDArray[np.float64]:
        """Return an (N, 3) array ``(fx, fy, τ)`` about the centres of pressure."""
        return np.stack((self.fx, self.fy, self.tau_cop), axis=-1)


def transport_twist(vx: _T, vy: _T, omega: _T, a: Sequence[float] | NDArray[np.float64],
                    b: Sequence[float] | NDArray[np.float64]) -> tuple[_T, _T, _T]:
    """Move a twist from reference point ``a`` to ``b``: ``v_b = v_a + ω ẑ × (b − a)``.

    Args:
        vx: x velocity at ``a`` [m/s].
        vy: y velocity at ``a`` [m/s].
        omega: Angular velocity [rad/s] (unchanged).
        a: Current reference point (x, y) [m]; arrays of shape (2, ...) broadcast.
        b: New reference point (x, y) [m].

    Returns:
        ``(vx_b, vy_b, omega)``.
    """
    dx = b[0] - a[0]
    dy = b[1] - a[1]
    return vx - omega * dy, vy + omega * dx, omega


def transport_wrench(fx: _T, fy: _T, tau: _T, a: Sequence[float] | NDArray[np.float64],
                     b: Sequence[float] | NDArray[np.float64]) -> tuple[_T, _T, _T]:
    """Move a wrench from reference point ``a`` to ``b``: ``τ_b = τ_a + (a − b) × f``.

    Args:
        fx: Force x [N].
        fy: Force y [N].
        tau: Torque about ``a`` [N·m].
        a: Current reference point (x, y) [m].
        b: New reference point (x, y) [m].

    Returns:
        ``(fx, fy, τ_b)``.
    """
    rx = a[0] - b[0]
    ry = a[1] - b[1]
    return fx, fy, tau + rx * fy - ry * fx


def centre_of_rotation(vx: float, vy: float, omega: float,
                       at: Sequence[float] = (0.0, 0.0),
                       omega_min: float = 1e-10) -> tuple[float, float] | None:
    """Instantaneous centre of rotation of a twist given at point ``at`` (spec §1).

    Args:
        vx: x velocity at ``at`` [m/s].
        vy: y velocity at ``at`` [m/s].
        omega: Angular velocity [rad/s].
        at: Reference point of the twist [m].
        omega_min: Below this ``|ω|`` [rad/s] the motion counts as a pure translation.

    Returns:
        ``at + (−vy/ω, vx/ω)`` [m], or ``None`` for a (near-)pure translation.
    """
    if abs(omega) < omega_min:
        return None
    return (at[0] - vy / omega, at[1] + vx / omega)
