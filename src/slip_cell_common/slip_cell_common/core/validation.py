# SPDX-License-Identifier: Apache-2.0
"""Shared ``validate()`` helper for the parameter dataclasses of this package's cores."""
from __future__ import annotations

from collections.abc import Iterable

from slip_cell_common.core.param_schema import ParameterError, check_value, flatten, specs


def validate_fields(instance: object, extra: Iterable[str] = ()) -> None:
    """Check every (nested) field against its metadata, plus cross-field problems.

    Args:
        instance: A parameter dataclass instance.
        extra: Problems found by the caller (combinations of fields).

    Raises:
        ParameterError: Listing every problem, so a user sees all of them at once.
    """
    values = flatten(instance)
    problems = [p for s in specs(type(instance)) for p in check_value(s, values[s.name])]
    problems.extend(extra)
    if problems:
        raise ParameterError('; '.join(problems))
