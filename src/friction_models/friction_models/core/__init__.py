# SPDX-License-Identifier: Apache-2.0
"""ROS-free core of friction_models: no rclpy or message imports allowed here (tested).

Modules: :mod:`.params` (frozen parameter sets), :mod:`.one_d` (1-D laws),
:mod:`.surfaces` (grids and pressure maps), :mod:`.planar` (twists, wrenches, transport),
:mod:`.distributed` (distributed planar LuGre), :mod:`.limit_surface` (pre-computed limit
surface and its cache), :mod:`.reduced` (reduced planar LuGre, single and batched),
:mod:`.integrators` (exponential and explicit-Euler bristle updates), :mod:`.scenarios`
(the paper's reference scenarios).

The simulation's hot modules may be mypyc-compiled; :mod:`.native` picks the compiled or the
pure-Python implementation before anything imports them (see :data:`NATIVE_STATUS`).
"""
from __future__ import annotations

from pathlib import Path as _Path

from .native import NativeStatus, select as _select_native

#: Compiled or pure-Python simulation core, and why (decided once, at import).
NATIVE_STATUS: NativeStatus = _select_native(__name__, _Path(__file__).resolve().parent)

from .distributed import DistributedPlanarLuGre, steady_state_wrenches
from .integrators import UnstableStepError, phi
from .limit_surface import (LimitSurface, LimitSurfaceCache, cache_key, characteristic_radius,
                            corner_wrenches)
from .one_d import (AmendedLuGre, Coulomb, Dahl, ElastoPlastic, LuGre, Stribeck, ep_weight,
                    lugre_steady_state, stribeck_curve)
from .params import (PARAMETER_SETS, ClassicLuGreParams, DahlParams, LuGreParams,
                     StribeckParams)
from .planar import (BatchWrench, Twist, Wrench, centre_of_rotation, transport_twist,
                     transport_wrench)
from .reduced import ReducedPlanarLuGre, ReducedPlanarLuGreBatch
from .surfaces import (STANDARD_SURFACES, ContactSurface, circle, line, line_grad, line_grad_x,
                       non_convex_1, non_convex_2, soft_finger, square, standard_surface)

__all__ = [
                            'NATIVE_STATUS',
                            'PARAMETER_SETS',
                            'STANDARD_SURFACES',
                            'AmendedLuGre',
                            'BatchWrench',
                            'ClassicLuGreParams',
                            'ContactSurface',
                            'Coulomb',
                            'Dahl',
                            'DahlParams',
                            'DistributedPlanarLuGre',
                            'ElastoPlastic',
                            'LimitSurface',
                            'LimitSurfaceCache',
                            'LuGre',
                            'LuGreParams',
                            'NativeStatus',
                            'ReducedPlanarLuGre',
                            'ReducedPlanarLuGreBatch',
                            'Stribeck',
                            'StribeckParams',
                            'Twist',
                            'UnstableStepError',
                            'Wrench',
                            'cache_key',
                            'centre_of_rotation',
                            'characteristic_radius',
                            'circle',
                            'corner_wrenches',
                            'ep_weight',
                            'line',
                            'line_grad',
                            'line_grad_x',
                            'lugre_steady_state',
                            'non_convex_1',
                            'non_convex_2',
                            'phi',
                            'soft_finger',
                            'square',
                            'standard_surface',
                            'steady_state_wrenches',
                            'stribeck_curve',
                            'transport_twist',
                            'transport_wrench',
]
