"""Fit of rig fields to a modal table: measured frequencies and damping ratios against spin rate and tip mass.

:func:`fit_modal_table` uses the least squares and diagnostics of
:mod:`hubbeam_ctrl.calibrate.fit` with residuals from FOAM modal analysis.
"""

from __future__ import annotations

import math
import re
import time
from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.calibrate.fit import FitResult, FitSettings, resolve_fields, set_fields
from hubbeam_ctrl.calibrate.solver import _bounds, _diagnose, _least_squares, _scales
from hubbeam_ctrl.core.errors import HubbeamError, ParameterError
from hubbeam_ctrl.plant.modal import modal_analysis
from hubbeam_ctrl.plant.rig import Rig

__all__ = ["ModalTable", "load_modal_table", "fit_modal_table", "MODAL_TABLE_COLUMNS"]


#: Largest modal table read [bytes].
MAX_TABLE_BYTES = 1_000_000

#: Columns of a modal table: name -> unit.
MODAL_TABLE_COLUMNS = {"spin": "rad/s", "m_t": "kg", "mode": "-", "frequency": "Hz", "damping": "-"}


@dataclass(frozen=True)
class ModalTable:
    """Measured bending frequencies (and damping ratios) against spin rate and tip mass.

    Parameters
    ----------
    spin : ndarray (K,)
        Steady spin rate of each row [rad/s].
    m_t : ndarray (K,)
        Tip mass of each row [kg] (NaN: the rig's).
    mode : ndarray of int (K,)
        1-based bending mode.
    frequency : ndarray (K,)
        Measured frequency [Hz], > 0.
    damping : ndarray (K,)
        Measured damping ratio [-] (NaN: not measured).
    """

    spin: np.ndarray
    m_t: np.ndarray
    mode: np.ndarray
    frequency: np.ndarray
    damping: np.ndarray

    def __post_init__(self):
        n = len(np.atleast_1d(self.frequency))
        for name in MODAL_TABLE_COLUMNS:
            a = np.atleast_1d(np.asarray(getattr(self, name), dtype=float))
            if a.shape != (n,):
                raise ParameterError(f"modal table: column {name} has {a.size} values for {n} rows")
            object.__setattr__(self, name, a)
        if n == 0:
            raise ParameterError("modal table: needs at least one row")
        if not np.all(np.isfinite(self.frequency)) or np.any(self.frequency <= 0):
            raise ParameterError("modal table: frequency [Hz] must be finite and > 0 in every row")
        if not np.all(np.isfinite(self.spin)):
            raise ParameterError("modal table: spin [rad/s] must be finite in every row")
        if np.any(self.mode < 1) or np.any(self.mode != np.round(self.mode)):
            raise ParameterError("modal table: mode must be an integer >= 1 in every row")
        object.__setattr__(self, "mode", self.mode.astype(int))


def load_modal_table(path, what: str = "modal table") -> ModalTable:
    """Read a modal table CSV (header ``spin [rad/s],m_t [kg],mode [-],frequency [Hz],damping [-]``;
    ``m_t`` and ``damping`` optional; at most :data:`MAX_TABLE_BYTES`).

    Parameters
    ----------
    path : str or Path
    what : str
        The table as the caller names it (``"--modal-table file"``), starting every refusal.

    Returns
    -------
    ModalTable
    """
    from hubbeam_ctrl.core.reading import read_text
    header, _, body = read_text(path, what, MAX_TABLE_BYTES).partition("\n")
    where = f"{what} {path}"
    names = []
    for item in header.strip().split(","):
        m = re.match(r"^\s*(\w+)\s*\[([^\]]*)\]\s*$", item)
        if not m or m.group(1) not in MODAL_TABLE_COLUMNS or m.group(2).strip() != MODAL_TABLE_COLUMNS[m.group(1)]:
            raise ParameterError(f"{where}: header item {item.strip()[:40]!r} is not one of "
                                 + ", ".join(f"{k} [{u}]" for k, u in MODAL_TABLE_COLUMNS.items()))
        names.append(m.group(1))
    for need in ("spin", "mode", "frequency"):
        if need not in names:
            raise ParameterError(f"{where}: needs a column {need} [{MODAL_TABLE_COLUMNS[need]}]")
    rows = [line.split(",") for line in body.splitlines() if line.strip()]
    for i, row in enumerate(rows):
        if len(row) != len(names):
            raise ParameterError(f"{where}: row {i + 2} has {len(row)} cells for {len(names)} columns")
    try:
        data = np.array([[float(c) for c in row] for row in rows], dtype=float).reshape(-1, len(names))
    except ValueError:
        raise ParameterError(f"{where}: a cell is not a number") from None
    cols = {n: data[:, j] for j, n in enumerate(names)}
    k = len(data)
    try:
        return ModalTable(spin=cols["spin"], m_t=cols.get("m_t", np.full(k, np.nan)), mode=cols["mode"],
                          frequency=cols["frequency"], damping=cols.get("damping", np.full(k, np.nan)))
    except ParameterError as exc:                  # "modal table: ..." -> the table as the caller named it
        raise ParameterError(f"{where}{str(exc).removeprefix('modal table')}") from None


