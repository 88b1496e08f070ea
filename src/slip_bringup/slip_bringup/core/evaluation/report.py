# SPDX-License-Identifier: Apache-2.0
"""Text tables of the evaluation: estimate − truth, target − achieved (truth), details."""
from __future__ import annotations

import math
from collections.abc import Sequence

from slip_bringup.core.evaluation.online import OnlineOutcome
from slip_bringup.core.evaluation.table import LINEAR_CASES, ROTATIONAL_CASES, PresetEvaluation


def format_online_table(outcomes: Sequence[OnlineOutcome]) -> str:
    """Table of `online_refinement` outcomes: largest relative error over the two fingers,
    start → online, for ``μ_c`` (after the LINEAR slide) and ``r`` (after the ROTATIONAL slip).
    """
    lines = ['Online refinement (ONLINE during LINEAR 2 cm/2 s, then ROTATIONAL 20 deg/2 s; '
             'max relative error over the fingers)',
             f'{"preset":<10} {"start":>5}  {"mu_c err start->online":>22}  '
             f'{"r err start->online":>19}  {"published":>9}  {"drops":>5}']
    for o in outcomes:
        pub = '/'.join('yes' if b else 'no' for b in (o.published_linear,
                                                       o.published_rotational))
        lines.append(
            f'{o.preset:<10} {o.start_scale:>4.2f}x  '
            f'{100 * o.mu_c_error_start:>8.1f} % -> {100 * o.mu_c_error_online:>5.1f} %  '
            f'{100 * o.r_error_start:>5.1f} % -> {100 * o.r_error_online:>5.1f} %  {pub:>9}  '
            f'{int(o.dropped):>5}')
    return '\n'.join(lines)


def _fmt(value: float | None, scale: float = 1.0, digits: int = 2, width: int = 7) -> str:
    if value is None or not math.isfinite(value):
        return f'{"n/a":>{width}}'
    return f'{value * scale:{width}.{digits}f}'


