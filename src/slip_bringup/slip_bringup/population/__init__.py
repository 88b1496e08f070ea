# SPDX-License-Identifier: Apache-2.0
"""Population evaluation: many random objects through the deployed estimator and controllers.

The objects are drawn by `friction_models.core.population.draw_object` (deterministic per
``(seed, index)``). Modules, one concern each:

* `runner` — one object through exploration + estimation, HOLD, LINEAR, ROTATIONAL and HINGE
  (per control-law family), judged by the simulator truth (`ObjectResult`);
* `feasibility` — which scenarios are physically possible for an object (stated criteria);
* `run` — a whole population: its tasks, on a backend, with its cost;
* `backends` — the same items on local worker processes or a Dask distributed cluster;
* `results` — the picklable result records;
* `statistics` — success rates with confidence intervals, distributions, failure splits;
* `report` — summaries, table, JSON, CSV and PNG plots;
* `progress` — the progress bar of the command line.

Command line: ``slip_evaluate --population N --seed S`` (`slip_bringup.evaluate_cli`).
"""
