# SPDX-License-Identifier: Apache-2.0
"""The contact-estimation exploration (control_and_estimation §3.8): the one procedure.

With the object standing on the table between the pads at the pick-up pose:

1. grasp with ``grasp.force`` for ``grasp.wait`` if not holding yet (no HOLD: there are no
   valid properties yet); HOLD on if allowed, then slip mode OFF, so nothing fights the
   moves;
2. command the exploration force ``estimation.force`` (5 N);
3. LINEAR phase for ``estimation.linear_window`` while the tool descends
   ``estimation.descent`` (0.01 m) in ``estimation.descent_time``: the table holds the
   object, which slides up between the pads;
4. ROTATIONAL phase for ``estimation.rotational_window`` while the tool twists
   ``±estimation.twist_angle`` (0.1745 rad) about the grasp axis, ``estimation.twist_time``
   each way: the table stops the object turning, so the pads twist on it.

The procedure is step data (`slip_control.core.runner_steps`): the experiment runner plays it
in ``est_contact`` and ``demo``, and the in-process evaluation plays the same sequences on the
simulated cell through `slip_control.core.sequence_runner.SequenceRunner`.
"""
from __future__ import annotations

from slip_control.core.contact_estimator import EstimationPhase
from slip_control.core.controllers import SlipMode
from slip_control.core.mode_switch import ModeRequest
from slip_control.core.runner_steps import Action, Step, StepBuilder, make_step


def exploration_steps(b: StepBuilder) -> tuple[Step, ...]:
    """§3.8 steps 1–4 as runner steps, timed by the runner parameters of ``b``."""
    e = b.p.estimation
    return (
        *b.grasp(hold=False, when={'holding': False}),
        b.mode('explore: HOLD on (if allowed)', ModeRequest(int(SlipMode.HOLD)), optional=True),
        b.mode('explore: slip mode OFF', ModeRequest(int(SlipMode.OFF))),
        b.force('explore: exploration force', e.force),
        make_step('explore: start linear phase', Action.START_ESTIMATION, b.to,
                  phase=EstimationPhase.LINEAR, duration=e.linear_window),
        b.move('explore: descend', lift=-e.descent, duration=e.descent_time),
        b.wait('explore: settle', max(0.0, e.linear_window - e.descent_time)),
        make_step('explore: start rotational phase', Action.START_ESTIMATION, b.to,
                  phase=EstimationPhase.ROTATIONAL, duration=e.rotational_window),
        b.move('explore: twist', rotation=e.twist_angle, duration=e.twist_time),
        b.move('explore: twist back', rotation=-e.twist_angle, duration=e.twist_time),
        b.wait('explore: finish window', max(0.0, e.rotational_window - 2.0 * e.twist_time)),
    )
