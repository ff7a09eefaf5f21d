"""One description of the physical rig: the beam, the drive, friction, damping, sensors, timing.

A :class:`Rig` is a frozen, validated value that says everything about a setup: the beam
(:class:`~hubbeam_ctrl.plant.params.Params`, as everywhere in the toolbox) and the hardware
around it: :class:`Drive` (an ideal torque source, the default, or a geared DC motor),
:class:`Friction` at the hub, :class:`Damping` of the beam's modes, :class:`Sensors` and
:class:`Timing`. Every field has a unit, a range and a description (``docs/ranges.md``);
a value out of range gives one line naming the key as it is written in a rig file
(``motor.R must be > 0 [ohm], got -1``).

One TOML file holds a rig, one table per part::

    [beam]        # Params fields (L, rho, A, E, I, J_h, r, m_t, ...)
    [motor]       # Drive fields (kind = "dc_motor", R, k_t, k_e, N, ...)
    [friction]    # Friction fields (viscous, coulomb, ...)
    [damping]     # Damping fields (ratios, alpha, beta)
    [sensors]     # Sensors fields (encoder_counts, strain_gauges, ...)
    [timing]      # Timing fields (dt, delay)

A missing table means ideal hardware for that part; today's flat parameter file (the
:class:`Params` fields at top level or in ``[params]``) loads as the beam alone with ideal
hardware. :func:`load_rig` also takes the name of a preset that ships with the toolbox
(:data:`PRESETS`: ``servo_link``, a Quanser-class rotary flexible link on an SRV02-class
servo, and ``paper``, Table 1 of Bai et al. with ideal hardware).

Examples
--------
>>> rig = load_rig("servo_link")
>>> rig.drive.kind, rig.drive.N, rig.sensors.encoder_counts
('dc_motor', 70.0, 4096)
>>> Rig().is_ideal
True
>>> Drive(kind="dc_motor", R=-1)
Traceback (most recent call last):
...
hubbeam_ctrl.core.errors.ParameterError: motor.R must be in (0, 10000] [ohm], got -1
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from importlib import resources
from pathlib import Path

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.fileio import atomic_write_text
from hubbeam_ctrl.core.reading import path_exists, read_toml
from hubbeam_ctrl.core.settings import Settings, setting
from hubbeam_ctrl.plant.params import MAX_MODES, MAX_PARAMS_FILE_BYTES, Params, _read_toml
from hubbeam_ctrl.plant.rig_parts import Damping, Drive, Friction, Sensors, Timing
from hubbeam_ctrl.plant.uncertainty import Uncertainty

__all__ = ["Drive", "Friction", "Damping", "Sensors", "Timing", "Rig", "load_rig", "save_rig", "PRESETS",
           "RIG_TABLES", "RIG_RELATIONS", "rig_from_dict", "rig_to_toml", "TAU_MAX_TOLERANCE"]

#: The presets that ship with the toolbox (``hubbeam_ctrl/data/rigs/<name>.toml``).
PRESETS = ("servo_link", "paper", "accel_link", "servo_payload", "space_boom")


#: Bounds of rig fields that depend on other fields: ``(class name, field) -> text`` (``docs/ranges.md``).
RIG_RELATIONS = {
    ("Drive", "I_max"): "eta_forward N eta_motor k_t I_max >= friction breakaway (the motor holds the hub at rest)",
    ("Drive", "tau_max"): 'kind = "torque" only; beam.tau_max within 1 % of it',
    ("Friction", "breakaway"): ">= coulomb",
    ("Damping", "ratios"): "each in [0, 1)",
    ("Sensors", "strain_gauges"): "each in [0, beam.L]",
    ("Rig", "beam"): "damping_ratio = 0 when [damping] is given; tau_max within 1 % of the drive's limit "
                     "(a DC motor's stall torque, a torque source's motor.tau_max)",
}

#: The tables of a rig file and the class each holds, in file order.
RIG_TABLES = {"beam": Params, "motor": Drive, "friction": Friction, "damping": Damping, "sensors": Sensors,
              "timing": Timing}

#: A beam's ``tau_max`` within this fraction of the drive's hub-torque limit is accepted (a preset
#: states the stall torque rounded, ``servo_link``'s 1.86 N m for 1.861) [-].
TAU_MAX_TOLERANCE = 0.01

_ATTR = {"beam": "beam", "motor": "drive", "friction": "friction", "damping": "damping", "sensors": "sensors",
         "timing": "timing"}


@dataclass(frozen=True)
class Rig(Settings):
    """The physical rig: the beam and the hardware around it (see the module docstring).

    Beyond each part's own ranges, a rig is refused when its DC motor cannot hold the hub
    at rest against friction (``eta_forward N eta_motor k_t I_max`` below the breakaway
    torque), a strain gauge lies beyond the beam, the beam's ``damping_ratio`` and the rig's
    ``[damping]`` are both given. The beam's ``tau_max`` follows from the drive
    (:attr:`Drive.torque_limit`): one within :data:`TAU_MAX_TOLERANCE` of it is kept, any
    other is replaced by it (so a rig whose drive is replaced, e.g. by a calibration, keeps a
    consistent limit); a rig file that states a conflicting ``beam.tau_max`` is refused
    (:func:`rig_from_dict`).
    """

    beam: Params = setting(factory=Params, doc="The beam, hub and tip mass (Params).")
    drive: Drive = setting(factory=Drive, doc="The hub drive ([motor] in a rig file).")
    friction: Friction = setting(factory=Friction, doc="Friction at the hub.")
    damping: Damping = setting(factory=Damping, doc="Damping of the beam's modes.")
    sensors: Sensors = setting(factory=Sensors, doc="The sensors.")
    timing: Timing = setting(factory=Timing, doc="Sample time and computation delay.")
    uncertainty: Uncertainty = setting(factory=Uncertainty, doc="What is not known: ranges on the physical "
                                       "parameters ([uncertainty]; empty: the rig is taken as exact).")

    def __post_init__(self):
        super().__post_init__()
        d, f = self.drive, self.friction
        if not d.is_ideal and d.eta_forward * d.N * d.k_torque * d.I_max < f.static:
            need = f.static / (d.eta_forward * d.N * d.k_torque)
            raise ParameterError(f"motor.I_max must be >= {need:.4g} [A] (eta_forward N eta_motor k_t I_max must "
                                 f"hold the hub against the breakaway friction {f.static:g} N m), got {d.I_max:g}")
        limit = d.torque_limit
        if limit is not None and not _close(self.beam.tau_max, limit):
            object.__setattr__(self, "beam", self.beam.replace(tau_max=limit))
        for k, x in enumerate(self.sensors.strain_gauges):
            if x > self.beam.L:
                raise ParameterError(f"sensors.strain_gauges[{k}] must be in [0, L] = [0, {self.beam.L:g}] [m] "
                                     f"(on the beam), got {x:g}")
        if self.damping.is_set and self.beam.damping_ratio > 0:
            raise ParameterError(f"beam.damping_ratio must be 0 when [damping] is given (one source of "
                                 f"damping), got {self.beam.damping_ratio:g}")
        if self.uncertainty.is_set:
            self.uncertainty.check(self.replace(uncertainty=Uncertainty()))

    @property
    def is_ideal(self) -> bool:
        """True when the hardware is ideal: torque drive, no friction, no extra damping, ideal
        sensors, no delay (the rig is then the beam alone)."""
        return (self.drive.is_ideal and self.friction.is_ideal and not self.damping.is_set
                and self.sensors.is_ideal and self.timing.is_ideal)

    @property
    def plant_params(self) -> Params:
        """The beam's :class:`Params` as the plant sees them: ``J_h`` plus the reflected rotor
        inertia ``N^2 J_r``, and the rig's damping as per-mode ratios of the transverse clamped
        modes (``damping_ratios``, all :data:`~hubbeam_ctrl.plant.params.MAX_MODES` of them, Rayleigh
        terms at each mode's frequency); the beam itself when there is neither."""
        changes = {}
        if self.drive.reflected_inertia:
            changes["J_h"] = self.beam.J_h + self.drive.reflected_inertia
        if self.damping.is_set:
            changes["damping_ratios"] = self.mode_damping()
        return self.beam.replace(**changes) if changes else self.beam

    def mode_damping(self, n: int = MAX_MODES) -> tuple:
        """Damping ratios of transverse clamped modes 1..n by :meth:`Damping.ratio` [-].

        Parameters
        ----------
        n : int
            Number of modes (default all the toolbox models, 20).

        Returns
        -------
        tuple of float
        """
        from hubbeam_ctrl.plant.basis import modal_basis
        b = modal_basis(self.beam.replace(n_transverse=n, damping_ratios=()))
        omega = np.sqrt(np.diag(b.K2)[:n] / np.diag(b.beam.M2)[:n])
        out = tuple(min(self.damping.ratio(i + 1, float(w)), 0.999) for i, w in enumerate(omega))
        return out

    def to_tables(self) -> dict:
        """The rig as the tables of a rig file: ``{"beam": {...}, "motor": {...}, ...}``."""
        out = {}
        for table in RIG_TABLES:
            part = getattr(self, _ATTR[table])
            out[table] = {f.name: getattr(part, f.name) for f in fields(part)}
        return out


def _close(tau_max: float, limit: float) -> bool:
    return abs(tau_max - limit) <= TAU_MAX_TOLERANCE * limit


def _check_tau_max(tau_max: float, drive: Drive) -> None:
    """Refuse a beam ``tau_max`` [N m] that conflicts with the drive's limit, in one line."""
    limit = drive.torque_limit
    if limit is None or _close(tau_max, limit):
        return
    whose = ("the DC motor's stall torque eta_forward N eta_motor k_t min(V_max / R, I_max)" if not drive.is_ideal
             else "the torque source's motor.tau_max")
    raise ParameterError(f"beam.tau_max must be within {100 * TAU_MAX_TOLERANCE:g} % of {limit:.4g} N m ({whose}; "
                         f"omit beam.tau_max to take it), got {tau_max:g}")


# the rig files (TOML): in their own module, re-exported here


def _part(table: str, data, path, what: str = "rig file") -> Settings:
    cls = RIG_TABLES[table]
    where = f"{what} {path}: " if path is not None else ""
    if not isinstance(data, dict):
        raise ParameterError(f"{where}[{table}] must be a table of keys, got {type(data).__name__}")
    if cls is Params:
        try:
            return Params.from_dict(data)
        except ParameterError as exc:
            raise ParameterError(f"{where}beam.{exc}" if str(exc).split(" ")[0] in data
                                 else f"{where}[beam]: {exc}") from None
    known = [f.name for f in fields(cls)]
    for key in data:
        if key not in known:
            raise ParameterError(f"{where}unknown key {table}.{str(key)[:40]}; allowed in [{table}]: "
                                 f"{', '.join(known)}")
    try:
        return cls(**data)
    except ParameterError as exc:
        raise ParameterError(f"{where}{exc}") from None
    except TypeError as exc:
        raise ParameterError(f"{where}[{table}]: {exc}") from None


def rig_from_dict(data: dict, path=None, what: str = "rig file") -> Rig:
    """A :class:`Rig` from the tables of a rig file (or a flat :class:`Params` mapping).

    Parameters
    ----------
    data : dict
        ``{"beam": {...}, "motor": {...}, ...}`` (:data:`RIG_TABLES`); a mapping without
        tables (or with ``[params]`` only) is a flat parameter set: the beam alone, ideal hardware.
    path : str or Path, optional
        The file it came from (named in error messages).
    what : str
        What the file is, as error messages start (``"rig file"``; ``"params file"`` for a
        parameter file read as a rig).

    Returns
    -------
    Rig
    """
    where = f"{what} {path}: " if path is not None else ""
    if not isinstance(data, dict):
        raise ParameterError(f"{where}a rig must be a mapping of tables, got {type(data).__name__}")
    if set(data) == {"params"} and isinstance(data["params"], dict):
        data = data["params"]
    if not any(isinstance(v, dict) for v in data.values()):      # today's flat Params file
        try:
            return Rig(beam=Params.from_dict(data))
        except ParameterError as exc:
            raise ParameterError(f"{where}{exc}") from None
    uncertainty = Uncertainty.from_table(data["uncertainty"], where) if "uncertainty" in data else Uncertainty()
    data = {k: v for k, v in data.items() if k != "uncertainty"}
    for key, value in data.items():
        if key not in RIG_TABLES:
            kind = "table" if isinstance(value, dict) else "key"
            shown = f"[{str(key)[:40]}]" if kind == "table" else str(key)[:40]
            raise ParameterError(f"{where}unknown {kind} {shown}; allowed tables: "
                                 f"{', '.join(f'[{t}]' for t in RIG_TABLES)}, [uncertainty]")
    parts = {_ATTR[t]: _part(t, data[t], path, what) for t in RIG_TABLES if t in data}
    try:
        drive = parts.get("drive", Drive())
        if "beam" in parts:           # beam.tau_max follows from the drive; a stated one must agree
            if "tau_max" in data["beam"]:
                _check_tau_max(parts["beam"].tau_max, drive)
            elif drive.torque_limit is not None:
                parts["beam"] = parts["beam"].replace(tau_max=drive.torque_limit)
        return Rig(**parts, uncertainty=uncertainty)
    except ParameterError as exc:
        raise ParameterError(f"{where}{exc}") from None


def _preset_path(name: str):
    return resources.files("hubbeam_ctrl").joinpath("data", "rigs", f"{name}.toml")


def load_rig(source, what: str = "rig") -> Rig:
    """Load a rig from a TOML file or a preset name.

    Parameters
    ----------
    source : str or Path
        A rig file (tables ``[beam]``, ``[motor]``, ``[friction]``, ``[damping]``,
        ``[sensors]``, ``[timing]``; or a flat parameter file: the beam alone), or the name
        of a preset (:data:`PRESETS`). An existing file wins over a preset of the same name.
    what : str
        The input's name as error messages start (``"rig"``: ``rig file x.toml does not
        exist``; the command line puts its option in front, ``--rig file ...``).

    Returns
    -------
    Rig

    Raises
    ------
    ParameterError
        One line naming the file and the table or key at fault.
    """
    if isinstance(source, Rig):
        return source
    if source is None or str(source).strip() == "":
        raise ParameterError(f"{what} must name a file or a preset ({', '.join(PRESETS)}), got {source!r}")
    path = Path(source)
    exists = path_exists(path)
    if not exists and str(source) in PRESETS:
        with resources.as_file(_preset_path(str(source))) as preset:
            return rig_from_dict(_read_toml(preset), path=f"(preset {source})")
    if not exists and path.suffix == "" and "/" not in str(source):
        raise ParameterError(f"{what} {str(source)[:80]!r} is neither a file nor a preset "
                             f"({', '.join(PRESETS)})")
    data = read_toml(path, f"{what} file", MAX_PARAMS_FILE_BYTES)
    return rig_from_dict(data, path=path, what=f"{what} file")


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, tuple):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    return repr(value)


