# SPDX-License-Identifier: Apache-2.0
"""HOLD (§4.4) and HINGE (§4.7) laws with hand-computed numbers; stale-input rules (CE-3)."""
from __future__ import annotations

import math
from collections.abc import Callable

import pytest

from slip_control.core.controllers import (ControlContact, HingeController, HoldController,
                                           OffController, SlipMode)
from slip_control.core.params import SlipControllerParams
from slip_control.core.signals import SensorSnapshot

CONTACT = ControlContact(mu_c=0.4, r=0.005, r_valid=True)
DT = 1.0 / 120.0
Snap = Callable[..., SensorSnapshot]


def test_hold_law_hand_computed(params: SlipControllerParams, snap: Snap) -> None:
    h = HoldController(params, CONTACT)
    # F̄ = (0.3, −0.4) → ft 0.5 N; τ̄/r = 0.002/0.005 = 0.4 N → D = √0.41 = 0.6403 N;
    # D/μ_c = 1.6008 < floor 2 N → 2·2 = 4 N. v̄ = (3, 4) mm/s, r·ω̄ = 1 mm/s:
    # v_s = √26 mm/s → +100·0.0050990 = 0.50990 N.
    out = h.step(snap(1.0, f=(0.3, -0.4), tz=0.002, v=(0.003, 0.004), omega=0.2), 1.0)
    assert out.mode == SlipMode.HOLD and not out.safe_hold
    assert out.force == pytest.approx(4.0 + 100.0 * math.sqrt(26e-6), rel=1e-9)
    assert out.timeout == params.command_timeout
    # F̄ = (1.2, −1.6) → ft 2 N; τ̄/r = 1.5 N → D = 2.5 N; 2·2.5/0.4 = 12.5 N (rise at once).
    out = h.step(snap(1.0 + DT, f=(1.2, -1.6), tz=0.0075), 1.0 + DT)
    assert out.force == pytest.approx(12.5, rel=1e-9)
    # Fall: out ← 0.95·12.5 + 0.05·4.
    out = h.step(snap(1.0 + 2 * DT, f=(0.3, -0.4), tz=0.002), 1.0 + 2 * DT)
    assert out.force == pytest.approx(0.95 * 12.5 + 0.05 * 4.0, rel=1e-9)


def test_hold_fall_time_constant_at_120_hz(params: SlipControllerParams, snap: Snap) -> None:
    h = HoldController(params, CONTACT)
    t = 0.0
    high = h.step(snap(t, f=(0.0, 2.0)), t).force
    assert high == pytest.approx(2.0 * 2.0 / 0.4)
    low = 4.0                                            # floor case
    target = low + (high - low) * math.exp(-1.0)
    t_cross = None
    for i in range(1, 200):
        t = i * DT
        f = h.step(snap(t, f=(0.0, 0.1)), t).force
        assert f is not None and f < high
        if t_cross is None and f <= target:
            t_cross = t
    assert t_cross is not None
    assert t_cross == pytest.approx(-DT / math.log(0.95), abs=DT)     # ≈ 0.1625 s
    assert t_cross == pytest.approx(0.16, abs=0.01)


def test_hold_ignores_repeated_samples_and_unsynced_fingers(params: SlipControllerParams,
                                                            snap: Snap) -> None:
    h = HoldController(params, CONTACT)
    assert h.step(snap(0.0, f=(0.0, 2.0)), 0.0).force == pytest.approx(10.0)
    # A watchdog call with the same twist must not run the fall filter again.
    out = h.step(snap(0.0, f=(0.0, 0.1)), 0.005)
    assert out.force is None and out.reason == 'no new sample'
    out = h.step(snap(0.03, f=(0.0, 0.1), v2_stamp=0.0), 0.03)
    assert out.force is None and not out.status.synced
    assert h.last_force == pytest.approx(10.0)


def test_hold_stale_velocity_never_falls_but_rises(params: SlipControllerParams,
                                                   snap: Snap) -> None:
    h = HoldController(params, CONTACT)
    h.step(snap(0.0, f=(0.0, 1.2), v=(0.0, 0.01)), 0.0)        # 2·3 + 1 = 7 N
    assert h.last_force == pytest.approx(7.0)
    # Velocity stops at 0.0; F/T keeps coming with a smaller load: force must not fall.
    for i in range(1, 30):
        t = 0.06 + i * 0.01
        out = h.step(snap(0.0, f=(0.0, 0.2), ft_stamp=t), t)
        assert out.safe_hold and out.force == pytest.approx(7.0)
    # Load increases while velocity is stale: force rises at once (slip term 0).
    out = h.step(snap(0.0, f=(0.0, 2.0), ft_stamp=0.5), 0.5)
    assert out.safe_hold and out.force == pytest.approx(10.0)
    # Velocity back: normal law with the fall filter from 10 N.
    out = h.step(snap(0.6, f=(0.0, 0.2)), 0.6)
    assert not out.safe_hold and out.force == pytest.approx(0.95 * 10.0 + 0.05 * 4.0)


def test_hold_stale_ft_holds_last_output(params: SlipControllerParams, snap: Snap) -> None:
    h = HoldController(params, CONTACT)
    h.step(snap(0.0, f=(0.0, 2.0)), 0.0)
    out = h.step(snap(0.03, f=(0.0, 0.1), ft_stamp=0.0), 0.03)
    assert out.safe_hold and out.force == pytest.approx(10.0)
    assert 'F/T stale' in out.reason


def test_hold_without_radius_uses_tangential_load_only(params: SlipControllerParams,
                                                       snap: Snap) -> None:
    h = HoldController(params, ControlContact(mu_c=0.5))
    out = h.step(snap(0.0, f=(0.0, 2.0), tz=0.05, omega=1.0), 0.0)
    assert out.force == pytest.approx(2.0 * 2.0 / 0.5)


def test_hinge_law_and_stale_handover(params: SlipControllerParams, snap: Snap) -> None:
    c = HingeController(params, ControlContact(mu_c=0.5, r=0.005, r_valid=True))
    # 1.4·1/0.5 + 100·0.005 = 3.3 N; torque ignored.
    out = c.step(snap(0.0, f=(0.6, 0.8), tz=0.05, v=(0.003, -0.004), omega=2.0), 0.0)
    assert out.force == pytest.approx(3.3) and out.mode == SlipMode.HINGE
    out = c.step(snap(DT, f=(0.0, 0.01)), DT)
    assert out.force == pytest.approx(0.6)                       # floor
    out = c.step(snap(DT, f=(0.0, 1.0), ft_stamp=0.2), 0.2)      # velocity stale
    assert isinstance(out.next_controller, HoldController) and out.safe_hold
    # 2·max(D/μ_c, 2 N) = 2·max(1/0.5, 2) = 4 N, never below the hinge output.
    assert out.mode == SlipMode.HOLD and out.force == pytest.approx(4.0)


def test_off_publishes_nothing(params: SlipControllerParams, snap: Snap) -> None:
    out = OffController(params).step(snap(0.0, f=(0.0, 2.0)), 0.0)
    assert out.force is None and out.mode == SlipMode.OFF and out.status.all_fresh
