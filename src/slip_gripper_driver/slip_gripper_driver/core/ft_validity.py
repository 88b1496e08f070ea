# SPDX-License-Identifier: Apache-2.0
"""Which RDT records are measurements: status word and measuring range (ROS-free, §4.5).

A record whose status word carries an error (e.g. ``0x80020000``, saturation or A/D error)
or whose value lies beyond the transducer's calibrated range (``cfgmr``) is not a valid
measurement: a saturated transducer under-reports the force. The drivers count such records
and keep them away from the grasp-force loop and from ``finger_k/ft/wrench``.
"""
from __future__ import annotations

from enum import IntEnum
from collections.abc import Sequence

from slip_gripper_driver.core.netft_status import is_error_status

#: Six range limits (|Fx|, |Fy|, |Fz| [N], |Tx|, |Ty|, |Tz| [N·m]); 0 = axis unchecked.
RangeLimits = tuple[float, float, float, float, float, float]
UNCHECKED: RangeLimits = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


class RecordFlaw(IntEnum):
    """Why a record is not a measurement (NONE: it is one)."""

    NONE = 0
    STATUS_ERROR = 1
    OUT_OF_RANGE = 2


def merge_limits(parameter: Sequence[float], box: Sequence[float] | None) -> RangeLimits:
    """Range limits [N, N·m]: a positive parameter entry wins, else the box's ``cfgmr``
    entry, else 0 (unchecked).

    Raises:
        ValueError: Not six values.
    """
    if len(parameter) != 6 or (box is not None and len(box) != 6):
        raise ValueError('range limits need six values (Fx, Fy, Fz, Tx, Ty, Tz)')
    out = [float(p) if p > 0.0 else (float(box[i]) if box is not None and box[i] > 0.0
                                     else 0.0) for i, p in enumerate(parameter)]
    return (out[0], out[1], out[2], out[3], out[4], out[5])


def record_flaw(status: int, wrench: Sequence[float], limits: Sequence[float]) -> RecordFlaw:
    """Classify one record by its status word and its wrench [N, N·m] against ``limits``."""
    if is_error_status(status):
        return RecordFlaw.STATUS_ERROR
    for value, limit in zip(wrench, limits):
        if limit > 0.0 and abs(value) > limit:
            return RecordFlaw.OUT_OF_RANGE
    return RecordFlaw.NONE