def format_table(rows: Sequence[PresetEvaluation]) -> str:
    """The issue-7 table: estimate − truth, and target − achieved from the simulator truth.

    Columns of the slip table: LINEAR and ROTATIONAL final errors; HOLD: largest slip under
    the sustained pushes and under the taps (each from the pose at the push), largest
    rotation; HINGE: ``|relative rotation|`` over the 60° turn (ideal 60°) and the grasp-point
    translation over the turn; pick-up slip; number of scenarios in which the object fell.
    """
    lines: list[str] = []
    deg = 180.0 / math.pi
    lines.append('Contact estimation (estimate - truth)')
    lines.append(f'{"preset":<10} {"mu_c f1":>8} {"mu_c f2":>8} {"r f1 mm":>8} {"r f2 mm":>8}'
                 f'  {"valid":>5}  {"mu_c true":>11}  {"r true mm":>11}')
    for row in rows:
        f1, f2 = row.estimation.fingers
        lines.append(
            f'{row.preset:<10} {_fmt(f1.mu_c_error, 1, 4, 8)} {_fmt(f2.mu_c_error, 1, 4, 8)} '
            f'{_fmt(f1.r_error, 1e3, 2, 8)} {_fmt(f2.r_error, 1e3, 2, 8)}  '
            f'{str(row.estimation.valid):>5}  {f1.mu_c_true:5.3f}/{f2.mu_c_true:5.3f}  '
            f'{f1.r_true * 1e3:5.2f}/{f2.r_true * 1e3:5.2f}')
    lines.append('')
    lines.append('Slip control (simulator truth; final error = target - achieved)')
    lines.append(f'{"preset":<10} {"props":<12} {"lin 2cm/2s":>10} {"lin 4cm/5s":>10} '
                 f'{"rot 20/2s":>9} {"rot 45/5s":>9} {"hold push":>9} {"hold tap":>8} '
                 f'{"hold rot":>8} {"hinge rel":>9} {"hinge tr":>8} {"pick-up":>7} '
                 f'{"drops":>5}')
    lines.append(f'{"":<10} {"":<12} {"[mm]":>10} {"[mm]":>10} {"[deg]":>9} {"[deg]":>9} '
                 f'{"[mm]":>9} {"[mm]":>8} {"[deg]":>8} {"[deg]":>9} {"[mm]":>8} {"[mm]":>7} '
                 f'{"":>5}')
    for row in rows:
        lin = [row.linear.get(k) for k in LINEAR_CASES]
        rot = [row.rotational.get(k) for k in ROTATIONAL_CASES]
        hold, hng, pick = row.hold, row.hinge, row.pick_up
        outcomes: list[object] = [*lin, *rot, hold, hng, pick]
        drops = sum(1 for o in outcomes if o is not None and getattr(o, 'dropped', False))
        lines.append(
            f'{row.preset:<10} {row.properties_source:<12} '
            f'{_fmt(lin[0].final_error if lin[0] else None, 1e3, 2, 10)} '
            f'{_fmt(lin[1].final_error if lin[1] else None, 1e3, 2, 10)} '
            f'{_fmt(rot[0].final_error if rot[0] else None, deg, 2, 9)} '
            f'{_fmt(rot[1].final_error if rot[1] else None, deg, 2, 9)} '
            f'{_fmt(hold.sustained_slip if hold else None, 1e3, 3, 9)} '
            f'{_fmt(hold.tap_slip if hold else None, 1e3, 3, 8)} '
            f'{_fmt(hold.rotation_peak if hold else None, deg, 2, 8)} '
            f'{_fmt(abs(hng.relative_rotation) if hng else None, deg, 1, 9)} '
            f'{_fmt(hng.translation_turn if hng else None, 1e3, 2, 8)} '
            f'{_fmt(pick.slip_peak if pick else None, 1e3, 3, 7)} {drops:>5}')
    lines.append('')
    lines.append('Details: controller self-report (sensor-integrated final error) and extras')
    for row in rows:
        parts = []
        for (d, T), o in row.linear.items():
            r = o.result
            parts.append(f'linear {d * 100:.0f} cm / {T:.0f} s: controller error '
                         f'{_fmt(r.final_error if r else None, 1e3, 2, 0)} mm '
                         f'({r.message if r else "no result"}); tracking rms/max '
                         f'{o.tracking_rms * 1e3:.2f}/{o.tracking_max * 1e3:.2f} mm; sideways '
                         f'{o.off_axis * 1e3:.2f} mm; force {o.force_min:.2f}-{o.force_max:.2f} N'
                         f'{"; DROPPED" if o.dropped else ""}')
        for (a, T), o in row.rotational.items():
            r = o.result
            parts.append(f'rotational {math.degrees(a):.0f} deg / {T:.0f} s: controller error '
                         f'{_fmt(r.final_error if r else None, deg, 2, 0)} deg '
                         f'({r.message if r else "no result"}); tracking rms/max '
                         f'{o.tracking_rms * deg:.2f}/{o.tracking_max * deg:.2f} deg; grasp-point '
                         f'translation {o.off_axis * 1e3:.1f} mm; force '
                         f'{o.force_min:.2f}-{o.force_max:.2f} N'
                         f'{"; DROPPED" if o.dropped else ""}')
        if row.hold is not None:
            ho = row.hold
            per = ', '.join(f'{d * 1e3:.2f}' for d in ho.push_slip)
            parts.append(f'hold: slip per push [mm] {per}; peak {ho.slip_peak * 1e3:.2f} mm, '
                         f'rotation {math.degrees(ho.rotation_peak):.2f} deg; force '
                         f'{ho.force_min:.2f}-{ho.force_max:.2f} N'
                         f'{"; DROPPED" if ho.dropped else ""}')
        if row.hinge is not None:
            hg = row.hinge
            parts.append(f'hinge: swing at HINGE on {math.degrees(hg.swing):.1f} deg; relative '
                         f'rotation over the turn {math.degrees(hg.relative_rotation):.1f} deg; '
                         f'object turned {math.degrees(hg.object_turn):.1f} deg in the world; '
                         f'translation peak {hg.translation_peak * 1e3:.1f} mm; force '
                         f'{hg.force_min:.2f}-{hg.force_max:.2f} N'
                         f'{"; DROPPED" if hg.dropped else ""}')
        if row.pick_up is not None:
            pu = row.pick_up
            parts.append(f'pick-up: lift {pu.lift * 1e3:.1f} mm, slip {pu.slip_peak * 1e3:.3f} mm,'
                         f' force {pu.force_min:.2f}-{pu.force_max:.2f} N'
                         f'{"; DROPPED" if pu.dropped else ""}')
        lines.append(f'{row.preset}:')
        lines.extend(f'  {p}' for p in parts)
        lines.extend(f'  NOTE {n}' for n in row.notes)
    return '\n'.join(lines)
