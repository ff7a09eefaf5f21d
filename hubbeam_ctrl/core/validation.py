"""Checks of scalar settings that raise one-line :class:`ParameterError` messages.

Each names the setting, its allowed range and unit, and returns the value as a float.
"""

from __future__ import annotations

import math

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError

__all__ = ["check_positive", "check_nonnegative", "check_finite", "check_in_range", "check_integer",
           "check_array"]

_NUMBER = (int, float, np.floating, np.integer)


def _shown(value) -> str:
    """``value`` as shown in a message: floats with ``%g``, anything else by ``repr``, <= 40 chars."""
    text = f"{value:g}" if isinstance(value, float) else repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _is_number(value) -> bool:
    if isinstance(value, bool) or not isinstance(value, _NUMBER):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:          # an int beyond the float range, e.g. 10**400
        return False


#: The bounds of :func:`check_positive` and :func:`check_nonnegative`, as their messages say them.
_BOUNDS = {"": lambda v: True, "> 0": lambda v: v > 0, ">= 0": lambda v: v >= 0}


def _check_number(name: str, value, unit: str, bound: str = "") -> float:
    if not (_is_number(value) and _BOUNDS[bound](value)):
        raise ParameterError(f"{name} must be a finite number{' ' + bound if bound else ''} [{unit}], "
                             f"got {_shown(value)}")
    return float(value)


def check_finite(name: str, value, unit: str) -> float:
    """Return ``float(value)``; raise unless it is a finite number [``unit``].

    Parameters
    ----------
    name : str
        The argument's name as the caller spelled it (starts the message).
    value : float
        The value.
    unit : str
        Its unit (for the message).
    """
    return _check_number(name, value, unit)


def check_positive(name: str, value, unit: str) -> float:
    """Return ``float(value)``; raise unless it is a finite number > 0 [``unit``].

    Parameters
    ----------
    name : str
    value : float
    unit : str
        As :func:`check_finite`.
    """
    return _check_number(name, value, unit, "> 0")


def check_nonnegative(name: str, value, unit: str) -> float:
    """Return ``float(value)``; raise unless it is a finite number >= 0 [``unit``].

    Parameters
    ----------
    name, value, unit
        As :func:`check_finite`.
    """
    return _check_number(name, value, unit, ">= 0")


def check_in_range(name: str, value, unit: str, lo: float, hi: float, why: str = "") -> float:
    """Return ``float(value)``; raise unless it is a real number with ``lo <= value <= hi``.

    Parameters
    ----------
    name : str
        The argument's name as the caller spelled it (starts the message).
    value : object
        Anything: NaN, infinities, booleans and text are refused.
    unit : str
        Its unit (for the message).
    lo, hi : float
        Inclusive bounds.
    why : str, optional
        What the bounds stand for, added to the message in parentheses.

    Returns
    -------
    float

    Examples
    --------
    >>> check_in_range("t_end", 0.004, "s", 0.01, 1e9, "at least two samples")
    Traceback (most recent call last):
    ...
    hubbeam_ctrl.core.errors.ParameterError: t_end must be in [0.01, 1e+09] [s] (at least two samples), got 0.004
    """
    note = f" ({why})" if why else ""
    if not _is_number(value) or not lo <= value <= hi:
        raise ParameterError(f"{name} must be in [{lo:g}, {hi:g}] [{unit}]{note}, got {_shown(value)}")
    return float(value)


def check_integer(name: str, value, lo: int, hi: int) -> int:
    """Return ``int(value)``; raise unless it is an integer (or an integral float) in ``lo..hi``.

    NaN, infinities, booleans, strings and fractions are one-line errors, never a
    ``ValueError``/``OverflowError`` from the conversion.

    Parameters
    ----------
    name : str
        The argument's name as the caller spelled it (starts the message).
    value : object
    lo, hi : int
        Inclusive bounds.

    Returns
    -------
    int

    Examples
    --------
    >>> check_integer("n_modes", float("nan"), 1, 4)
    Traceback (most recent call last):
    ...
    hubbeam_ctrl.core.errors.ParameterError: n_modes must be an integer in 1..4, got nan
    """
    ok = not isinstance(value, bool) and isinstance(value, (int, np.integer, float, np.floating)) \
        and (isinstance(value, (int, np.integer)) or (math.isfinite(value) and float(value).is_integer()))
    if not ok or not lo <= int(value) <= hi:
        raise ParameterError(f"{name} must be an integer in {lo}..{hi}, got {_shown(value)}")
    return int(value)


def check_array(name: str, values, unit: str, nonempty: bool = True) -> np.ndarray:
    """Return ``values`` as a 1-D float array; raise unless every entry is a finite number
    (and, with ``nonempty``, there is at least one).

    Parameters
    ----------
    name, unit : str
        As :func:`check_finite`.
    values : array_like
        A sequence of numbers (a scalar is one).
    nonempty : bool
        Refuse an empty sequence.

    Returns
    -------
    ndarray
    """
    try:
        arr = np.atleast_1d(np.asarray(values, dtype=float))
    except (TypeError, ValueError, OverflowError):
        raise ParameterError(f"{name} must be a sequence of finite numbers [{unit}], got {_shown(values)}") from None
    if arr.ndim != 1:
        raise ParameterError(f"{name} must be a 1-D sequence of numbers [{unit}], got shape {arr.shape}")
    if nonempty and arr.size == 0:
        raise ParameterError(f"{name} must hold at least one value [{unit}], got none")
    if not np.all(np.isfinite(arr)):
        raise ParameterError(f"{name} must hold finite numbers [{unit}], got {_shown(arr[~np.isfinite(arr)][0])}")
    return arr
