"""What the user does not know about a rig: ranges on its physical parameters, as one value.

An :class:`Uncertainty` is a box: for each uncertain parameter a closed range ``[lo, hi]`` in
the parameter's own SI unit. It is the ``[uncertainty]`` table of a rig file::

    [uncertainty]
    m_t = [0.0, 0.5]          # [kg] payload at the tip
    E = [66e9, 72e9]          # [Pa]
    damping = [0.0005, 0.02]  # [-] every bending mode's damping ratio; the low end is the floor
    delay = [0.3, 0.7]        # [-] computation delay, fraction of the sample

and the same in Python (``Uncertainty.from_table({"m_t": (0.0, 0.5)})``); a calibration's
95 % intervals become one with :meth:`Uncertainty.from_intervals`. :meth:`Uncertainty.apply`
gives the rig at one point of the box, which is how every consumer (the worst-case
certificate of :mod:`hubbeam_ctrl.study.worst_case`, a nonlinear run at the worst plant) sees
the set: the parameters are physical, never a perturbation of a linear model.

The parameters (:data:`UNCERTAIN`):

========== =========== ============ =====================================================
name       rig field   unit         what
========== =========== ============ =====================================================
m_t        beam.m_t    kg           point mass at the tip (the payload)
l          beam.l      m            where along the beam that mass sits (root 0, tip L)
E          beam.E      Pa           Young's modulus (the bending stiffness E I)
J_h        beam.J_h    kg m^2       hub inertia
damping    damping     \\-           modal damping ratio of every bending mode
viscous    friction    N m s/rad    viscous friction at the hub
coulomb    friction    N m          Coulomb friction at the hub (not linear: nonlinear runs only)
k_t        motor.k_t   N m/A        torque constant (DC motor rigs)
k_e        motor.k_e   V s/rad      back-EMF constant (DC motor rigs)
R          motor.R     ohm          armature resistance (DC motor rigs)
delay      timing      \\-           computation delay, fraction of the sample
========== =========== ============ =====================================================
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError

__all__ = ["UNCERTAIN", "UncertainRange", "Uncertainty"]

#: Uncertain parameter -> (rig part, field, unit, what it is).
UNCERTAIN = {
    "m_t": ("beam", "m_t", "kg", "tip payload mass"),
    "l": ("beam", "l", "m", "position of the tip mass along the beam"),
    "E": ("beam", "E", "Pa", "Young's modulus"),
    "J_h": ("beam", "J_h", "kg m^2", "hub inertia"),
    "damping": ("damping", "ratios", "-", "damping ratio of every bending mode"),
    "viscous": ("friction", "viscous", "N m s/rad", "viscous friction at the hub"),
    "coulomb": ("friction", "coulomb", "N m", "Coulomb friction at the hub"),
    "k_t": ("drive", "k_t", "N m/A", "motor torque constant"),
    "k_e": ("drive", "k_e", "V s/rad", "motor back-EMF constant"),
    "R": ("drive", "R", "ohm", "armature resistance"),
    "delay": ("timing", "delay", "-", "computation delay as a fraction of the sample"),
}

#: Parameters a linear loop does not see (the certificate says so; nonlinear runs use them).
NONLINEAR_ONLY = ("coulomb",)


@dataclass(frozen=True)
class UncertainRange:
    """One uncertain parameter's closed range.

    Attributes
    ----------
    name : str
        A key of :data:`UNCERTAIN`.
    lo, hi : float
        The range's ends, in the parameter's unit (``lo <= hi``).
    """

    name: str
    lo: float
    hi: float

    @property
    def unit(self) -> str:
        """The parameter's unit."""
        return UNCERTAIN[self.name][2]

    def at(self, u: float) -> float:
        """The value at a normalised coordinate.

        Parameters
        ----------
        u : float
            In [0, 1] (0: ``lo``, 1: ``hi``; clipped).

        Returns
        -------
        float
            In the parameter's unit.
        """
        return float(self.lo + (self.hi - self.lo) * min(max(float(u), 0.0), 1.0))


