# SPDX-License-Identifier: Apache-2.0
"""``slip_evaluate``: evaluate the contact estimator and the slip controllers in-process.

Runs `slip_bringup.core.sim_evaluation.evaluate_all` on the simulated cell (no ROS, no DDS;
sim time, deterministic for a seed) and prints the table of issue 7 item 4: per reference
object the μ_c and r estimation errors per finger, LINEAR 2 cm / 2 s and 4 cm / 5 s and
ROTATIONAL 20° / 2 s and 45° / 5 s final errors, peak slip under HOLD disturbances, and the
hinge through 60°, all measured from the simulator truth. Then, unless ``--quick`` or
``--no-online``, the ONLINE estimator (§3.6) is judged by `online_refinement`: started from the
true μ_c and r times 0.8 and 1.2, refined during a LINEAR and a ROTATIONAL slip (≈ 3 s wall per
preset and start).

Examples::

    slip_evaluate                           # the four reference objects (~20-60 s)
    slip_evaluate --preset cardboard --quick
    slip_evaluate --preset wood,case --truth-properties
    slip_evaluate --no-online               # skip the online-refinement table
"""
from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence

from slip_bringup.core.sim_evaluation import (ONLINE_START_SCALES, REFERENCE_PRESETS,
                                              EvalSettings, EvaluationError, evaluate_all,
                                              format_online_table, format_table,
                                              online_refinement)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog='slip_evaluate',
        description='In-process evaluation of the contact estimator and the slip controllers '
                    'on the simulated cell (sim time, no ROS).')
    p.add_argument('--preset', action='append', default=None, metavar='NAME[,NAME...]',
                   help='object preset(s); repeatable or comma-separated '
                        f'(default: {", ".join(REFERENCE_PRESETS)})')
    p.add_argument('--quick', action='store_true',
                   help='only the 2 s trajectories, no pick-up, no online refinement '
                        '(about half the time)')
    p.add_argument('--no-online', action='store_true',
                   help='skip the online-refinement table (ONLINE estimator from a start '
                        'off by 0.8x/1.2x)')
    p.add_argument('--truth-properties', action='store_true',
                   help='controllers use the simulator\'s true contact properties instead of '
                        'the estimate of the same run')
    p.add_argument('--physics-dt', type=float, default=EvalSettings.physics_dt,
                   help='physics step [s] (default %(default)s; the node uses 1e-4)')
    p.add_argument('--seed', type=int, default=0, help='sensor-noise seed (default 0)')
    p.add_argument('--presets-file', default='',
                   help='extra presets YAML (friction_models format) besides the reference '
                        'objects')
    p.add_argument('--velocity-model', choices=('chips', 'ideal'), default='chips',
                   help='velocity-sensor model (default chips)')
    return p


def _presets(values: Sequence[str] | None) -> list[str]:
    if not values:
        return list(REFERENCE_PRESETS)
    out: list[str] = []
    for v in values:
        out.extend(name.strip() for name in v.split(',') if name.strip())
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Print the evaluation table; returns the process exit code."""
    parser = _parser()
    ns = parser.parse_args(argv)
    presets = _presets(ns.preset)
    if not presets:
        parser.error('--preset needs at least one name')
    if not (ns.physics_dt > 0.0):
        parser.error(f'--physics-dt must be > 0, got {ns.physics_dt}')
    try:
        settings = EvalSettings(physics_dt=ns.physics_dt, seed=ns.seed,
                                velocity_model=ns.velocity_model,
                                presets_file=ns.presets_file)
        t0 = time.monotonic()

        def progress(text: str) -> None:
            print(f'[{time.monotonic() - t0:6.1f} s] {text}', file=sys.stderr, flush=True)

        rows = evaluate_all(presets, settings, quick=ns.quick,
                            use_truth=ns.truth_properties, progress=progress)
        online = []
        if not (ns.quick or ns.no_online):
            for name in presets:
                for scale in ONLINE_START_SCALES:
                    progress(f'{name}: online refinement from {scale:g}x')
                    online.append(online_refinement(name, scale, settings))
    except (KeyError, ValueError, EvaluationError) as exc:
        message = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
        print(f'slip_evaluate: error: {message}', file=sys.stderr)
        return 1
    print(format_table(rows))
    if online:
        print()
        print(format_online_table(online))
    print(f'\n(physics_dt {settings.physics_dt:g} s, seed {settings.seed}, velocity sensor '
          f'{settings.velocity_model}; {time.monotonic() - t0:.1f} s wall)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
