# SPDX-License-Identifier: Apache-2.0
"""In-process evaluation of the contact estimator and the slip controllers (issue 7 item 4).

The deployed cores run as agents of the friction_models `Harness` on a `SimCell`: no DDS, sim
time only, deterministic for a given `settings.EvalSettings` (seed, physics step), and as
fast as Python allows. The slip controller runs in the ``slip_controller`` node's own host
(`slip_control.core.controller_host.ControllerHost`, stale debounce included) and the
exploration is the experiment runner's own sequence, played by its step machine. Every outcome
is a frozen dataclass of physical quantities taken from the **simulator truth** (the
grasp-relative pose ``x, y, θ`` of the object in ``gripper_middle``, ``dropped``, normal forces)
next to what the sensors and the controller itself reported.

Modules, one concern each:

===================  ==========================================================================
``settings``         `EvalSettings`, `EvaluationError`, the reference presets
``agents``           the nodes' cores as harness agents (sensor inputs, estimator, controller host)
``truth``            `TruthProbe`: the simulator truth sampled during a scenario
``scene``            cells for the scenarios (homed, biased; true properties; held under HOLD)
``sim_runner_cell``  the runner's cell seam on the simulated cell; runner modes played in process
``estimation``       the runner's exploration → estimate vs truth; exploring without contact
``holding``          pick-up and hold under disturbance
``trajectories``     LINEAR and ROTATIONAL slips
``hinge``            HINGE through 60°
``faults``           a sensor stream stops mid-slip
``online``           ONLINE refinement during controlled slip
``table``            every scenario per preset (`evaluate_preset`, `evaluate_all`)
``report``           the text tables (CLI: ``slip_evaluate``)
===================  ==========================================================================

Contact properties for the controller scenarios: by default the simulator's true per-finger
values (source ``GROUND_TRUTH``, flags from the estimator's plausibility limits), so a
controller scenario does not depend on the estimator; `table.evaluate_all` passes the
properties estimated in the same run (the real pipeline) unless told otherwise.
"""
