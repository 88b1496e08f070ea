# SPDX-License-Identifier: Apache-2.0
"""friction_models: 1-D and planar LuGre friction models, pure numpy, no ROS imports.

Distributed and reduced (pre-computed limit surface) planar models with the Elasto-Plastic
extension. The public API is defined in :mod:`friction_models.core` and re-exported here; see
the package README.
"""
from __future__ import annotations

from . import core
from .core import *  # noqa: F403  (the curated core API, listed in core.__all__)

__all__ = list(core.__all__)
