"""Physical and discretisation parameters of the hub-beam system.

One frozen :class:`Params` value, in SI units, travels through every layer of the
toolbox. Its defaults are Table 1 of Bai et al. (2009) with the tip mass at the free
end and five axial plus five transverse assumed modes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.fileio import atomic_write_text
from hubbeam_ctrl.core.settings import Settings, setting

__all__ = ["Params", "load_params", "save_params", "MAX_MODES", "MAX_ROOT_STRAIN", "RELATIONS", "Relation",
           "check_spin"]

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

    L: float = setting(8.0, unit="m", lo=1e-2, hi=1e3, doc="Beam length.")
    rho: float = setting(2.7667e3, unit="kg/m^3", lo=1.0, hi=1e5, doc="Mass density.")
    A: float = setting(7.2968e-5, unit="m^2", lo=1e-10, hi=1.0, doc="Cross-section area.")
    E: float = setting(6.8952e10, unit="Pa", lo=1e5, hi=1e13, doc="Young's modulus.")
    I: float = setting(8.2189e-9, unit="m^4", lo=1e-20, hi=1.0,
                       doc="Area moment of inertia of the cross-section; the slenderness "
                           "L / sqrt(I/A) must be in [10, 1e5] (Euler-Bernoulli beam).")
    J_h: float = setting(200.0, unit="kg m^2", lo=1e-9, hi=1e12,
                         doc="Hub moment of inertia about its axis; at most 1e8 times the beam's "
                             "(beam_inertia).")
    r: float = setting(0.5, unit="m", lo=0.0, hi=1e3, doc="Hub radius, i.e. radius of the beam root; "
                                                         "at most 100 L.")
    m_t: float = setting(0.1, unit="kg", lo=0.0, hi=1e6,
                         doc="Point tip mass; at most 1000 times the beam mass rho A L.")
    l: float | None = setting(None, unit="m", lo=0.0, hi="L", kind=float,
                              doc="Position of the tip mass along the undeformed beam, measured from "
                                  "the root; None means the free end, l = L.")
    n_axial: int = setting(5, lo=1, hi=MAX_MODES, doc="Number of axial assumed modes n1.")
    n_transverse: int = setting(5, lo=1, hi=MAX_MODES, doc="Number of transverse assumed modes n2.")
    damping_ratio: float = setting(0.0, lo=0.0, hi=1.0, hi_open=True,
                                   doc="Modal damping ratio zeta of the non-rotating clamped modes "
                                       "(0: undamped, as in the paper).")
    damping_ratios: tuple = setting((), kind=tuple,
                                    doc="Per-mode damping ratios of transverse clamped modes 1, 2, ..., each "
                                        "in [0, 1); modes beyond the list take its last value; empty: "
                                        "damping_ratio for every mode (axial modes always take damping_ratio).")
    tau_max: float = setting(200.0, unit="N m", lo=0.0, lo_open=True, hi=1e9,
                             doc="Torque limit of the hub motor (default: the paper's Eq. 44 amplitude). "
                                 "Every controller saturates its output there, or at a smaller limit its "
                                 "settings give; a larger one is an error.")

    def __post_init__(self):
        if isinstance(self.damping_ratios, list):
            object.__setattr__(self, "damping_ratios", tuple(self.damping_ratios))
        super().__post_init__()
        ratios = []
        for k, z in enumerate(self.damping_ratios):
            if isinstance(z, bool) or not isinstance(z, (int, float, np.integer, np.floating)) \
                    or not 0.0 <= z < 1.0:
                raise ParameterError(f"damping_ratios must hold numbers in [0, 1), got {str(z)[:40]} at "
                                     f"index {k}")
            ratios.append(float(z))
        object.__setattr__(self, "damping_ratios", tuple(ratios))
        for rel in RELATIONS:
            rel.check(self)

    def to_dict(self) -> dict:
        """Plain dictionary of the fields; ``damping_ratios`` only when set (so that files, hashes
        and study folders of parameter sets without per-mode damping are as before)."""
        out = super().to_dict()
        if not out["damping_ratios"]:
            del out["damping_ratios"]
        return out

    def transverse_damping(self, n: int) -> np.ndarray:
        """Damping ratios of transverse modes 1..n [-] (``damping_ratios``, else ``damping_ratio``).

        Parameters
        ----------
        n : int
            Number of modes.

        Returns
        -------
        ndarray (n,)
        """
        z = self.damping_ratios
        if not z:
            return np.full(n, self.damping_ratio)
        return np.array([z[min(i, len(z) - 1)] for i in range(n)])

    # -- derived quantities -------------------------------------------------
    tip_position = property(lambda self: self.L if self.l is None else self.l,
                            doc="Position of the tip mass along the beam [m] (``l``, or ``L`` if unset).")
    EI = property(lambda self: self.E * self.I, doc="Bending stiffness E I [N m^2].")
    EA = property(lambda self: self.E * self.A, doc="Axial stiffness E A [N].")
    rhoA = property(lambda self: self.rho * self.A, doc="Mass per unit length rho A [kg/m].")
    beam_mass = property(lambda self: self.rhoA * self.L, doc="Mass of the beam rho A L [kg].")

    @property
    def total_inertia(self) -> float:
        """Rigid-body inertia of hub, undeformed beam and tip mass about the hub axis [kg m^2]."""
        r, L = self.r, self.L
        beam = self.rhoA * ((r + L) ** 3 - r ** 3) / 3.0
        return self.J_h + beam + self.m_t * (r + self.tip_position) ** 2

    @property
    def beam_inertia(self) -> float:
        """Inertia of the undeformed beam about the hub axis ``rho A ((r+L)^3 - r^3) / 3`` [kg m^2]."""
        return self.rhoA * ((self.r + self.L) ** 3 - self.r ** 3) / 3.0

    @property
    def slenderness(self) -> float:
        """Slenderness ratio ``L / sqrt(I/A)`` [-] (length over radius of gyration)."""
        return self.L / math.sqrt(self.I / self.A)

    @property
    def max_spin(self) -> float:
        """Largest spin rate the models are used at [rad/s].

        The steady centrifugal force at the root, ``rho A ((r+L)^2 - r^2) Omega^2 / 2 +
        m_t (r + l) Omega^2``, may stretch the root by at most :data:`MAX_ROOT_STRAIN` (1 %):
        the models are second order in the elastic coordinates (small strain). For Table 1
        this is 79 rad/s (83 without the tip mass), well above TLAM's critical speed
        (2.6 rad/s), so its unstable regime stays reachable, and well below the first axial
        frequency (where the steady stretch has no solution).
        """
        r, L = self.r, self.L
        force_per_rate2 = 0.5 * self.rhoA * ((r + L) ** 2 - r ** 2) + self.m_t * (r + self.tip_position)
        return math.sqrt(MAX_ROOT_STRAIN * self.EA / force_per_rate2)

    @classmethod
    def from_dict(cls, data: dict) -> "Params":
        """Build from a mapping; unknown keys raise :class:`ParameterError`.

        Parameters
        ----------
        data : dict
            Field name -> value (SI units, as in a TOML file).
        """
        if not isinstance(data, dict):
            raise ParameterError(f"params must be a mapping of field names to values, got "
                                 f"{type(data).__name__}")
        known = {f.name for f in fields(cls)}
        unknown = sorted(str(k) for k in set(data) - known)
        if unknown:
            shown = ", ".join(k[:40] for k in unknown[:5]) + (f" and {len(unknown) - 5} more"
                                                              if len(unknown) > 5 else "")
            raise ParameterError(f"unknown parameter(s) {shown}; allowed: {', '.join(sorted(known))}")
        return cls(**data)


#: Largest steady centrifugal strain at the beam root [-] (see :attr:`Params.max_spin`).
MAX_ROOT_STRAIN = 0.01


@dataclass(frozen=True)
class Relation:
    """A bound of one :class:`Params` field that depends on other fields.

    :data:`RELATIONS` lists them; a :class:`Params` that breaks one is refused with its ``text``
    and ``why``.

    Attributes
    ----------
    name : str
        The field it bounds.
    text : str
        The bound as written in messages and in ``docs/ranges.md``.
    lo, hi : callable or None
        ``Params -> float``: the bound's value (inclusive).
    why : str
        What the bound protects.
    """

    name: str
    text: str
    lo: object
    hi: object
    why: str

    def check(self, p: "Params") -> None:
        """Raise :class:`ParameterError` naming the field unless ``p`` satisfies the bound.

        Parameters
        ----------
        p : Params
            The parameters to check.
        """
        value = getattr(p, self.name)
        lo = self.lo(p) if self.lo else None
        hi = self.hi(p) if self.hi else None
        if (lo is not None and value < lo * (1 - 1e-12)) or (hi is not None and value > hi * (1 + 1e-12)):
            span = (f"in [{lo:.4g}, {hi:.4g}]" if lo is not None and hi is not None
                    else f"<= {hi:.4g}" if hi is not None else f">= {lo:.4g}")
            unit = Params.units()[self.name]
            raise ParameterError(f"{self.name} must be {span} [{unit}] ({self.text}: {self.why}), "
                                 f"got {value:g}")


#: Bounds between fields, checked after each field's own range (in this order).
RELATIONS = (
    Relation("I", "slenderness L / sqrt(I/A) in [10, 1e5]", lambda p: p.A * (p.L / 1e5) ** 2,
             lambda p: p.A * (p.L / 10) ** 2, "a slender Euler-Bernoulli beam"),
    Relation("r", "r <= 100 L", None, lambda p: 100 * p.L, "hub and beam of comparable size"),
    Relation("J_h", "J_h <= 1e8 beam_inertia", None, lambda p: 1e8 * p.beam_inertia,
             "a well-conditioned mass matrix"),
    Relation("m_t", "m_t <= 1000 rho A L", None, lambda p: 1e3 * p.beam_mass,
             "the beam's assumed modes still describe the tip mass"),
)


def check_spin(name: str, spin, params: Params) -> float:
    """Return ``float(spin)``; raise unless it is a real number with ``|spin| <= params.max_spin``.

    Parameters
    ----------
    name : str
        The argument's name as the caller spelled it (starts the message).
    spin : float
        Spin rate [rad/s].
    params : Params
        The beam: its ``max_spin``.

    Returns
    -------
    float

    Examples
    --------
    >>> check_spin("spin", 3, Params())
    3.0
    >>> check_spin("spin", 1e308, Params())  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    hubbeam_ctrl.core.errors.ParameterError: spin must be in [-78.73, 78.73] [rad/s] (1 % ...), got 1e+308
    """
    if isinstance(spin, (bool, np.bool_)) or not isinstance(spin, (int, float, np.integer, np.floating)):
        raise ParameterError(f"{name} must be a number [rad/s], got {spin!r}"[:200])
    try:
        value = float(spin)
    except OverflowError:
        value = math.inf
    limit = params.max_spin
    if not abs(value) <= limit:
        raise ParameterError(f"{name} must be in [{-limit:.4g}, {limit:.4g}] [rad/s] (1 % centrifugal "
                             f"strain at the root, Params.max_spin), got {value:g}")
    return value


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
    data = _read_toml(path)
    if set(data) == {"params"} and isinstance(data["params"], dict):
        data = data["params"]
    try:
        return Params.from_dict(data)
    except ParameterError as exc:
        raise ParameterError(f"params file {path}: {exc}") from None


#: Largest parameter file read [bytes] (a parameter set is a few hundred bytes).
MAX_PARAMS_FILE_BYTES = 1_000_000


def _read_toml(path) -> dict:
    """The TOML document at ``path`` (:func:`hubbeam_ctrl.core.reading.read_toml`: a missing
    path, a folder, a FIFO or device, an unreadable file, a file over
    :data:`MAX_PARAMS_FILE_BYTES`, bytes that are not UTF-8, invalid or too deeply nested TOML
    are one-line errors)."""
    from hubbeam_ctrl.core.reading import read_toml
    if path is None or str(path).strip() == "":
        raise ParameterError(f"params file must be named, got {str(path)!r}")
    return read_toml(path, "params file", MAX_PARAMS_FILE_BYTES)


def save_params(params: Params, path) -> None:
    """Write :class:`Params` to a TOML file atomically, with units as comments.

    Parameters
    ----------
    params : Params
        The parameters (every field, SI units).
    path : str or Path
        The TOML file; :func:`load_params` reads it back equal.
    """
    if not isinstance(params, Params):
        raise ParameterError(f"params must be a Params (Params.from_dict(d) makes one from a dict), "
                             f"got {type(params).__name__}")
    units = Params.units()
    lines = ["# hubbeam-ctrl parameters, SI units"]
    for key, value in params.to_dict().items():
        if value is None:   # l unset: tip mass at the free end
            lines.append(f"# {key} unset: at the free end")
            continue
        text = "[" + ", ".join(map(repr, value)) + "]" if isinstance(value, tuple) else repr(value)
        lines.append(f"{key} = {text}  # [{units[key]}]")
    atomic_write_text(path, "\n".join(lines) + "\n")
