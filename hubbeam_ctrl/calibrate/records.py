"""Measured (or simulated) records: the CSV and NPZ format, loaded and saved with validation.

A record is the toolbox's own result CSV: one header line of ``name [unit]`` columns, then
one row per sample. ``t [s]`` is required, and one input: ``tau [N m]`` (a torque, for the
ideal torque drive) or ``V [V]`` (the voltage of a DC-motor drive). The sensor columns are
any of :data:`SENSOR_COLUMNS` (``theta [rad]``, ``theta_dot [rad/s]``, ``v_tip [m]``,
``root_moment [N m]``, ``tip_accel [m/s^2]``); the other series a toolbox run saves
(:data:`hubbeam_ctrl.sim.results.CSV_COLUMNS`, e.g. ``u_tip`` or ``energy``) are accepted
and ignored, so a simulated run saved with ``Result.save("run.csv")`` is a valid record and
a measured one needs only a header. ``.npz`` records hold one array per column and a JSON
``metadata`` entry with the units (:func:`save_record` writes it).

:func:`load_record` refuses, in one line naming the file and the column: a header that is
not ``name [unit]``, an unknown column, a unit that is not the column's, a duplicate, a
missing ``t`` or input, a non-numeric cell, NaN or infinity, time that does not increase,
fewer than :data:`MIN_SAMPLES` rows. Time may be non-uniform (:attr:`Record.is_uniform`;
:meth:`Record.resampled` puts it on a uniform grid).

Examples
--------
>>> import numpy as np
>>> rec = Record(t=np.arange(10) * 1e-3, columns={"V": np.ones(10), "theta": np.zeros(10)})
>>> rec.input_name, rec.sensors, round(rec.dt, 6)
('V', ('theta',), 0.001)
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.fileio import atomic_write
from hubbeam_ctrl.core.npz import read_npz, write_npz
from hubbeam_ctrl.core.reading import check_regular_file
from hubbeam_ctrl.sim.results import CSV_COLUMNS

__all__ = ["Record", "load_record", "save_record", "INPUT_COLUMNS", "SENSOR_COLUMNS", "RECORD_COLUMNS",
           "MIN_SAMPLES", "record_from_result"]

#: The input columns: name -> unit (one of them is required).
INPUT_COLUMNS = {"tau": "N m", "V": "V"}
#: The sensor columns a fit can use: name -> (unit, meaning).
SENSOR_COLUMNS = {"theta": ("rad", "hub angle (encoder)"),
                  "theta_dot": ("rad/s", "hub rate"),
                  "v_tip": ("m", "transverse tip deflection in the hub frame"),
                  "root_moment": ("N m", "bending moment at the beam root (strain gauge)"),
                  "tip_accel": ("m/s^2", "in-plane tip acceleration (accelerometer)")}
#: Every column a record may hold: name -> unit (the toolbox's result series included).
RECORD_COLUMNS = {"t": "s", **INPUT_COLUMNS, **{k: v[0] for k, v in SENSOR_COLUMNS.items()},
                  **{k: v for k, v in CSV_COLUMNS.items() if k not in ("t", "tau")}}
#: Fewest samples a record may have.
MIN_SAMPLES = 8
_HEADER_ITEM = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*\[([^\]]*)\]\s*$")


def _where(source) -> str:
    return f"record {source}: " if source else "record: "


@dataclass(frozen=True)
class Record:
    """One record: sample times, the input and the sensors (see the module docstring).

    Parameters
    ----------
    t : ndarray (N,)
        Sample times [s], strictly increasing.
    columns : dict
        Name -> ndarray (N,) for every other column, in :data:`RECORD_COLUMNS` units.
    source : str
        Where it came from (named in messages and reports).
    units : dict
        Filled in: column name -> unit (:data:`RECORD_COLUMNS`); what is passed is ignored.
    """

    t: np.ndarray
    columns: dict
    source: str = ""
    units: dict = field(default_factory=dict)

    def __post_init__(self):
        where = _where(self.source)
        t = np.asarray(self.t, dtype=float)
        if t.ndim != 1 or t.size < MIN_SAMPLES:
            raise ParameterError(f"{where}needs at least {MIN_SAMPLES} samples, got {t.size}")
        cols = {}
        for name, values in self.columns.items():
            if name == "t" or name not in RECORD_COLUMNS:
                raise ParameterError(f"{where}unknown column {str(name)[:40]!r}; allowed: "
                                     f"{', '.join(k for k in RECORD_COLUMNS if k != 't')}")
            a = np.asarray(values, dtype=float)
            if a.shape != t.shape:
                raise ParameterError(f"{where}column {name} has {a.size} values for {t.size} times")
            cols[name] = a
        for name, a in [("t", t), *cols.items()]:
            bad = ~np.isfinite(a)
            if bad.any():
                k = int(np.argmax(bad))
                what = "NaN" if np.isnan(a[k]) else "infinity"
                at = "" if name == "t" else f" (t = {t[k]:.6g} s)"
                raise ParameterError(f"{where}column {name} has {what} at row {k + 1}{at}"
                                     + (f", and {int(bad.sum()) - 1} more" if bad.sum() > 1 else ""))
        steps = np.diff(t)
        if np.any(steps <= 0):
            k = int(np.argmax(steps <= 0))
            raise ParameterError(f"{where}time must increase strictly: t [s] goes from {t[k]:.9g} to "
                                 f"{t[k + 1]:.9g} at row {k + 2}")
        inputs = [k for k in INPUT_COLUMNS if k in cols]
        if len(inputs) != 1:
            raise ParameterError(f"{where}needs exactly one input column, tau [N m] (torque) or V [V] "
                                 f"(DC-motor voltage), got {', '.join(inputs) or 'none'}")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "columns", cols)
        object.__setattr__(self, "units", {"t": "s", **{k: RECORD_COLUMNS[k] for k in cols}})

    # -- views -------------------------------------------------------------------
    @property
    def input_name(self) -> str:
        """``"tau"`` (torque [N m]) or ``"V"`` (voltage [V])."""
        return next(k for k in INPUT_COLUMNS if k in self.columns)

    @property
    def input(self) -> np.ndarray:
        """The input series [N m or V]."""
        return self.columns[self.input_name]

    @property
    def sensors(self) -> tuple:
        """The sensor columns it holds, in :data:`SENSOR_COLUMNS` order."""
        return tuple(k for k in SENSOR_COLUMNS if k in self.columns)

    @property
    def duration(self) -> float:
        """``t[-1] - t[0]`` [s]."""
        return float(self.t[-1] - self.t[0])

    @property
    def dt(self) -> float:
        """Median sample period [s]."""
        return float(np.median(np.diff(self.t)))

    @property
    def is_uniform(self) -> bool:
        """True when every sample period is within 1e-6 relative of the median."""
        d = np.diff(self.t)
        return bool(np.all(np.abs(d - self.dt) <= 1e-6 * self.dt))

    def resampled(self, dt: float | None = None) -> "Record":
        """The record on a uniform grid from its first time (linear interpolation).

        Parameters
        ----------
        dt : float, optional
            Sample period [s] (default the median period).

        Returns
        -------
        Record
        """
        dt = self.dt if dt is None else float(dt)
        if not (math.isfinite(dt) and dt > 0):
            raise ParameterError(f"dt must be > 0 [s], got {dt!r}")
        if self.is_uniform and abs(dt - self.dt) <= 1e-9 * dt:
            return self
        n = int(math.floor(self.duration / dt * (1 + 1e-12))) + 1
        t = self.t[0] + dt * np.arange(n)
        cols = {k: np.interp(t, self.t, v) for k, v in self.columns.items()}
        return Record(t=t, columns=cols, source=self.source)

    def window(self, t_start: float, t_stop: float | None = None) -> "Record":
        """The samples with ``t_start <= t <= t_stop`` [s], time kept.

        Parameters
        ----------
        t_start : float
            [s]
        t_stop : float, optional
            [s]; default the end.

        Returns
        -------
        Record
        """
        stop = self.t[-1] if t_stop is None else t_stop
        keep = (self.t >= t_start - 1e-12) & (self.t <= stop + 1e-12)
        return Record(t=self.t[keep], columns={k: v[keep] for k, v in self.columns.items()}, source=self.source)

    def check_input_varies(self) -> None:
        """Raise when the input is constant (nothing to identify from)."""
        u = self.input
        if float(np.ptp(u)) <= 1e-12 * max(1.0, float(np.max(np.abs(u)))):
            raise ParameterError(f"{_where(self.source)}the input {self.input_name} "
                                 f"[{INPUT_COLUMNS[self.input_name]}] is constant ({u[0]:g}): it excites "
                                 f"nothing; give an excitation (hubbeam excite)")


def record_from_result(result, command: str = "torque") -> Record:
    """A :class:`Record` of a simulated run (:class:`~hubbeam_ctrl.sim.results.Result`).

    Parameters
    ----------
    result : Result
    command : {"torque", "voltage"}
        What the run's ``tau`` series holds: a torque [N m] or, for a DC-motor rig, the
        voltage command [V] (``simulate_fixed_step(..., hardware=)`` stores the command).

    Returns
    -------
    Record
    """
    if command not in ("torque", "voltage"):
        raise ParameterError(f"command must be 'torque' or 'voltage', got {command!r}")
    cols = {k: v for k, v in result.columns().items() if k != "t"}
    if command == "voltage":
        cols["V"] = cols.pop("tau")
    return Record(t=result.t, columns=cols, source=f"{result.kind} run")


def _parse_header(line: str, where: str) -> list:
    names = []
    for item in line.strip().split(","):
        m = _HEADER_ITEM.match(item)
        if not m:
            raise ParameterError(f"{where}header item {item.strip()[:40]!r} is not 'name [unit]' "
                                 "(e.g. t [s],V [V],theta [rad])")
        name, unit = m.group(1), " ".join(m.group(2).split())
        if name not in RECORD_COLUMNS:
            raise ParameterError(f"{where}unknown column {name!r}; allowed: "
                                 f"{', '.join(RECORD_COLUMNS)}")
        if unit != RECORD_COLUMNS[name]:
            raise ParameterError(f"{where}column {name} must be in [{RECORD_COLUMNS[name]}], got [{unit}]")
        if name in names:
            raise ParameterError(f"{where}column {name} appears twice")
        names.append(name)
    if "t" not in names:
        raise ParameterError(f"{where}needs a time column t [s]")
    return names


def load_record(path) -> Record:
    """Load and validate a record (``.csv`` or ``.npz``; see the module docstring).

    Parameters
    ----------
    path : str or Path
        The record file; a missing, unreadable or invalid one is one line of
        :class:`ParameterError` naming it.

    Returns
    -------
    Record

    Raises
    ------
    ParameterError
        One line naming the file and what is wrong.
    """
    path = check_regular_file(path, "record")
    where = _where(path)
    suffix = path.suffix.lower()
    if suffix == ".npz":
        arrays, meta = read_npz(path, "record", "hubbeam record")
        units = meta.get("units", {}) if isinstance(meta.get("units", {}), dict) else {}
        for name in arrays:
            if name not in RECORD_COLUMNS:
                raise ParameterError(f"{where}unknown column {name!r}; allowed: {', '.join(RECORD_COLUMNS)}")
            if name in units and units[name] != RECORD_COLUMNS[name]:
                raise ParameterError(f"{where}column {name} must be in [{RECORD_COLUMNS[name]}], "
                                     f"got [{units[name]}]")
            if arrays[name].ndim != 1:
                raise ParameterError(f"{where}column {name} must be 1-D, got shape {arrays[name].shape}")
        if "t" not in arrays:
            raise ParameterError(f"{where}needs a time column t [s]")
        cols = {k: v for k, v in arrays.items() if k != "t"}
        return Record(t=arrays["t"], columns=cols, source=str(path))
    if suffix != ".csv":
        raise ParameterError(f"{where}unknown extension {suffix!r}; allowed: .csv, .npz")
    try:
        with open(path, encoding="utf-8") as fh:
            header = fh.readline()
            lines = fh.read().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise ParameterError(f"{where}cannot be read ({getattr(exc, 'strerror', None) or exc})") from None
    names = _parse_header(header, where)
    rows = []
    for k, line in enumerate(lines):
        if not line.strip():
            continue
        cells = line.split(",")
        if len(cells) != len(names):
            raise ParameterError(f"{where}row {k + 2} has {len(cells)} values for {len(names)} columns")
        try:
            rows.append([float(c) for c in cells])
        except ValueError:
            bad = next(c for c in cells if not _is_float(c))
            raise ParameterError(f"{where}row {k + 2}: {bad.strip()[:30]!r} is not a number") from None
    data = np.array(rows, dtype=float).reshape(-1, len(names))
    cols = {n: data[:, j] for j, n in enumerate(names)}
    t = cols.pop("t")
    return Record(t=t, columns=cols, source=str(path))


def _is_float(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


def save_record(record: Record, path) -> Path:
    """Write a record atomically as ``.csv`` (header ``name [unit]``) or ``.npz``.

    Parameters
    ----------
    record : Record
        The record (validated when it was made).
    path : str or Path
        A ``.csv`` or ``.npz`` file name; the extension picks the format.

    Returns
    -------
    Path
    """
    if not isinstance(record, Record):
        raise ParameterError(f"record must be a Record, got {type(record).__name__}")
    path = Path(path)
    names = ["t"] + [k for k in RECORD_COLUMNS if k in record.columns]
    arrays = {"t": record.t, **{k: record.columns[k] for k in names[1:]}}
    suffix = path.suffix.lower()
    if suffix == ".npz":
        return write_npz(path, arrays, {"format": "hubbeam-record", "version": 1,
                                        "units": {k: RECORD_COLUMNS[k] for k in names}})
    if suffix != ".csv":
        raise ParameterError(f"out: unknown extension {suffix!r}; allowed: .csv, .npz")
    header = ",".join(f"{k} [{RECORD_COLUMNS[k]}]" for k in names)
    data = np.column_stack([arrays[k] for k in names])

    def write(tmp):
        with open(tmp, "w", encoding="utf-8") as fh:
            np.savetxt(fh, data, delimiter=",", header=header, comments="", fmt="%.17g")
    return atomic_write(path, write)
