# SPDX-License-Identifier: Apache-2.0
"""The table of the simulated cell: penalty contacts of the object's corners (ROS-free).

A horizontal line at ``Y = table.height``; unilateral penalty contacts at the object's four
corners (normally only the two bottom ones touch): normal force
``N = k δ⁺ − c v_n⁺ ≥ 0`` on the penetration ``δ``, tangential anchor spring
``F_t = −k_t s⁺ − c_t v_t⁺`` limited to ``|F_t| ≤ μ_table N`` (Coulomb sliding beyond it), all
inside the same implicit solve and active set. Corners enter speculatively (when the
penetration predicted from the current velocity is positive), so an impact never starts
one step late inside the table, which would create spring energy from nothing. The table
stops the object from moving down and, through the two corner normals, from turning: this is
what makes the estimation exploration (push down 1 cm, twist ±10°) slide and twist the pads
on the object.

`TableContact` holds the corner state and adds the table's part to the plant's implicit solve
(:mod:`.plant`, "Time stepping").
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from slip_cell_common.core.param_schema import ranged_field as _f

__all__ = [
    'TableContact',
    'TableParams',
]


@dataclass(frozen=True)
class TableParams:
    """The table the object can stand on (parameter group ``table``)."""

    enabled: bool = field(default=True, metadata={'description': 'simulate the table'})
    height: float = _f(0.0, 'm', -10.0, 10.0, 'world Y of the table surface')
    stiffness: float = _f(1.0e5, 'N/m', 1.0e2, 1.0e8, 'normal penalty stiffness per corner')
    damping: float = _f(300.0, 'N·s/m', 0.0, 1.0e5, 'normal damping per corner')
    tangential_stiffness: float = _f(1.0e5, 'N/m', 1.0e2, 1.0e8,
                                     'stick (anchor) stiffness per corner')
    tangential_damping: float = _f(300.0, 'N·s/m', 0.0, 1.0e5, 'stick damping per corner')


class TableContact:
    """Corner contacts of the object with the table, stepped by the plant (module docstring).

    Per physics step the plant takes the `candidates`, adds their `terms` to its implicit
    solve, lets `update_modes` change the active set until it settles and `commit`s the final
    velocity. A candidate is ``[index, e_x, e_y, δ, active, slide_sign]`` (``e`` = corner minus
    CoM in world axes [m], penetration ``δ`` [m], may be negative for a speculative contact).

    Args:
        params: Table settings.
        dt: Physics step [s].
    """

    def __init__(self, params: TableParams, dt: float) -> None:
        self.params = params
        self.dt = dt
        self.corners: tuple[tuple[float, float], ...] = ()
        self.radius = 0.0
        self.mu = 0.0
        self.normal_force = [0.0, 0.0, 0.0, 0.0]   #: per corner [N]
        self.anchor = [0.0, 0.0, 0.0, 0.0]         #: tangential anchor displacement [m]

    def set_object(self, corners: tuple[tuple[float, float], ...], mu: float) -> None:
        """Use an object's corners (relative to its CoM, object frame [m]) and table friction."""
        self.corners = corners
        self.radius = max(math.hypot(x, y) for x, y in corners)
        self.mu = mu

    def reset(self) -> None:
        """No corner loaded, no anchor stretched."""
        self.normal_force = [0.0, 0.0, 0.0, 0.0]
        self.anchor = [0.0, 0.0, 0.0, 0.0]

    def add_stored_energy(self, e: float, y: float, th: float) -> float:
        """``e`` plus the energy in the corner springs [J] for the object CoM height ``y`` [m]
        and angle ``th`` [rad]."""
        tp = self.params
        if tp.enabled:
            c, s = math.cos(th), math.sin(th)
            for i, (bx, by) in enumerate(self.corners):
                pen = tp.height - (y + s * bx + c * by)
                if pen > 0.0:
                    e += 0.5 * tp.stiffness * pen * pen
                    e += 0.5 * tp.tangential_stiffness * self.anchor[i] ** 2
        return e

    def candidates(self, y: float, th: float, vy: float, w: float) -> tuple[list[float], ...]:
        """Corners that touch the table by the end of the step (speculative contacts).

        A corner enters the solve when its penetration ``δ`` or its predicted penetration
        ``δ − dt·v_n`` (current normal velocity) is positive, so an approaching corner is
        caught in the step it would cross the surface instead of one step later (a late
        penalty contact would create spring energy from nothing). The solve keeps ``N ≥ 0``.

        Args:
            y: Object CoM height [m].
            th: Object angle [rad].
            vy: Vertical CoM velocity [m/s].
            w: Angular velocity [rad/s].
        """
        top = self.params.height
        margin = self.dt * (abs(vy) + abs(w) * self.radius)
        if y - self.radius - margin > top:
            return ()
        c, s = math.cos(th), math.sin(th)
        out = []
        dt = self.dt
        for i, (bx, by) in enumerate(self.corners):
            ex = c * bx - s * by
            ey = s * bx + c * by
            pen = top - (y + ey)
            if pen > 0.0 or pen - dt * (vy + w * ex) > 0.0:
                out.append([i, ex, ey, pen, 1.0, 0.0])
        return tuple(out)

    def terms(self, corners: tuple[list[float], ...]) -> tuple[list[float], list[float]]:
        """Implicit table contributions ``(H, r)`` for the current active sets.

        Per active corner with lever ``e`` (``J_n = (0, 1, e_x)``, ``J_t = (1, 0, −e_y)``):
        normal ``N = k δ − (k dt + c) J_n u⁺``; tangential stick
        ``F_t = −k_t s − (k_t dt + c_t) J_t u⁺``, or sliding ``F_t = ±μ N(u⁺)``.
        """
        tp = self.params
        kn, dn = tp.stiffness, tp.stiffness * self.dt + tp.damping
        kt = tp.tangential_stiffness
        dtn = kt * self.dt + tp.tangential_damping
        mu = self.mu
        cs = self.anchor
        h00 = h01 = h02 = h11 = h12 = h21 = h22 = h20 = 0.0
        r0 = r1 = r2 = 0.0
        for i, ex, ey, pen, active, sgn in corners:
            if not active:
                continue
            ns = kn * pen
            r1 += ns
            r2 += ns * ex
            h11 += dn
            h12 += dn * ex
            h21 += dn * ex
            h22 += dn * ex * ex
            if sgn == 0.0:
                fs = -kt * cs[int(i)]
                r0 += fs
                r2 -= ey * fs
                h00 += dtn
                h02 -= dtn * ey
                h20 -= dtn * ey
                h22 += dtn * ey * ey
            else:
                a = sgn * mu
                r0 += a * ns
                r2 -= ey * a * ns
                h01 += a * dn
                h02 += a * dn * ex
                h21 -= ey * a * dn
                h22 -= ey * a * dn * ex
        return [h00, h01, h02, 0.0, h11, h12, h20, h21, h22], [r0, r1, r2]

    def update_modes(self, corners: tuple[list[float], ...], ux: float, uy: float,
                     uw: float) -> bool:
        """Deactivate pulling corners, switch overloaded stick corners to sliding."""
        tp = self.params
        kn, dn = tp.stiffness, tp.stiffness * self.dt + tp.damping
        kt = tp.tangential_stiffness
        dtn = tp.tangential_stiffness * self.dt + tp.tangential_damping
        mu = self.mu
        changed = False
        for cr in corners:
            i, ex, ey, pen, active, sgn = cr
            if not active:
                continue
            n = kn * pen - dn * (uy + uw * ex)
            if n < 0.0:
                cr[4] = 0.0
                changed = True
                continue
            if sgn == 0.0:
                ft = -kt * self.anchor[int(i)] - dtn * (ux - uw * ey)
                if abs(ft) > mu * n:
                    cr[5] = 1.0 if ft > 0.0 else -1.0
                    changed = True
        return changed

    def commit(self, corners: tuple[list[float], ...], ux: float, uy: float, uw: float) -> bool:
        """Store corner forces and anchors after the final velocity; True when a corner
        touches (the object stands on the table)."""
        tp = self.params
        kn, dn = tp.stiffness, tp.stiffness * self.dt + tp.damping
        kt = tp.tangential_stiffness
        mu = self.mu
        touching = [False] * 4
        corner_n, corner_s = self.normal_force, self.anchor
        for i, ex, ey, pen, active, sgn in corners:
            ii = int(i)
            if not active:
                continue
            n = max(0.0, kn * pen - dn * (uy + uw * ex))
            corner_n[ii] = n
            touching[ii] = True
            if sgn == 0.0:
                corner_s[ii] += self.dt * (ux - uw * ey)
            else:
                corner_s[ii] = -sgn * mu * n / kt
        for ii in range(4):
            if not touching[ii]:
                corner_n[ii] = 0.0
                corner_s[ii] = 0.0
        return any(touching)
