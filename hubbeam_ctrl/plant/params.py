"""Physical and discretisation parameters of the hub-beam system.

One frozen :class:`Params` value, in SI units, travels through every layer of the
toolbox. Its defaults are Table 1 of Bai et al. (2009) with the tip mass at the free
end and five axial plus five transverse assumed modes.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from pathlib import Path

import tomllib

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.fileio import atomic_write_text
from hubbeam_ctrl.core.settings import Settings, setting

__all__ = ["Params", "load_params", "save_params", "MAX_MODES"]

#: Largest number of assumed modes per family that the basis is verified for.
MAX_MODES = 20


@dataclass(frozen=True)
class Params(Settings):
    """Parameters of the hub-beam-tip-mass system (SI units).

    Examples
    --------
    >>> p = Params(m_t=0.0)
    >>> p.tip_position
    8.0
    >>> p.replace(n_transverse=3).n_transverse
    3
    """

    L: float = setting(8.0, unit="m", lo=0.0, lo_open=True, doc="Beam length.")
    rho: float = setting(2.7667e3, unit="kg/m^3", lo=0.0, lo_open=True, doc="Mass density.")
    A: float = setting(7.2968e-5, unit="m^2", lo=0.0, lo_open=True, doc="Cross-section area.")
    E: float = setting(6.8952e10, unit="Pa", lo=0.0, lo_open=True, doc="Young's modulus.")
    I: float = setting(8.2189e-9, unit="m^4", lo=0.0, lo_open=True, doc="Area moment of inertia of the cross-section.")
    J_h: float = setting(200.0, unit="kg m^2", lo=0.0, lo_open=True, doc="Hub moment of inertia about its axis.")
    r: float = setting(0.5, unit="m", lo=0.0, doc="Hub radius, i.e. radius of the beam root.")
    m_t: float = setting(0.1, unit="kg", lo=0.0, doc="Point tip mass.")
    l: float | None = setting(None, unit="m", lo=0.0, hi="L", kind=float,
                              doc="Position of the tip mass along the undeformed beam, measured from "
                                  "the root; None means the free end, l = L.")
    n_axial: int = setting(5, lo=1, hi=MAX_MODES, doc="Number of axial assumed modes n1.")
    n_transverse: int = setting(5, lo=1, hi=MAX_MODES, doc="Number of transverse assumed modes n2.")
    damping_ratio: float = setting(0.0, lo=0.0, hi=1.0, hi_open=True,
                                   doc="Modal damping ratio zeta of the non-rotating clamped modes "
                                       "(0: undamped, as in the paper).")
    tau_max: float = setting(200.0, unit="N m", lo=0.0, lo_open=True,
                             doc="Torque limit of the hub motor (default: the paper's Eq. 44 amplitude). "
                                 "Every controller saturates its output there, or at a smaller limit its "
                                 "settings give; a larger one is an error.")

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
