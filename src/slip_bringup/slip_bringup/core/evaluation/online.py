# SPDX-License-Identifier: Apache-2.0
"""Online refinement (§3.6) during controlled slip on the simulated cell, judged by the truth."""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

from friction_models.core.harness import default_motion_time

from slip_bringup.core.evaluation.agents import EstimatorAgent
from slip_bringup.core.evaluation.scene import controlled_scene, make_harness, true_properties
from slip_bringup.core.evaluation.settings import EvalSettings, EvaluationError
from slip_control.core.contact import ContactProperties, ContactSource
from slip_control.core.contact_estimator import EstimationPhase
from slip_control.core.controllers import SlipMode
from slip_control.core.mode_switch import ModeRequest


@dataclass(frozen=True)
class OnlineOutcome:
    """Outcome of `online_refinement`: per-finger values, finger 1 then finger 2.

    Attributes:
        preset: Object preset.
        start_scale: Factor applied to the true ``μ_c`` and ``r`` for the starting estimate.
        mu_c_true: True ``μ_c``.
        r_true: True ``r`` [m].
        mu_c_start: Starting ``μ_c`` (``start_scale · μ_c_true``).
        r_start: Starting ``r`` [m].
        mu_c_online: ``μ_c`` after the LINEAR slip with ONLINE running.
        r_online: ``r`` [m] after the ROTATIONAL slip with ONLINE running.
        published_linear: The estimator published an online-updated set during the LINEAR run.
        published_rotational: Same during the ROTATIONAL run.
        dropped: The object fell in either run.
    """

    preset: str
    start_scale: float
    mu_c_true: tuple[float, float]
    r_true: tuple[float, float]
    mu_c_start: tuple[float, float]
    r_start: tuple[float, float]
    mu_c_online: tuple[float, float]
    r_online: tuple[float, float]
    published_linear: bool
    published_rotational: bool
    dropped: bool

    @staticmethod
    def _rel(values: tuple[float, float], truth: tuple[float, float]) -> float:
        return max(abs(v - t) / t for v, t in zip(values, truth))

    @property
    def mu_c_error_start(self) -> float:
        """Largest relative ``μ_c`` error of the starting estimate [-]."""
        return self._rel(self.mu_c_start, self.mu_c_true)

    @property
    def mu_c_error_online(self) -> float:
        """Largest relative ``μ_c`` error after the online update [-]."""
        return self._rel(self.mu_c_online, self.mu_c_true)

    @property
    def r_error_start(self) -> float:
        """Largest relative ``r`` error of the starting estimate [-]."""
        return self._rel(self.r_start, self.r_true)

    @property
    def r_error_online(self) -> float:
        """Largest relative ``r`` error after the online update [-]."""
        return self._rel(self.r_online, self.r_true)


def _scaled(props: ContactProperties, scale: float) -> ContactProperties:
    """``props`` with every finger's ``μ_c`` and ``r`` multiplied by ``scale`` (source
    ESTIMATED, as a poor exploration would have published)."""
    return replace(props, source=ContactSource.ESTIMATED,
                   finger_1=replace(props.finger_1, mu_c=props.finger_1.mu_c * scale,
                                    r=props.finger_1.r * scale),
                   finger_2=replace(props.finger_2, mu_c=props.finger_2.mu_c * scale,
                                    r=props.finger_2.r * scale))


def online_refinement(preset: str, start_scale: float = 0.8,
                      settings: EvalSettings = EvalSettings()) -> OnlineOutcome:
    """How well the ONLINE phase (§3.6) corrects a wrong estimate during controlled slip.

    Starts from the true properties scaled by ``start_scale`` (both ``μ_c`` and ``r``), which
    the controllers also use. Run 1: ONLINE on, LINEAR 2 cm in 2 s (held in the air; refines
    ``μ_c``). Run 2 starts from the properties run 1 ended with: ONLINE on, ROTATIONAL 20° in
    2 s from 90° off vertical (refines ``r``, which needs ``μ_c``). The estimator is the node's
    core with ``online.enabled``.
    """
    if not (math.isfinite(start_scale) and start_scale > 0.0):
        raise ValueError(f'start_scale must be finite and > 0, got {start_scale!r}')
    est_params = replace(settings.estimator,
                         online=replace(settings.estimator.online, enabled=True))
    probe_cell = make_harness(preset, settings).cell
    truth = true_properties(probe_cell, est_params)
    start = _scaled(truth, start_scale)

    def run(initial: ContactProperties, request: ModeRequest, tilt: float
            ) -> tuple[ContactProperties, bool, bool]:
        h, ctl, _ = controlled_scene(preset, settings, initial)
        if tilt:
            h.move(rotation=tilt, duration=default_motion_time(0.0, tilt))
            h.run_for(0.5)
        agent = EstimatorAgent(est_params, initial)
        h.add_agent(agent)
        outcome = agent.start(h, EstimationPhase.ONLINE, 0.0)
        if not outcome.accepted:
            raise EvaluationError(f'{preset}: ONLINE refused: {outcome.message}')
        ctl.require_mode(h, request)
        h.run_for(request.duration + 1.0)
        props = agent.estimator.properties
        return props, props.online_updated, h.state().dropped

    lin, pub_lin, drop_lin = run(start, ModeRequest(int(SlipMode.LINEAR), duration=2.0,
                                                    distance=0.02, latch_direction=True), 0.0)
    # The rotation starts from what the slide left (the demo's order: linear, then rotational).
    rot, pub_rot, drop_rot = run(lin, ModeRequest(int(SlipMode.ROTATIONAL), duration=2.0,
                                                  angle=math.radians(20.0)),
                                 -math.radians(90.0))

    def pair(p: ContactProperties, name: str) -> tuple[float, float]:
        return getattr(p.finger_1, name), getattr(p.finger_2, name)

    return OnlineOutcome(
        preset=preset, start_scale=start_scale, mu_c_true=pair(truth, 'mu_c'),
        r_true=pair(truth, 'r'), mu_c_start=pair(start, 'mu_c'), r_start=pair(start, 'r'),
        mu_c_online=pair(lin, 'mu_c'), r_online=pair(rot, 'r'), published_linear=pub_lin,
        published_rotational=pub_rot, dropped=drop_lin or drop_rot)


#: Starting errors of `online_refinement` in the table: true ``μ_c`` and ``r`` times these.
ONLINE_START_SCALES: tuple[float, ...] = (0.8, 1.2)
