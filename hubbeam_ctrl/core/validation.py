"""Checks of scalar settings that raise one-line :class:`ParameterError` messages.

Each names the setting, its allowed range and unit, and returns the value as a float.
"""

from __future__ import annotations

import math

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError

__all__ = ["check_positive", "check_nonnegative", "check_finite"]

_NUMBER = (int, float, np.floating, np.integer)


def _is_number(value) -> bool:
    return not isinstance(value, bool) and isinstance(value, _NUMBER) and math.isfinite(value)


def check_positive(name: str, value, unit: str) -> float:
    """Return ``float(value)``; raise unless it is a finite number > 0 [``unit``]."""
    if not (_is_number(value) and value > 0):
        raise ParameterError(f"{name} must be a finite number > 0 [{unit}], got {value!r}")
    return float(value)


def check_nonnegative(name: str, value, unit: str) -> float:
    """Return ``float(value)``; raise unless it is a finite number >= 0 [``unit``]."""
    if not (_is_number(value) and value >= 0):
        raise ParameterError(f"{name} must be a finite number >= 0 [{unit}], got {value!r}")
    return float(value)


def check_finite(name: str, value, unit: str) -> float:
    """Return ``float(value)``; raise unless it is a finite number [``unit``]."""
    if not _is_number(value):
        raise ParameterError(f"{name} must be a finite number [{unit}], got {value!r}")
    return float(value)
