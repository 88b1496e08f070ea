# SPDX-License-Identifier: Apache-2.0
"""Gripper actuator of the simulated cell: finger travel and grasp force from the motor voltage.

ROS-free and deterministic (time is passed in).

Model (hardware_protocols §2.4)
-------------------------------
Quasi-static finger model in the opening ``x`` [m] (motor and finger inertia neglected, as in
the shared firmware emulator), positive voltage opens:

    D_f ẋ = k_FV V_eff + k_c (w − x)⁺ + k_s (−x)⁺,    D_f = c_guide + k_FV k_e / k_open,
    V_eff = clip(V, ±V_phase),  x ≤ stroke,

where ``w`` is the object thickness (pad/object compliance ``k_c``; absent when the pads are
not on the object) and ``k_s`` the pad-to-pad stop. At stall the grasp force is exactly
``f_n = k_c (w − x) = k_FV |V|`` (the driver's 3.9166 N/V); while the fingers move, back-EMF
(``k_e``) lowers it. Implicit Euler in ``x``. The ``first_order`` alternative moves the
fingers the same way in free air but, in contact, lets ``f_n`` follow ``max(0, −k_FV V_eff)``
with a time constant. The motor angle is ``θ_m = θ_closed + x / k_open``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from slip_cell_common.core.param_schema import ranged_field as _f

__all__ = [
    'FingerActuator',
    'SimActuatorParams',
]


@dataclass(frozen=True)
class SimActuatorParams:
    """Gripper actuator of the simulation (parameter group ``actuator``; SI, volts at the link).

    The constants the driver uses (``newton_per_volt``, ``voltage_limit``,
    ``opening_per_rad``) default to the calibrated values of hardware_protocols §2.4.
    """

    model: str = field(default='voltage', metadata={
        'choices': ('voltage', 'first_order'),
        'description': 'voltage: motor with back-EMF and finger travel; first_order: force lag'})
    newton_per_volt: float = _f(3.9166, 'N/V', 0.1, 100.0, 'stall grasp force per volt')
    voltage_limit: float = _f(20.0, 'V', 0.5, 20.0, 'host clip of the voltage command')
    max_phase_voltage: float = _f(20.0 / math.sqrt(3.0), 'V', 0.5, 20.0,
                                  'voltage the driver can apply (SVPWM ceiling)')
    opening_per_rad: float = _f(0.0086751614, 'm/rad', 1.0e-4, 0.1,
                                'finger separation per motor radian')
    stroke: float = _f(0.08, 'm', 0.005, 0.5, 'opening at the open limit')
    back_emf: float = _f(0.4, 'V·s/rad', 0.0, 10.0, 'back-EMF constant (motor side)')
    guide_damping: float = _f(5.0, 'N·s/m', 0.0, 1.0e4, 'viscous damping of the finger guides')
    contact_stiffness: float = _f(2.0e4, 'N/m', 1.0e2, 1.0e7,
                                  'pad/object compliance along the grasp axis')
    stop_stiffness: float = _f(1.0e6, 'N/m', 1.0e3, 1.0e8, 'pad-to-pad stiffness when closed')
    time_constant: float = _f(0.01, 's', 1.0e-4, 1.0, 'first_order model: force lag')
    encoder_counts: int = field(default=4096, metadata={
        'unit': 'counts/rev', 'range': (16, 1 << 20), 'description': 'motor encoder resolution'})



class FingerActuator:
    """Finger travel and grasp force from the motor voltage (module docstring).

    Args:
        params: Actuator constants.
        opening: Initial opening [m].
    """

    def __init__(self, params: SimActuatorParams, opening: float) -> None:
        self.p = params
        self.x = opening
        self.rate = 0.0
        self.f_n = 0.0        #: pad–object normal force [N]
        self.f_stop = 0.0     #: pad–pad force at the closed stop [N]
        self._damp = params.guide_damping + \
            params.newton_per_volt * params.back_emf / params.opening_per_rad
        self._first_order = params.model == 'first_order'

    def place(self, opening: float) -> None:
        """Set the opening at rest (no force)."""
        self.x = opening
        self.rate = 0.0
        self.f_n = 0.0
        self.f_stop = 0.0

    def step(self, dt: float, voltage_v: float, width: float) -> None:
        """Advance by ``dt`` [s] with the applied voltage ``voltage_v`` [V] (positive opens).

        Args:
            dt: Step [s].
            voltage_v: Motor q-axis voltage [V].
            width: Object thickness between the pads [m], or a negative value when the pads
                are not on the object.
        """
        p = self.p
        v = min(max(voltage_v, -p.max_phase_voltage), p.max_phase_voltage)
        drive = p.newton_per_volt * v
        x0 = self.x
        if self._first_order and width >= 0.0 and (x0 <= width or self.f_n > 0.0):
            target = max(0.0, -drive)
            self.f_n += (target - self.f_n) * (1.0 - math.exp(-dt / p.time_constant))
            if target <= 0.0 and self.f_n < 1e-3 and drive > 0.0:
                self.f_n = 0.0
                x1 = min(width + dt * drive / self._damp, p.stroke)
            else:
                x1 = width - self.f_n / p.contact_stiffness
            self.rate = (x1 - x0) / dt
            self.x = x1
            self.f_stop = 0.0
            return
        h = dt / self._damp
        kc, ks = p.contact_stiffness, p.stop_stiffness
        on_object = width >= 0.0
        x1 = x0
        guess = x0
        for _ in range(3):
            # Springs active at the guess: object compliance (x < w), closed stop (x < 0).
            squeezed = on_object and guess < width
            k_sum = kc if squeezed else 0.0
            kw = kc * width if squeezed else 0.0
            if guess < 0.0:
                k_sum += ks
            x1 = (x0 + h * (drive + kw)) / (1.0 + h * k_sum)
            if (on_object and x1 < width) == squeezed and (x1 < 0.0) == (guess < 0.0):
                break
            guess = x1
        if x1 > p.stroke:
            x1 = p.stroke
        self.rate = (x1 - x0) / dt
        self.x = x1
        self.f_n = kc * (width - x1) if (on_object and x1 < width) else 0.0
        self.f_stop = ks * (-x1) if x1 < 0.0 else 0.0
