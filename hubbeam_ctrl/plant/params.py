"""Physical and discretisation parameters of the hub-beam system.

One frozen :class:`Params` value, in SI units, travels through every layer of the
toolbox. Its defaults are Table 1 of Bai et al. (2009) with the tip mass at the free
end and five axial plus five transverse assumed modes.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field, fields
from pathlib import Path

import tomllib

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.fileio import atomic_write_text

__all__ = ["Params", "load_params", "save_params", "MAX_MODES"]

#: Largest number of assumed modes per family that the basis is verified for.
MAX_MODES = 20


def _unit(unit: str, doc: str, positive: bool = False, nonnegative: bool = False):
    return {"unit": unit, "doc": doc, "positive": positive, "nonnegative": nonnegative}


@dataclass(frozen=True)
class Params:
    """Parameters of the hub-beam-tip-mass system (SI units).

    Parameters
    ----------
    L : float
        Beam length [m], > 0. Default 8.
    rho : float
        Mass density [kg/m^3], > 0. Default 2766.7.
    A : float
        Cross-section area [m^2], > 0. Default 7.2968e-5.
    E : float
        Young's modulus [Pa], > 0. Default 6.8952e10.
    I : float
        Area moment of inertia of the cross-section [m^4], > 0. Default 8.2189e-9.
    J_h : float
        Hub moment of inertia about its axis [kg m^2], > 0. Default 200.
    r : float
        Hub radius, i.e. radius of the beam root [m], >= 0. Default 0.5.
    m_t : float
        Point tip mass [kg], >= 0. Default 0.1.
    l : float or None
        Position of the tip mass along the undeformed beam, measured from the root
        [m], 0 <= l <= L. ``None`` (default) means the free end, l = L.
    n_axial : int
        Number of axial assumed modes n1, 1..20. Default 5.
    n_transverse : int
        Number of transverse assumed modes n2, 1..20. Default 5.
    damping_ratio : float
        Modal damping ratio zeta of the non-rotating clamped modes [-], 0 <= zeta < 1.
        Default 0 (undamped, as in the paper).
    tau_max : float
        Torque limit of the hub motor [N m], > 0. Default 200 (the paper's Eq. 44
        amplitude). Every controller saturates its output there, or at a smaller limit
        its settings give; a larger one is an error.

    Examples
    --------
    >>> p = Params(m_t=0.0)
    >>> p.tip_position
    8.0
    >>> p.replace(n_transverse=3).n_transverse
    3
    """

    L: float = field(default=8.0, metadata=_unit("m", "beam length", positive=True))
    rho: float = field(default=2.7667e3, metadata=_unit("kg/m^3", "mass density", positive=True))
    A: float = field(default=7.2968e-5, metadata=_unit("m^2", "cross-section area", positive=True))
    E: float = field(default=6.8952e10, metadata=_unit("Pa", "Young's modulus", positive=True))
    I: float = field(default=8.2189e-9, metadata=_unit("m^4", "area moment of inertia", positive=True))
    J_h: float = field(default=200.0, metadata=_unit("kg m^2", "hub inertia", positive=True))
    r: float = field(default=0.5, metadata=_unit("m", "hub radius", nonnegative=True))
    m_t: float = field(default=0.1, metadata=_unit("kg", "tip mass", nonnegative=True))
    l: float | None = field(default=None, metadata=_unit("m", "tip-mass position (None: at L)"))
    n_axial: int = field(default=5, metadata=_unit("-", "number of axial modes"))
    n_transverse: int = field(default=5, metadata=_unit("-", "number of transverse modes"))
    damping_ratio: float = field(default=0.0, metadata=_unit("-", "modal damping ratio"))
    tau_max: float = field(default=200.0, metadata=_unit("N m", "hub motor torque limit", positive=True))

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name == "l" and value is None:
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ParameterError(f"{f.name} must be a number, got {value!r}")
            if not math.isfinite(value):
                raise ParameterError(f"{f.name} must be finite, got {value}")
            meta = f.metadata
            if meta.get("positive") and not value > 0:
                raise ParameterError(f"{f.name} must be > 0 [{meta['unit']}], got {value}")
            if meta.get("nonnegative") and not value >= 0:
                raise ParameterError(f"{f.name} must be >= 0 [{meta['unit']}], got {value}")
        for name in ("n_axial", "n_transverse"):
            value = getattr(self, name)
            if int(value) != value or not 1 <= value <= MAX_MODES:
                raise ParameterError(
                    f"{name} must be an integer in 1..{MAX_MODES}, got {value}")
            object.__setattr__(self, name, int(value))
        if self.l is not None and not 0.0 <= self.l <= self.L:
            raise ParameterError(f"l must be in [0, L] = [0, {self.L}] m, got {self.l}")
        if not 0.0 <= self.damping_ratio < 1.0:
            raise ParameterError(
                f"damping_ratio must be in [0, 1), got {self.damping_ratio}")
        for name in ("L", "rho", "A", "E", "I", "J_h", "r", "m_t", "damping_ratio", "tau_max"):
            object.__setattr__(self, name, float(getattr(self, name)))
        if self.l is not None:
            object.__setattr__(self, "l", float(self.l))

    # -- derived quantities -------------------------------------------------
    @property
    def tip_position(self) -> float:
        """Position of the tip mass along the beam [m] (``l``, or ``L`` if unset)."""
        return self.L if self.l is None else self.l

    @property
    def EI(self) -> float:
        """Bending stiffness E I [N m^2]."""
        return self.E * self.I

    @property
    def EA(self) -> float:
        """Axial stiffness E A [N]."""
        return self.E * self.A

    @property
    def rhoA(self) -> float:
        """Mass per unit length rho A [kg/m]."""
        return self.rho * self.A

    @property
    def beam_mass(self) -> float:
        """Mass of the beam rho A L [kg]."""
        return self.rhoA * self.L

    @property
    def total_inertia(self) -> float:
        """Rigid-body inertia of hub, undeformed beam and tip mass about the hub axis [kg m^2]."""
        r, L = self.r, self.L
        beam = self.rhoA * ((r + L) ** 3 - r ** 3) / 3.0
        return self.J_h + beam + self.m_t * (r + self.tip_position) ** 2

    def replace(self, **changes) -> "Params":
        """Return a copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict:
        """Plain dictionary of all fields (``l`` is ``None`` when the mass is at the end)."""
        return dataclasses.asdict(self)

    @classmethod
    def units(cls) -> dict:
        """Mapping field name -> unit string."""
        return {f.name: f.metadata["unit"] for f in fields(cls)}

    @classmethod
    def from_dict(cls, data: dict) -> "Params":
        """Build from a mapping; unknown keys raise :class:`ParameterError`."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ParameterError(
                f"unknown parameter(s) {', '.join(unknown)}; allowed: {', '.join(sorted(known))}")
        return cls(**data)


def load_params(path) -> Params:
    """Load :class:`Params` from a TOML file.

    The file holds ``key = value`` pairs at top level or in a ``[params]`` table, keys
    being the field names of :class:`Params` (SI units). Missing keys take the defaults.

    Parameters
    ----------
    path : str or Path
        TOML file.

    Returns
    -------
    Params
    """
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise ParameterError(f"params file {path} does not exist") from None
    except tomllib.TOMLDecodeError as exc:
        raise ParameterError(f"params file {path} is not valid TOML: {exc}") from None
    if set(data) == {"params"} and isinstance(data["params"], dict):
        data = data["params"]
    return Params.from_dict(data)


def save_params(params: Params, path) -> None:
    """Write :class:`Params` to a TOML file atomically, with units as comments.

    Parameters
    ----------
    params : Params
    path : str or Path
    """
    units = Params.units()
    lines = ["# hubbeam-ctrl parameters, SI units"]
    for key, value in params.to_dict().items():
        if value is None:   # l unset: tip mass at the free end
            lines.append(f"# {key} unset: at the free end")
            continue
        lines.append(f"{key} = {value!r}  # [{units[key]}]")
    atomic_write_text(path, "\n".join(lines) + "\n")
