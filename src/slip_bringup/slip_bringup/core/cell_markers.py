# SPDX-License-Identifier: Apache-2.0
"""What the cell is doing, as display markers (ROS-free; published by ``cell_markers``).

From the latest contact wrenches (``finger_k/ft/wrench``, frame ``ft_sensor_k``), slip
velocities (``finger_k/slip/twist``, frame ``vel_sensor_k``) and the slip controller's
tracking (``slip_control/tracking``) it draws, with the frame prefix applied:

* ``pads`` — each pad as a box on its ``vel_sensor_k`` frame: grey free, green in contact
  (|Fz| ≥ ``contact_force``), red while slipping (speed ≥ ``sliding_speed``);
* ``wrench`` — each finger's contact force as an arrow from the pad centre, ``force_scale``
  m per N, in ``ft_sensor_k`` (the force the object exerts on the pad);
* ``slip`` — each finger's slip velocity as an arrow in ``vel_sensor_k``, ``slip_scale`` m per
  m/s;
* ``slip_target`` — in ``gripper_middle``: LINEAR as two arrows from the grasp centre along
  the slip direction (target ``ref_pos`` in blue, achieved ``meas_pos`` in orange), ROTATIONAL
  as two arcs of radius ``target_radius`` (target and achieved angle), and a text line.

Moving markers carry a ``lifetime`` of ``stale_after`` so they vanish when their topic stops;
stamps are the data's acquisition stamps. The simulator draws the object itself
(``sim/markers``, `friction_models.core.scene_frames`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from slip_cell_common.core import names
from slip_cell_common.core.frames import FrameParams, planar_to_middle
from slip_cell_common.core.markers import (
    BLUE,
    GREEN,
    GREY,
    ORANGE,
    RED,
    WHITE,
    MarkerSpec,
    arc,
    arrow,
    box,
    delete,
    line_strip,
    text,
)
from slip_cell_common.core.param_schema import ranged_field as _f
from slip_control.core.controllers import SlipMode

FINGERS = (1, 2)


@dataclass(frozen=True)
class CellMarkersParams:
    """Parameters of the ``cell_markers`` node (SI)."""

    rate: float = _f(20.0, 'Hz', 1.0, 100.0, 'marker publication rate')
    force_scale: float = _f(0.004, 'm/N', 1.0e-5, 1.0, 'wrench arrow length per newton')
    slip_scale: float = _f(1.0, 's', 1.0e-3, 100.0, 'slip arrow length per m/s of slip')
    pad_size: float = _f(0.02, 'm', 0.001, 0.2, 'side of the square pad drawn')
    contact_force: float = _f(0.5, 'N', 0.0, 100.0, 'pad normal force counted as contact')
    sliding_speed: float = _f(0.002, 'm/s', 0.0, 1.0, 'pad slip speed counted as slipping')
    target_radius: float = _f(0.03, 'm', 0.001, 1.0, 'radius of the rotational target arcs')
    stale_after: float = _f(0.5, 's', 0.05, 10.0,
                            'data older than this is not drawn (marker lifetime)')


@dataclass(frozen=True)
class Sample:
    """One stamped vector: a wrench ``(Fx, Fy, Fz, Tx, Ty, Tz)`` or twist ``(vx, vy, ω)``."""

    stamp: float
    values: tuple[float, ...]


@dataclass(frozen=True)
class Tracking:
    """One ``slip_control/tracking`` sample (m or rad by ``mode``)."""

    stamp: float
    mode: int
    ref_pos: float
    meas_pos: float
    done: bool = False


class SlipDirection:
    """Unit direction of the slip in ``gripper_middle`` xy, from both fingers' twists.

    Follows the mean finger velocity (rotated into ``gripper_middle``) whenever it is faster
    than ``min_speed``, smoothed over ``alpha``; keeps the last direction while the object
    sticks. None until a first motion.
    """

    def __init__(self, frames: FrameParams, min_speed: float, alpha: float = 0.2) -> None:
        self._frames = frames
        self._min_speed = min_speed
        self._alpha = alpha
        self._latest: dict[int, tuple[float, float]] = {}
        self.direction: tuple[float, float] | None = None

    def update(self, finger: int, vx: float, vy: float, wz: float) -> None:
        """Take one finger's twist ``(vx, vy)`` [m/s] in ``vel_sensor_k``."""
        x, y, _ = planar_to_middle(self._frames, finger, vx, vy, wz)
        self._latest[finger] = (x, y)
        mx = sum(v[0] for v in self._latest.values()) / len(self._latest)
        my = sum(v[1] for v in self._latest.values()) / len(self._latest)
        speed = math.hypot(mx, my)
        if not speed >= self._min_speed:
            return
        ux, uy = mx / speed, my / speed
        if self.direction is not None:
            a = self._alpha
            ux, uy = (1 - a) * self.direction[0] + a * ux, (1 - a) * self.direction[1] + a * uy
            norm = math.hypot(ux, uy)
            if norm <= 0.0:
                return
            ux, uy = ux / norm, uy / norm
        self.direction = (ux, uy)

    def reset(self) -> None:
        """Forget the direction (a new slip goal)."""
        self._latest.clear()
        self.direction = None


def _fresh(sample: Sample | Tracking | None, now: float, stale_after: float) -> bool:
    return sample is not None and now - sample.stamp <= stale_after


