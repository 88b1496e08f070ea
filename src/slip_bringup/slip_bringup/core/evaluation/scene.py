# SPDX-License-Identifier: Apache-2.0
"""Cells for the scenarios: a homed, biased simulated cell with its agents (SI units)."""
from __future__ import annotations

from dataclasses import replace

from friction_models.core.harness import Harness
from friction_models.core.presets import ObjectPreset, load_presets, reference_presets
from friction_models.core.sensors import VelocitySensorParams
from friction_models.core.sim_cell import SimCell, SimParams

from slip_bringup.core.evaluation.agents import ControllerAgent
from slip_bringup.core.evaluation.settings import EvalSettings
from slip_bringup.core.evaluation.truth import TruthProbe
from slip_control.core.contact import ContactProperties, ContactSource
from slip_control.core.contact_presets import preset_finger
from slip_control.core.controllers import SlipMode
from slip_control.core.mode_switch import ModeRequest
from slip_control.core.params import ContactEstimatorParams, SlipControllerParams


def presets(settings: EvalSettings) -> dict[str, ObjectPreset]:
    """The object presets the cells are built from: the reference objects (or a YAML file's,
    which include them) plus ``settings.objects``."""
    found = load_presets(settings.presets_file) if settings.presets_file else reference_presets()
    found.update(settings.objects)
    return found


def make_harness(preset: str, settings: EvalSettings = EvalSettings()) -> Harness:
    """A homed, biased cell with ``preset`` on the table at the pick-up pose, fingers open.

    Raises:
        KeyError: Unknown preset (the message lists the known ones).
    """
    params = SimParams(physics_dt=settings.physics_dt, seed=settings.seed,
                       velocity_sensor=VelocitySensorParams(model=settings.velocity_model),
                       reset_grasp_force=settings.reset_grasp_force)
    if settings.sensors is not None:
        s, ft = settings.sensors, params.ft
        params = replace(params, ft=replace(
            ft, noise_std=ft.noise_std * s.noise_scale,
            torque_noise_std=ft.torque_noise_std * s.noise_scale,
            offset_1=s.offset_1, offset_2=s.offset_2))
    cell = SimCell(params, presets(settings), preset)
    h = Harness(cell, chunk=settings.chunk)
    h.home()
    h.bias()
    return h


def true_properties(cell: SimCell, params: ContactEstimatorParams = ContactEstimatorParams()
                    ) -> ContactProperties:
    """The cell's per-finger contact parameters as a ``GROUND_TRUTH`` property set.

    Flags come from the estimator's plausibility limits (`preset_finger`), so a truth outside
    them is marked invalid exactly like an estimate would be.
    """
    fingers = []
    for c in cell.true_contact():
        fingers.append(preset_finger({'mu_c': c.mu_c, 'mu_s': c.mu_s, 'mu_v': c.mu_v,
                                      'r': c.r}, params))
    return ContactProperties(fingers[0], fingers[1], ContactSource.GROUND_TRUTH,
                             preset_name=cell.preset.name)


def controller_params(settings: EvalSettings, cell: SimCell) -> SlipControllerParams:
    """The controller parameters with the cell's frame constants (one cell.yaml in the graph)."""
    return replace(settings.controller, frames=cell.params.frames)


def controlled_scene(preset: str, settings: EvalSettings,
                     properties: ContactProperties | None, on_table: bool = False
                     ) -> tuple[Harness, ControllerAgent, TruthProbe]:
    """A cell with a controller agent and a truth probe; object held in the air under HOLD
    for ``settings.settle`` (or, with ``on_table``, standing on the table, controller OFF).

    ``properties`` ``None``: the simulator's true properties (`true_properties`).
    """
    h = make_harness(preset, settings)
    props = properties if properties is not None else true_properties(h.cell, settings.estimator)
    ctl = ControllerAgent(controller_params(settings, h.cell), props, settings.watchdog_period,
                          settings.control_law)
    probe = TruthProbe()
    h.add_agent(ctl)
    h.add_agent(probe)
    if not on_table:
        h.reset(object_on_table=False)
        h.run_for(0.2)
        ctl.require_mode(h, ModeRequest(int(SlipMode.HOLD)))
        h.run_for(settings.settle)
    return h, ctl, probe