def rig_to_toml(rig: Rig) -> str:
    """The TOML text of a rig file (units as comments; unset optional keys as comments).

    Parameters
    ----------
    rig : Rig

    Returns
    -------
    str
    """
    lines = ["# hubbeam-ctrl rig, SI units"]
    for table, values in rig.to_tables().items():
        units = RIG_TABLES[table].units()
        lines += ["", f"[{table}]"]
        for key, value in values.items():
            unit = units[key]
            if value is None:
                lines.append(f"# {key} unset")
                continue
            lines.append(f"{key} = {_toml_value(value)}" + ("" if unit in ("", "-") else f"  # [{unit}]"))
    if rig.uncertainty.is_set:
        lines += ["", "[uncertainty]"]
        for r in rig.uncertainty.ranges:
            lines.append(f"{r.name} = [{r.lo!r}, {r.hi!r}]" + ("" if r.unit == "-" else f"  # [{r.unit}]"))
    return "\n".join(lines) + "\n"


def save_rig(rig: Rig, path) -> None:
    """Write a rig to a TOML file atomically (:func:`load_rig` reads it back equal).

    Parameters
    ----------
    rig : Rig
        The rig: its beam and every hardware table.
    path : str or Path
        The TOML file (units as comments, as :func:`rig_to_toml` writes it).
    """
    if not isinstance(rig, Rig):
        raise ParameterError(f"rig must be a Rig, got {type(rig).__name__}")
    atomic_write_text(path, rig_to_toml(rig))