def pad_markers(frames: FrameParams, p: CellMarkersParams,
                wrench: tuple[Sample | None, ...], twist: tuple[Sample | None, ...],
                now: float) -> list[MarkerSpec]:
    """Both pads, coloured by contact and slip (boxes below the pad surface)."""
    out = []
    for k in FINGERS:
        w, v = wrench[k - 1], twist[k - 1]
        contact = _fresh(w, now, p.stale_after) and w is not None and \
            abs(w.values[2]) >= p.contact_force
        sliding = _fresh(v, now, p.stale_after) and v is not None and \
            math.hypot(v.values[0], v.values[1]) >= p.sliding_speed
        color = RED if (contact and sliding) else GREEN if contact else GREY
        thickness = max(frames.pad_offset, 0.001)
        out.append(box('pads', k, frames.frame_id(names.vel_sensor_frame(k)),
                       (p.pad_size, p.pad_size, thickness), color,
                       position=(0.0, 0.0, -0.5 * thickness)))
    return out


def wrench_markers(frames: FrameParams, p: CellMarkersParams,
                   wrench: tuple[Sample | None, ...], now: float) -> list[MarkerSpec]:
    """Contact force arrows from each pad centre (in ``ft_sensor_k``)."""
    out = []
    for k in FINGERS:
        frame = frames.frame_id(names.ft_sensor_frame(k))
        w = wrench[k - 1]
        if w is None or not _fresh(w, now, p.stale_after):
            out.append(delete('wrench', k, frame))
            continue
        start = (0.0, 0.0, frames.pad_offset)
        end = (start[0] + p.force_scale * w.values[0], start[1] + p.force_scale * w.values[1],
               start[2] + p.force_scale * w.values[2])
        out.append(arrow('wrench', k, frame, start, end, BLUE, shaft=0.002, stamp=w.stamp,
                         lifetime=p.stale_after))
    return out


def slip_markers(frames: FrameParams, p: CellMarkersParams, twist: tuple[Sample | None, ...],
                 now: float) -> list[MarkerSpec]:
    """Slip velocity arrows on each pad (in ``vel_sensor_k``)."""
    out = []
    for k in FINGERS:
        frame = frames.frame_id(names.vel_sensor_frame(k))
        v = twist[k - 1]
        if v is None or not _fresh(v, now, p.stale_after):
            out.append(delete('slip', k, frame))
            continue
        end = (p.slip_scale * v.values[0], p.slip_scale * v.values[1], 0.0)
        out.append(arrow('slip', k, frame, (0.0, 0.0, 0.0), end, RED, shaft=0.0015,
                         stamp=v.stamp, lifetime=p.stale_after))
    return out


def target_markers(frames: FrameParams, p: CellMarkersParams, tracking: Tracking | None,
                   direction: tuple[float, float] | None, now: float) -> list[MarkerSpec]:
    """The slip target vs what was achieved (in ``gripper_middle``); deleted when idle."""
    frame = frames.frame_id(names.GRIPPER_MIDDLE)
    ids = range(3)
    if tracking is None or not _fresh(tracking, now, p.stale_after) or \
            tracking.mode not in (SlipMode.LINEAR, SlipMode.ROTATIONAL):
        return [delete('slip_target', i, frame) for i in ids]
    t, life = tracking.stamp, p.stale_after
    label_at = (0.0, 1.5 * p.target_radius, 0.0)
    if tracking.mode == SlipMode.LINEAR:
        ux, uy = direction if direction is not None else (0.0, -1.0)
        origin = (0.0, 0.0, 0.0)
        ref = (ux * tracking.ref_pos, uy * tracking.ref_pos, 0.0)
        meas = (ux * tracking.meas_pos, uy * tracking.meas_pos, 0.0)
        label = (f'LINEAR  target {tracking.ref_pos * 1e3:.1f} mm  '
                 f'achieved {tracking.meas_pos * 1e3:.1f} mm' + ('  done' if tracking.done
                                                                 else ''))
        return [arrow('slip_target', 0, frame, origin, ref, BLUE, shaft=0.003, stamp=t,
                      lifetime=life),
                arrow('slip_target', 1, frame, origin, meas, ORANGE, shaft=0.002, stamp=t,
                      lifetime=life),
                text('slip_target', 2, frame, label_at, label, color=WHITE, stamp=t,
                     lifetime=life)]
    start = -0.5 * math.pi   # arcs start below the grasp centre
    r = p.target_radius
    label = (f'ROTATIONAL  target {math.degrees(tracking.ref_pos):.1f}°  '
             f'achieved {math.degrees(tracking.meas_pos):.1f}°' + ('  done' if tracking.done
                                                                  else ''))
    return [line_strip('slip_target', 0, frame, arc((0.0, 0.0, 0.0), r, start,
                                                    start + tracking.ref_pos), BLUE,
                       width=0.003, stamp=t, lifetime=life),
            line_strip('slip_target', 1, frame, arc((0.0, 0.0, 0.0), 0.8 * r, start,
                                                    start + tracking.meas_pos), ORANGE,
                       width=0.002, stamp=t, lifetime=life),
            text('slip_target', 2, frame, label_at, label, color=WHITE, stamp=t,
                 lifetime=life)]


def cell_markers(frames: FrameParams, p: CellMarkersParams,
                 wrench: tuple[Sample | None, Sample | None],
                 twist: tuple[Sample | None, Sample | None], tracking: Tracking | None,
                 direction: tuple[float, float] | None, now: float) -> list[MarkerSpec]:
    """Every marker of the cell picture at node time ``now`` [s] (module docstring)."""
    return [*pad_markers(frames, p, wrench, twist, now),
            *wrench_markers(frames, p, wrench, now),
            *slip_markers(frames, p, twist, now),
            *target_markers(frames, p, tracking, direction, now)]
