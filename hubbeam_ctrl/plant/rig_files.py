"""Rig files: a :class:`~hubbeam_ctrl.plant.rig.Rig` from and to TOML, and the presets.

One TOML file holds a rig, one table per part (``[beam]``, ``[motor]``, ``[friction]``,
``[damping]``, ``[sensors]``, ``[timing]``; :data:`~hubbeam_ctrl.plant.rig.RIG_TABLES`); a flat
parameter file is the beam alone. Bad input is one line naming the file and the key as written
in it. :mod:`hubbeam_ctrl.plant.rig` re-exports these functions.
"""

from __future__ import annotations

from dataclasses import fields
from importlib import resources
from pathlib import Path

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.fileio import atomic_write_text
from hubbeam_ctrl.core.settings import Settings
from hubbeam_ctrl.plant.params import Params, _read_toml
from hubbeam_ctrl.plant.rig import _ATTR, PRESETS, RIG_TABLES, Drive, Rig, _check_tau_max

__all__ = ["load_rig", "save_rig", "rig_from_dict", "rig_to_toml"]


def _part(table: str, data, path) -> Settings:
    cls = RIG_TABLES[table]
    where = f"rig file {path}: " if path is not None else ""
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


def rig_from_dict(data: dict, path=None) -> Rig:
    """A :class:`Rig` from the tables of a rig file (or a flat :class:`Params` mapping).

    Parameters
    ----------
    data : dict
        ``{"beam": {...}, "motor": {...}, ...}`` (:data:`RIG_TABLES`); a mapping without
        tables (or with ``[params]`` only) is a flat parameter set: the beam alone, ideal hardware.
    path : str or Path, optional
        The file it came from (named in error messages).

    Returns
    -------
    Rig
    """
    where = f"rig file {path}: " if path is not None else ""
    if not isinstance(data, dict):
        raise ParameterError(f"{where}a rig must be a mapping of tables, got {type(data).__name__}")
    if set(data) == {"params"} and isinstance(data["params"], dict):
        data = data["params"]
    if not any(isinstance(v, dict) for v in data.values()):      # today's flat Params file
        try:
            return Rig(beam=Params.from_dict(data))
        except ParameterError as exc:
            raise ParameterError(f"{where}{exc}") from None
    for key, value in data.items():
        if key not in RIG_TABLES:
            kind = "table" if isinstance(value, dict) else "key"
            shown = f"[{str(key)[:40]}]" if kind == "table" else str(key)[:40]
            raise ParameterError(f"{where}unknown {kind} {shown}; allowed tables: "
                                 f"{', '.join(f'[{t}]' for t in RIG_TABLES)}")
    parts = {_ATTR[t]: _part(t, data[t], path) for t in RIG_TABLES if t in data}
    try:
        drive = parts.get("drive", Drive())
        if "beam" in parts:           # beam.tau_max follows from the drive; a stated one must agree
            if "tau_max" in data["beam"]:
                _check_tau_max(parts["beam"].tau_max, drive)
            elif drive.torque_limit is not None:
                parts["beam"] = parts["beam"].replace(tau_max=drive.torque_limit)
        return Rig(**parts)
    except ParameterError as exc:
        raise ParameterError(f"{where}{exc}") from None


def _preset_path(name: str):
    return resources.files("hubbeam_ctrl").joinpath("data", "rigs", f"{name}.toml")


def load_rig(source) -> Rig:
    """Load a rig from a TOML file or a preset name.

    Parameters
    ----------
    source : str or Path
        A rig file (tables ``[beam]``, ``[motor]``, ``[friction]``, ``[damping]``,
        ``[sensors]``, ``[timing]``; or a flat parameter file: the beam alone), or the name
        of a preset (:data:`PRESETS`). An existing file wins over a preset of the same name.

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
        raise ParameterError(f"rig must name a file or a preset ({', '.join(PRESETS)}), got {source!r}")
    path = Path(source)
    if not path.exists() and str(source) in PRESETS:
        with resources.as_file(_preset_path(str(source))) as preset:
            return rig_from_dict(_read_toml(preset), path=f"(preset {source})")
    if not path.exists() and path.suffix == "" and "/" not in str(source):
        raise ParameterError(f"rig {str(source)[:80]!r} is neither a file nor a preset "
                             f"({', '.join(PRESETS)})")
    data = _read_toml(path)
    return rig_from_dict(data, path=path)


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
    return "\n".join(lines) + "\n"


def save_rig(rig: Rig, path) -> None:
    """Write a rig to a TOML file atomically (:func:`load_rig` reads it back equal).

    Parameters
    ----------
    rig : Rig
    path : str or Path
    """
    if not isinstance(rig, Rig):
        raise ParameterError(f"rig must be a Rig, got {type(rig).__name__}")
    atomic_write_text(path, rig_to_toml(rig))
