"""The fitted rig fields: names as a user spells them (``E``, ``damping``, ``friction.viscous``)
resolved to a rig table's key with its unit and range (:class:`FitField`, :func:`resolve_fields`).
Used by :mod:`hubbeam_ctrl.calibrate.fit` and :mod:`hubbeam_ctrl.calibrate.table`.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, fields

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.rig import _ATTR, RIG_TABLES, Rig

__all__ = ["FitField", "resolve_fields", "FIT_ALIASES"]

#: Short names of ``--fit``: name -> (table, key, index or None).
FIT_ALIASES = {"damping": ("damping", "ratios", 0), "friction": ("friction", "coulomb", None),
               "coulomb": ("friction", "coulomb", None), "viscous": ("friction", "viscous", None)}
_FITTABLE_TABLES = ("beam", "motor", "friction", "damping")
_NAME = re.compile(r"^(?:(beam|motor|friction|damping)\.)?([A-Za-z_][A-Za-z0-9_]*)(?:\[(\d+)\])?$")


@dataclass(frozen=True)
class FitField:
    """One fitted rig field: where it is in the rig, its scale and its bounds.

    Built by :func:`resolve_fields` from the names the caller gives (``--fit`` on the command line).

    Attributes
    ----------
    name : str
        As the caller spelled it (``"E"``, ``"damping"``, ``"friction.coulomb"``).
    table, key : str
        Its table in a rig file and key (``"damping"``, ``"ratios"``).
    index : int or None
        The entry of a list field (``damping.ratios[0]``).
    unit : str
    lo, hi : float
        Its allowed range (from the field's metadata).
    """

    name: str
    table: str
    key: str
    index: int | None
    unit: str
    lo: float
    hi: float

    @property
    def path(self) -> str:
        """``table.key`` or ``table.key[i]``."""
        return f"{self.table}.{self.key}" + ("" if self.index is None else f"[{self.index}]")

    def get(self, rig: Rig) -> float:
        """Its value in ``rig`` [its unit].

        Parameters
        ----------
        rig : Rig
        """
        value = getattr(getattr(rig, _ATTR[self.table]), self.key)
        if self.index is None:
            return float(value)
        if not value:
            return 0.0
        return float(value[min(self.index, len(value) - 1)])


def _allowed_names() -> str:
    beam = [f.name for f in fields(RIG_TABLES["beam"]) if f.metadata["kind"] is float]
    return ", ".join(beam + list(FIT_ALIASES)) + ", or table.key (motor.k_t, friction.viscous, ...)"


def resolve_fields(names, rig: Rig, option: str = "--fit") -> list:
    """The :class:`FitField` of each name: a beam field (``E``), an alias (:data:`FIT_ALIASES`),
    a key of one table (``k_t``) or ``table.key`` (``damping.ratios[1]``).

    Parameters
    ----------
    names : sequence of str or str
        Comma-separated text or a sequence.
    rig : Rig
    option : str
        The argument's name as the caller spelled it.

    Returns
    -------
    list of FitField
    """
    if isinstance(names, str):
        names = [n.strip() for n in names.split(",")]
    names = list(names)
    if not names or any(not isinstance(n, str) or not n for n in names):
        raise ParameterError(f"{option} must name at least one rig field ({_allowed_names()})")
    out = []
    for name in names:
        if name in FIT_ALIASES:
            table, key, index = FIT_ALIASES[name]
        else:
            m = _NAME.match(name)
            if not m:
                raise ParameterError(f"{option}: {name[:40]!r} is not a rig field; allowed: {_allowed_names()}")
            table, key, index = m.group(1), m.group(2), None if m.group(3) is None else int(m.group(3))
            if table is None:
                hits = [t for t in _FITTABLE_TABLES if key in {f.name for f in fields(RIG_TABLES[t])}]
                if not hits:
                    raise ParameterError(f"{option}: {name[:40]!r} is not a rig field; allowed: {_allowed_names()}")
                table = hits[0]
        cls = RIG_TABLES[table]
        meta = {f.name: f.metadata for f in fields(cls)}.get(key)
        if meta is None:
            raise ParameterError(f"{option}: {name[:40]!r} is not a rig field; allowed: {_allowed_names()}")
        if key == "ratios":
            index = 0 if index is None else index
            lo, hi, unit = 0.0, 0.999, "-"
        else:
            if index is not None or meta["kind"] is not float:
                raise ParameterError(f"{option}: {name[:40]!r} is not a number field that can be fitted")
            lo = meta["lo"] if isinstance(meta["lo"], (int, float)) else 0.0
            hi = meta["hi"] if isinstance(meta["hi"], (int, float)) else math.inf
            if meta["lo_open"]:
                lo = lo + max(abs(lo) * 1e-9, 1e-300)
            unit = meta["unit"]
        f = FitField(name, table, key, index, unit, float(lo), float(hi))
        if any(g.path == f.path for g in out):
            raise ParameterError(f"{option}: {name} is given twice")
        out.append(f)
    return out