def _modal_predict(rig, table, n_modes, hub):
    f_out = np.empty(len(table.frequency))
    z_out = np.empty(len(table.frequency))
    keys = {}
    for k, (w, mt) in enumerate(zip(table.spin, table.m_t)):
        keys.setdefault((float(w), float(mt)), []).append(k)
    for (w, mt), rows in keys.items():
        p = rig.plant_params.replace(n_transverse=n_modes, n_axial=2)
        if not math.isnan(mt):
            p = p.replace(m_t=mt)
        r = modal_analysis("foam", w, hub, p)
        for k in rows:
            f_out[k] = r.bending_hz[table.mode[k] - 1]
            z_out[k] = r.damping_ratios[table.mode[k] - 1]
    return f_out, z_out


def fit_modal_table(rig: Rig, table: ModalTable, fit, *, bounds=None, hub: str = "prescribed",
                    settings: FitSettings | None = None, progress: bool = True) -> FitResult:
    """Fit rig fields to measured frequencies and damping ratios by modal analysis (FOAM).

    The residuals are the relative frequency errors ``f_model / f - 1`` and, where measured,
    the damping errors ``(zeta_model - zeta) / zeta``.

    Parameters
    ----------
    rig : Rig
    table : ModalTable
    fit : str or sequence of str
    bounds : dict, optional
    hub : {"prescribed", "free"}
        Whether the measured modes are those of the held hub (clamped root turning at the
        spin rate) or of the free hub.
    settings : FitSettings, optional
    progress : bool

    Returns
    -------
    FitResult
        ``fit`` holds the frequency (and damping) fit per mode as percentages of agreement.
    """
    settings = settings or FitSettings()
    fit_fields = resolve_fields(fit, rig)
    if hub not in ("prescribed", "free"):
        raise ParameterError(f"hub must be 'prescribed' or 'free', got {hub!r}")
    n_modes = int(min(20, table.mode.max() + 3))
    start = np.array([f.get(rig) for f in fit_fields])
    lo, hi = _bounds(fit_fields, bounds, start)
    scale = _scales(fit_fields, start, rig)
    has_z = np.isfinite(table.damping) & (table.damping > 0)
    m = len(table.frequency) + int(has_z.sum())
    if m < len(fit_fields):
        raise ParameterError(f"modal table: {m} measured values cannot determine {len(fit_fields)} fields")

    def residual_of(x):
        try:
            f, z = _modal_predict(set_fields(rig, fit_fields, x * scale), table, n_modes, hub)
        except (HubbeamError, ParameterError, IndexError):
            return np.full(m, 10.0)
        return np.concatenate([f / table.frequency - 1.0, (z[has_z] - table.damping[has_z]) / table.damping[has_z]])

    t0 = time.perf_counter()
    sol = _least_squares(residual_of, start / scale, lo / scale, hi / scale, len(fit_fields), settings,
                         "modal fit", progress)
    estimate = sol.x * scale
    converged = bool(sol.status > 0)
    message = sol.message if converged else f"did not converge ({sol.message}); the last estimate is kept"
    calibrated = set_fields(rig, fit_fields, estimate)
    std, corr, warnings = _diagnose(sol.jac, scale, estimate, sol.fun, fit_fields)
    f, z = _modal_predict(calibrated, table, n_modes, hub)
    err = {f"mode {k} frequency error [%]": float(np.max(np.abs(f[table.mode == k] / table.frequency[table.mode == k]
                                                                 - 1)) * 100) for k in np.unique(table.mode)}
    worst = max(err.values())
    if worst > 1.0:
        warnings.append(f"the fitted model misses a measured frequency by {worst:.2f} % (more than 1 %): a field "
                        "that should be fitted (e.g. damping, when damping ratios are in the table) or a model "
                        "that lacks something; do not trust the estimate")
    if has_z.any():
        z_err = float(np.max(np.abs(z[has_z] / table.damping[has_z] - 1))) * 100
        err["damping error [%]"] = z_err
        if z_err > 20.0:
            warnings.append(f"the fitted model misses a measured damping ratio by {z_err:.0f} % (more than 20 %)")
    return FitResult(fit_fields, start, estimate, std, corr, converged, message, int(sol.nfev),
                     {"modal table": err}, warnings, calibrated, time.perf_counter() - t0, kind="modal_table")
