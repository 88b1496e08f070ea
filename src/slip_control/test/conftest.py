# SPDX-License-Identifier: Apache-2.0
"""Helpers for the slip_control core tests: snapshots built from gripper_middle values."""
from __future__ import annotations

from collections.abc import Callable

import pytest

from slip_control.core.contact import ContactProperties, ContactSource, FingerContact
from slip_control.core.params import SlipControllerParams
from slip_control.core.signals import SensorSnapshot, TwistSample, WrenchSample
from slip_gripper_driver.core.frames import FrameParams, planar_from_middle

FRAMES = FrameParams()


def middle_snapshot(stamp: float, *, f: tuple[float, float] = (0.0, 0.0), tz: float = 0.0,
                    v: tuple[float, float] = (0.0, 0.0), omega: float = 0.0,
                    normal: float = 5.0, ft_stamp: float | None = None,
                    v2_stamp: float | None = None) -> SensorSnapshot:
    """Both fingers seeing the same ``gripper_middle`` force, torque, velocity and rate."""
    ws, ts = [], []
    for k in (1, 2):
        fx, fy, t = planar_from_middle(FRAMES, k, f[0], f[1], tz)
        ws.append(WrenchSample(fx, fy, -normal, t, stamp if ft_stamp is None else ft_stamp))
        vx, vy, w = planar_from_middle(FRAMES, k, v[0], v[1], omega)
        s = stamp if (k == 1 or v2_stamp is None) else v2_stamp
        ts.append(TwistSample(vx, vy, w, s))
    return SensorSnapshot(ws[0], ws[1], ts[0], ts[1])


def finger(mu_c: float = 0.4, r: float = 0.005, *, linear_valid: bool = True,
           rotational_valid: bool = True) -> FingerContact:
    """A finger result with the given values and flags."""
    return FingerContact(mu_c=mu_c, mu_s=mu_c, mu_v=0.0, r=r, u=r * r, mu_c_std=0.005,
                         r_std=0.0002, n_linear=50, n_static=5, n_rotational=50,
                         linear_valid=linear_valid, viscous_valid=False, static_valid=True,
                         rotational_valid=rotational_valid)


def props(mu_c: float = 0.4, r: float = 0.005, *,
          source: ContactSource = ContactSource.ESTIMATED, linear_valid: bool = True,
          rotational_valid: bool = True, name: str = '') -> ContactProperties:
    """A two-finger property set with identical fingers."""
    f = finger(mu_c, r, linear_valid=linear_valid, rotational_valid=rotational_valid)
    return ContactProperties(f, f, source, preset_name=name)


@pytest.fixture
def params() -> SlipControllerParams:
    return SlipControllerParams()


@pytest.fixture
def snap() -> Callable[..., SensorSnapshot]:
    return middle_snapshot


@pytest.fixture
def make_props() -> Callable[..., ContactProperties]:
    return props


@pytest.fixture
def make_finger() -> Callable[..., FingerContact]:
    return finger
