# SPDX-License-Identifier: Apache-2.0
"""Stream faults on the simulated cell: a sensor stream stops in the middle of a LINEAR slip."""
from __future__ import annotations

import math
from dataclasses import dataclass

from slip_bringup.core.evaluation.scene import controlled_scene
from slip_bringup.core.evaluation.settings import EvalSettings
from slip_bringup.core.evaluation.truth import centre_point_displacement
from slip_control.core.contact import ContactProperties
from slip_control.core.controllers import SlipMode, SlipResult
from slip_control.core.mode_switch import ModeRequest

_NAN = math.nan


@dataclass(frozen=True)
class FaultOutcome:
    """Outcome of `stream_fault`.

    Attributes:
        preset: Object preset.
        stream: ``'ft'`` or ``'velocity'``.
        t_cut: Time the stream stopped, from the LINEAR request [s].
        reaction: Time from the cut to the controller's first safe-hold output [s] (NaN: none).
        result: The trajectory's result (e.g. "F/T stale").
        mode_after: Mode in charge at the end.
        force_at_cut: Last force commanded before the cut [N].
        force_after: Last force commanded at the end [N].
        slip_after: Largest true displacement of the grasp point after the cut [m].
        creep: True displacement over the last 0.5 s of the observation [m] (≈ 0 once the
            safe hold has stopped the object).
        dropped: The object fell.
        deferred_steps: Control steps the host held back after the cut while the stale
            verdict was being confirmed (`StaleDebounce`, as in the node).
    """

    preset: str
    stream: str
    t_cut: float
    reaction: float
    result: SlipResult | None
    mode_after: SlipMode
    force_at_cut: float
    force_after: float
    slip_after: float
    creep: float
    dropped: bool
    deferred_steps: int


def stream_fault(preset: str, stream: str, at: float, distance: float = 0.02,
                 duration: float = 2.0, observe: float = 1.5,
                 settings: EvalSettings = EvalSettings(),
                 properties: ContactProperties | None = None) -> FaultOutcome:
    """Stop the F/T (``'ft'``) or velocity (``'velocity'``) stream ``at`` [s] into a LINEAR
    slip and watch the controller and the object for ``observe`` [s]."""
    if stream not in ('ft', 'velocity'):
        raise ValueError(f"stream must be 'ft' or 'velocity', got {stream!r}")
    h, ctl, probe = controlled_scene(preset, settings, properties)
    t0 = h.t
    ctl.require_mode(h, ModeRequest(int(SlipMode.LINEAR), duration=duration, distance=distance,
                                    latch_direction=True))
    h.run_until_time(t0 + at)
    t_cut = h.t
    s_cut = h.state()
    before = [f for t, f in ctl.commands if t <= t_cut]
    if stream == 'ft':
        ctl.cut_ft(t_cut)
    else:
        ctl.cut_velocity(t_cut)
    ctl.first_safe_hold = None
    deferred_before = ctl.host.steps_deferred
    h.run_for(max(0.0, observe - 0.5))
    s_late = h.state()
    h.run_for(min(0.5, observe))
    s = h.state()
    ended = [r for t, r in ctl.results if t >= t_cut]
    safe = ctl.first_safe_hold
    return FaultOutcome(
        preset=preset, stream=stream, t_cut=t_cut - t0,
        reaction=(safe - t_cut) if safe is not None else _NAN,
        result=ended[0] if ended else None, mode_after=ctl.mode,
        force_at_cut=before[-1] if before else _NAN,
        force_after=ctl.commands[-1][1] if ctl.commands else _NAN,
        slip_after=probe.peak_displacement(t_cut, h.t, s_cut.x, s_cut.y, s_cut.theta),
        creep=math.hypot(*centre_point_displacement(
            s_late.x, s_late.y, s_late.theta, s.x, s.y, s.theta)), dropped=s.dropped,
        deferred_steps=ctl.host.steps_deferred - deferred_before)
