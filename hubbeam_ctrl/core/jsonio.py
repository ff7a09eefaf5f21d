"""JSON text of the toolbox's values: NumPy scalars and arrays, dataclasses and paths
converted; strict JSON with non-finite numbers as ``null`` and flagged.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np

__all__ = ["json_ready", "strict_json", "json_text"]


def _json_default(obj):
    """``json.dumps`` fallback: NumPy scalars and arrays, dataclasses, paths, else ``str``."""
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return dataclasses.asdict(obj)
    return str(obj)


def json_text(value) -> str:
    """``value`` as JSON text (NumPy values, dataclasses and paths converted, see :func:`json_ready`).

    Parameters
    ----------
    value : object
        Nested dicts, lists, numbers and strings; anything else becomes its ``str``.
    """
    return json.dumps(value, default=_json_default)


def json_ready(value):
    """``value`` as it reads back from JSON: tuples become lists, NumPy scalars plain numbers.

    Storing metadata in this form makes a save/load round trip return equal values.

    Parameters
    ----------
    value : object
        Nested dicts, lists, numbers, strings; NumPy values, dataclasses and paths are
        converted, anything else becomes its ``str``.

    Returns
    -------
    object
    """
    return json.loads(json_text(value))


def _finite_only(value, flag: str):
    """``value`` with non-finite floats as ``None``; each dict that had some lists their keys
    under ``flag``."""
    if isinstance(value, (float, np.floating)):
        return float(value) if np.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.ndarray):
        return _finite_only(value.tolist(), flag)
    if isinstance(value, (list, tuple)):
        return [_finite_only(v, flag) for v in value]
    if isinstance(value, dict):
        out, bad = {}, []
        for k, v in value.items():
            out[k] = _finite_only(v, flag)
            if out[k] is None and isinstance(v, (float, np.floating)):
                bad.append(k)
        if bad:
            out[flag] = bad
        return out
    return value


def strict_json(value, flag: str = "non_finite", **kwargs) -> str:
    """Strict JSON text (``allow_nan=False``): NaN and infinities become ``null``.

    Every object that had such values gets ``flag`` listing their keys, so ``null`` is
    never mistaken for a missing value.

    Parameters
    ----------
    value : object
        Nested dicts, lists, numbers, strings (NumPy values accepted).
    flag : str
        Key of the list of replaced entries.
    **kwargs
        Passed to :func:`json.dumps` (``indent``...).

    Returns
    -------
    str

    Examples
    --------
    >>> strict_json({"peak": float("nan"), "n": 3})
    '{"peak": null, "n": 3, "non_finite": ["peak"]}'
    """
    return json.dumps(_finite_only(value, flag), allow_nan=False, default=_json_default, **kwargs)
