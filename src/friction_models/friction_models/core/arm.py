# SPDX-License-Identifier: Apache-2.0
"""The arm of the simulated cell: gripper pose along relative minimum-jerk moves (ROS-free).

The gripper pose ``(X_g, Y_g, φ)`` is the origin of ``gripper_middle`` in the world plane and
its rotation about the grasp axis (frames as in :mod:`.plant`). A move translates the grasp
centre by ``(lateral, lift)`` [m] and turns it by ``rotation`` [rad] along one quintic
minimum-jerk time profile, so velocity and acceleration are zero at both ends.
"""
from __future__ import annotations

__all__ = [
    'ArmTrajectory',
    'minimum_jerk',
]


def minimum_jerk(tau: float) -> tuple[float, float, float]:
    """Quintic minimum-jerk profile ``s(τ) = 10τ³ − 15τ⁴ + 6τ⁵`` and its τ-derivatives.

    Args:
        tau: Normalised time in [0, 1] (clipped).

    Returns:
        ``(s, ds/dτ, d²s/dτ²)``; zero velocity and acceleration at both ends.
    """
    if tau <= 0.0:
        return 0.0, 0.0, 0.0
    if tau >= 1.0:
        return 1.0, 0.0, 0.0
    t2 = tau * tau
    return (t2 * tau * (10.0 + tau * (-15.0 + 6.0 * tau)),
            30.0 * t2 * (1.0 + tau * (-2.0 + tau)),
            60.0 * tau * (1.0 + tau * (-3.0 + 2.0 * tau)))


class ArmTrajectory:
    """Gripper pose ``(X_g, Y_g, φ)`` driven by relative minimum-jerk moves (world frame).

    ``move`` starts a straight-line move of the grasp centre by ``(lateral, lift)`` [m] and a
    rotation ``rotation`` [rad] about the grasp axis, all with the same quintic time profile.
    """

    __slots__ = ('_start', '_delta', '_t0', '_duration', '_pose')

    def __init__(self, x: float, y: float, phi: float) -> None:
        self._pose = (x, y, phi)
        self._start = (x, y, phi)
        self._delta = (0.0, 0.0, 0.0)
        self._t0 = 0.0
        self._duration = 0.0

    def place(self, x: float, y: float, phi: float) -> None:
        """Put the gripper at a pose at rest (cancels a move)."""
        self.__init__(x, y, phi)  # type: ignore[misc]

    def move(self, t: float, lateral: float, lift: float, rotation: float,
             duration: float) -> float:
        """Start a relative move at ``t`` [s]; returns its end time [s]."""
        x, y, phi = self.evaluate(t)[:3]
        self._start = (x, y, phi)
        self._delta = (lateral, lift, rotation)
        self._t0 = t
        self._duration = duration
        return t + duration

    def moving(self, t: float) -> bool:
        """True while a move is in progress at ``t``."""
        return self._duration > 0.0 and t < self._t0 + self._duration

    @property
    def end_time(self) -> float:
        """End of the current (or last) move [s]."""
        return self._t0 + self._duration

    def evaluate(self, t: float) -> tuple[float, float, float, float, float, float]:
        """Pose and velocity ``(X_g, Y_g, φ, Ẋ_g, Ẏ_g, φ̇)`` at ``t`` [m, m, rad, m/s, rad/s]."""
        if self._duration <= 0.0:
            x, y, p = self._pose
            return x, y, p, 0.0, 0.0, 0.0
        tau = (t - self._t0) / self._duration
        s, ds, _ = minimum_jerk(tau)
        x0, y0, p0 = self._start
        dx, dy, dp = self._delta
        k = ds / self._duration
        if tau >= 1.0:
            self._pose = (x0 + dx, y0 + dy, p0 + dp)
            self._duration = 0.0
            x, y, p = self._pose
            return x, y, p, 0.0, 0.0, 0.0
        return x0 + s * dx, y0 + s * dy, p0 + s * dp, k * dx, k * dy, k * dp