def _pair(name: str, value, where: str) -> tuple:
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        value = (value, value)
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise ParameterError(f"{where}{name} must be a range [lo, hi] of two numbers, got {value!r}")
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ParameterError(f"{where}{name} must be a range [lo, hi] of two numbers, got {value!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise ParameterError(f"{where}{name} must be finite, got [{lo:g}, {hi:g}]")
    if lo > hi:
        raise ParameterError(f"{where}{name} must have lo <= hi, got [{lo:g}, {hi:g}]")
    return lo, hi


@dataclass(frozen=True)
class Uncertainty:
    """A box of uncertain physical parameters of a rig (see the module docstring).

    Attributes
    ----------
    ranges : tuple of UncertainRange
        One per uncertain parameter, in :data:`UNCERTAIN`'s order; empty: nothing uncertain.
    """

    ranges: tuple = ()

    def __post_init__(self):
        seen = set()
        for r in self.ranges:
            if not isinstance(r, UncertainRange):
                raise ParameterError(f"uncertainty ranges must be UncertainRange, got {type(r).__name__}")
            if r.name not in UNCERTAIN:
                raise ParameterError(f"unknown uncertainty.{str(r.name)[:40]}; allowed: {', '.join(UNCERTAIN)}")
            if r.name in seen:
                raise ParameterError(f"uncertainty.{r.name} is given twice")
            seen.add(r.name)
            _pair(r.name, (r.lo, r.hi), "uncertainty.")
        order = list(UNCERTAIN)
        object.__setattr__(self, "ranges", tuple(sorted(self.ranges, key=lambda r: order.index(r.name))))

    @classmethod
    def from_table(cls, table, where: str = "") -> "Uncertainty":
        """The set of an ``[uncertainty]`` table: ``name -> [lo, hi]`` (a single number: fixed).

        Parameters
        ----------
        table : dict
            Keys of :data:`UNCERTAIN`, values ranges in the parameter's unit.
        where : str
            Prefix of error messages (e.g. ``"rig file x.toml: "``).

        Returns
        -------
        Uncertainty
        """
        if not isinstance(table, dict):
            raise ParameterError(f"{where}[uncertainty] must be a table of ranges, got {type(table).__name__}")
        ranges = []
        for key, value in table.items():
            if key not in UNCERTAIN:
                raise ParameterError(f"{where}unknown key uncertainty.{str(key)[:40]}; allowed in "
                                     f"[uncertainty]: {', '.join(UNCERTAIN)}")
            lo, hi = _pair(f"uncertainty.{key}", value, where)
            ranges.append(UncertainRange(key, lo, hi))
        return cls(tuple(ranges))

    @classmethod
    def from_intervals(cls, intervals: dict) -> "Uncertainty":
        """The set of a calibration's confidence intervals.

        Parameters
        ----------
        intervals : dict
            Field -> ``(lo, hi)``: ``E``, ``J_h``, ``m_t`` as fitted; ``friction.viscous``,
            ``friction.coulomb``, ``motor.k_t``... map to their short names; fields that are
            not uncertain parameters are left out.

        Returns
        -------
        Uncertainty
        """
        short = {f"{part if part != 'drive' else 'motor'}.{fld}": name for name, (part, fld, _, _) in UNCERTAIN.items()}
        short.update({f"beam.{n}": n for n in ("m_t", "l", "E", "J_h")})
        short["friction"] = "coulomb"          # identify's "friction" field is the Coulomb level
        table = {}
        for key, value in intervals.items():
            name = key if key in UNCERTAIN else short.get(key)
            if name is not None and value is not None:
                table[name] = tuple(value)
        return cls.from_table(table)

    def to_table(self) -> dict:
        """The ``[uncertainty]`` table: ``name -> [lo, hi]``."""
        return {r.name: [r.lo, r.hi] for r in self.ranges}

    @property
    def names(self) -> tuple:
        """The uncertain parameters, in order."""
        return tuple(r.name for r in self.ranges)

    @property
    def is_set(self) -> bool:
        """Something is uncertain."""
        return bool(self.ranges)

    @property
    def varying(self) -> tuple:
        """The ranges of positive width."""
        return tuple(r for r in self.ranges if r.hi > r.lo)

    def __getitem__(self, name: str) -> UncertainRange:
        for r in self.ranges:
            if r.name == name:
                return r
        raise KeyError(name)

    def values_at(self, u) -> dict:
        """Parameter values at normalised coordinates ``u`` of the varying ranges (fixed ones at their value).

        Parameters
        ----------
        u : sequence of float
            One coordinate in [0, 1] per range of :attr:`varying`.

        Returns
        -------
        dict
            name -> value, every range.
        """
        u = np.atleast_1d(np.asarray(u, dtype=float))
        vary = self.varying
        if u.size != len(vary):
            raise ParameterError(f"u must have {len(vary)} coordinates (the varying ranges), got {u.size}")
        out = {r.name: r.lo for r in self.ranges}
        out.update({r.name: r.at(x) for r, x in zip(vary, u)})
        return out

    def apply(self, rig, values: dict):
        """The rig at one point of the set.

        Parameters
        ----------
        rig : Rig
            The nominal rig.
        values : dict
            name -> value for some of the uncertain parameters (others keep the rig's).

        Returns
        -------
        Rig
            With the values set (``damping``: every mode's ratio, the beam's own
            ``damping_ratio`` cleared); refused in one line when a value does not fit the
            rig (a motor constant on a torque drive, a value outside the field's range).
        """
        from hubbeam_ctrl.plant.rig_parts import Damping
        beam, drive, friction, timing = {}, {}, {}, {}
        damping = None
        for name, value in values.items():
            if name not in UNCERTAIN:
                raise ParameterError(f"unknown uncertainty.{str(name)[:40]}; allowed: {', '.join(UNCERTAIN)}")
            part, fld, _, _ = UNCERTAIN[name]
            if part == "drive" and rig.drive.is_ideal:
                raise ParameterError(f"uncertainty.{name} needs a DC motor (motor.kind = \"dc_motor\"); "
                                     "the rig's drive is a torque source")
            target = {"beam": beam, "drive": drive, "friction": friction, "timing": timing}.get(part)
            if target is not None:
                target[fld] = float(value)
            else:
                damping = float(value)
        try:
            parts = {}
            if beam or damping is not None:
                parts["beam"] = rig.beam.replace(**beam, **({"damping_ratio": 0.0} if damping is not None else {}))
            if drive:
                parts["drive"] = rig.drive.replace(**drive)
            if friction:
                f = rig.friction
                if f.breakaway is not None and "coulomb" in friction:
                    friction["breakaway"] = max(f.breakaway, friction["coulomb"])
                parts["friction"] = f.replace(**friction)
            if timing:
                parts["timing"] = rig.timing.replace(**timing)
            if damping is not None:
                parts["damping"] = Damping(ratios=(damping,))
            return rig.replace(**parts, uncertainty=Uncertainty())
        except ParameterError as exc:
            raise ParameterError(f"uncertainty: {exc}") from None

    @staticmethod
    def rig_value(rig, name: str) -> float:
        """The rig's own value of an uncertain parameter.

        Parameters
        ----------
        rig : Rig
        name : str
            A key of :data:`UNCERTAIN`.

        Returns
        -------
        float
            In the parameter's unit (``damping``: the first bending mode's ratio; ``l`` unset:
            the beam's length, the free end).
        """
        part, fld, _, _ = UNCERTAIN[name]
        if part == "damping":
            ratios = rig.damping.ratios if rig.damping.is_set else (rig.beam.damping_ratio,)
            return float(ratios[0]) if ratios else 0.0
        if part == "beam":
            value = getattr(rig.beam, fld)
            return float(rig.beam.L if value is None else value)
        return float(getattr({"drive": rig.drive, "friction": rig.friction, "timing": rig.timing}[part], fld))

    def check(self, rig) -> None:
        """Refuse (one line) a set whose ends do not fit ``rig`` (each range's both ends applied).

        Parameters
        ----------
        rig : Rig
        """
        for r in self.ranges:
            for v in (r.lo, r.hi):
                try:
                    self.apply(rig, {r.name: v})
                except ParameterError as exc:
                    raise ParameterError(f"uncertainty.{r.name} = [{r.lo:g}, {r.hi:g}] does not fit the rig: "
                                         f"{str(exc).removeprefix('uncertainty: ')}") from None

    def describe(self) -> str:
        """One line: ``m_t 0-0.5 kg, damping 0.0005-0.02``."""
        if not self.ranges:
            return "nothing uncertain"
        return ", ".join(f"{r.name} {r.lo:g}-{r.hi:g}" + ("" if r.unit == "-" else f" {r.unit}") for r in self.ranges)
