"""Physical-parameter fitting: rig fields by least squares against records or a modal table.

:func:`fit_rig` adjusts the chosen fields of a :class:`~hubbeam_ctrl.plant.rig.Rig` (beam,
drive, friction, damping: :func:`resolve_fields`) so that the sensors simulated on the
nonlinear plant with the rig's hardware (:func:`~hubbeam_ctrl.calibrate.model.simulate_sensors`)
match the measured ones of one or more records. The residual of sensor ``s`` of a record is
``(y_model - y) / (||y - mean(y)|| )``, so that each sensor of each record weighs the same
whatever its unit, and ``1 - ||residual||`` is the fit fraction
(:func:`fit_percent`). The least-squares problem is solved by SciPy's trust-region
reflective method within the fields' ranges (and the caller's bounds) on scaled variables
(each value divided by its start, or a typical value when it starts at 0).

The Jacobian is by forward differences of whole simulations: the compiled CasADi step takes
the model's parameters as an input, so a simulation with other values costs no rebuild,
but the hardware's Karnopp sticking switches the equations between samples, which a
sensitivity of the step through the switch would miss (``docs/calibration.md``).

At the solution, the Jacobian gives the covariance ``s^2 (J' J)^-1`` (``s^2`` the residual
variance), the 95 % intervals and the correlations; a parameter is reported not identifiable
when it has no effect on the sensors, when the scaled Jacobian is nearly rank-deficient
(condition number above :data:`IDENTIFIABILITY_CONDITION`; the parameters of the weakest
direction are named) or when its interval is wider than half its value. A fit that reaches
its evaluation limit keeps the last estimate and says it did not converge
(:attr:`FitResult.converged`).

:func:`fit_modal_table` fits the same fields to measured frequencies and damping ratios
against spin rate and tip mass (:class:`ModalTable`), by modal analysis.
"""

from __future__ import annotations

import math
import re
import time
from dataclasses import dataclass, field, fields

import numpy as np

from hubbeam_ctrl.calibrate.model import ModelSettings, _check_sensors, rig_sensors, simulate_sensors
from hubbeam_ctrl.calibrate.records import Record
from hubbeam_ctrl.core.errors import HubbeamError, ParameterError
from hubbeam_ctrl.core.progress import progress_bar
from hubbeam_ctrl.plant.modal import modal_analysis
from hubbeam_ctrl.plant.rig import RIG_TABLES, Rig

__all__ = ["FitField", "FitSettings", "FitResult", "resolve_fields", "set_fields", "fit_rig", "fit_percent",
           "predict", "validate_record", "ModalTable", "load_modal_table", "fit_modal_table", "FIT_ALIASES",
           "IDENTIFIABILITY_CONDITION", "check_record_for_rig", "check_bounds", "MODAL_TABLE_COLUMNS"]

#: Short names of ``--fit``: name -> (table, key, index or None).
FIT_ALIASES = {"damping": ("damping", "ratios", 0), "friction": ("friction", "coulomb", None),
               "coulomb": ("friction", "coulomb", None), "viscous": ("friction", "viscous", None)}
#: Condition number of the column-scaled Jacobian above which the fit warns that its
#: parameters are not separately identifiable.
IDENTIFIABILITY_CONDITION = 1e4
_ATTR = {"beam": "beam", "motor": "drive", "friction": "friction", "damping": "damping", "sensors": "sensors",
         "timing": "timing"}
_FITTABLE_TABLES = ("beam", "motor", "friction", "damping")
_NAME = re.compile(r"^(?:(beam|motor|friction|damping)\.)?([A-Za-z_][A-Za-z0-9_]*)(?:\[(\d+)\])?$")


@dataclass(frozen=True)
class FitField:
    """One fitted rig field.

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


def set_fields(rig: Rig, fit_fields, values) -> Rig:
    """A copy of ``rig`` with the fields set to ``values`` (validated as a rig).

    Parameters
    ----------
    rig : Rig
    fit_fields : sequence of FitField
    values : sequence of float

    Returns
    -------
    Rig
    """
    changes: dict = {}
    for f, v in zip(fit_fields, values):
        part = changes.setdefault(f.table, {})
        if f.index is None:
            part[f.key] = float(v)
        else:
            ratios = list(part.get("ratios", rig.damping.ratios) or [rig.beam.damping_ratio])
            while len(ratios) <= f.index:
                ratios.append(ratios[-1])
            ratios[f.index] = float(v)
            part["ratios"] = tuple(ratios)
    parts = {_ATTR[t]: getattr(rig, _ATTR[t]).replace(**c) for t, c in changes.items()}
    if "damping" in changes and rig.beam.damping_ratio > 0:
        parts["beam"] = parts.get("beam", rig.beam).replace(damping_ratio=0.0)
    return rig.replace(**parts)


def fit_percent(y, y_model) -> float:
    """``100 (1 - ||y - y_model|| / ||y - mean(y)||)`` [%] (100: exact; 0: no better than the mean).

    Parameters
    ----------
    y, y_model : array_like (N,)

    Returns
    -------
    float
    """
    y, y_model = np.asarray(y, dtype=float), np.asarray(y_model, dtype=float)
    spread = float(np.linalg.norm(y - y.mean()))
    if spread == 0.0:
        return math.nan
    return 100.0 * (1.0 - float(np.linalg.norm(y - y_model)) / spread)


@dataclass(frozen=True)
class FitSettings:
    """Settings of :func:`fit_rig`.

    Attributes
    ----------
    model : ModelSettings
        The simulated plant.
    max_evaluations : int
        Most residual evaluations of the optimiser (each a simulation of every record; the
        Jacobian adds one per parameter).
    tolerance : float
        Relative change of cost, step and gradient that stops the optimiser [-].
    difference_step : float
        Relative difference step of the Jacobian [-].
    central : bool
        Central differences (twice the simulations; less sensitive to the switches of
        stick-slip friction) instead of forward differences.
    horizon_periods : tuple of float
        The fit runs in stages: first on the records cut to these many periods of the first
        clamped mode (of the start), each stage from the last one's estimate, then on the
        whole records. A long record with a wrong stiffness puts the model's oscillation out
        of phase with the measured one (a local minimum of output error); short horizons
        first avoid it. Empty: the whole records at once.
    restarts : int
        Restarts of the whole-record fit from its own estimate (a fresh trust region: the
        stick-slip friction makes the cost rough, and the first run can stop short); a
        restart that does not lower the cost ends them.
    warn_fit_percent : float
        A record's sensor fitted worse than this [%] gives a warning.
    """

    model: ModelSettings = field(default_factory=ModelSettings)
    max_evaluations: int = 60
    tolerance: float = 1e-8
    difference_step: float = 1e-4
    central: bool = False
    horizon_periods: tuple = (4.0, 12.0)
    restarts: int = 1
    warn_fit_percent: float = 90.0

    def __post_init__(self):
        if not isinstance(self.max_evaluations, int) or not 1 <= self.max_evaluations <= 10000:
            raise ParameterError(f"max_evaluations must be an integer in 1..10000, got {self.max_evaluations!r}")
        if not isinstance(self.restarts, int) or not 0 <= self.restarts <= 10:
            raise ParameterError(f"restarts must be an integer in 0..10, got {self.restarts!r}")
        hp = self.horizon_periods
        if not isinstance(hp, tuple) or not all(isinstance(h, (int, float)) and 0.5 <= h <= 1e4 for h in hp):
            raise ParameterError(f"horizon_periods must be a tuple of numbers in [0.5, 10000], got {hp!r}")
        for name, lo, hi in (("tolerance", 1e-15, 0.1), ("difference_step", 1e-10, 0.1),
                             ("warn_fit_percent", -1e9, 100.0)):
            v = getattr(self, name)
            if not isinstance(v, (int, float)) or not lo <= v <= hi:
                raise ParameterError(f"{name} must be in [{lo:g}, {hi:g}], got {v!r}")


@dataclass
class FitResult:
    """What :func:`fit_rig` (or :func:`fit_modal_table`) found.

    Attributes
    ----------
    fields : list of FitField
    start, estimate, std : ndarray
        Start, estimate and standard deviation of each field [its unit].
    correlation : ndarray (p, p)
    converged : bool
    message : str
        The optimiser's reason to stop (and "did not converge" when it did not).
    evaluations : int
        Residual evaluations (simulations of every record), Jacobians not counted.
    fit : dict
        Record source -> sensor -> fit [%] with the estimate.
    warnings : list of str
        Identifiability and convergence warnings.
    rig : Rig
        The calibrated rig (the estimate).
    wall_s : float
        Wall time of the fit [s].
    kind : str
        ``"records"`` or ``"modal_table"``.
    """

    fields: list
    start: np.ndarray
    estimate: np.ndarray
    std: np.ndarray
    correlation: np.ndarray
    converged: bool
    message: str
    evaluations: int
    fit: dict
    warnings: list
    rig: Rig
    wall_s: float
    kind: str = "records"

    @property
    def names(self) -> list:
        """The fitted names as given."""
        return [f.name for f in self.fields]

    @property
    def interval(self) -> np.ndarray:
        """95 % confidence intervals ``(p, 2)`` [unit of each field]."""
        return np.column_stack([self.estimate - 1.96 * self.std, self.estimate + 1.96 * self.std])

    def to_dict(self) -> dict:
        """JSON-ready summary: each field's estimate, interval and start by its name."""
        ci = self.interval
        return {"kind": self.kind, "converged": self.converged, "message": self.message,
                "evaluations": self.evaluations, "wall_s": self.wall_s,
                "estimates": {f.name: {"field": f.path, "unit": f.unit, "start": float(s), "estimate": float(e),
                                       "std": float(sd), "ci95": [float(lo), float(hi)]}
                              for f, s, e, sd, (lo, hi) in zip(self.fields, self.start, self.estimate, self.std, ci)},
                "correlation": {"names": self.names, "matrix": np.round(self.correlation, 6).tolist()},
                "fit_percent": self.fit, "warnings": list(self.warnings)}

    def summary(self) -> str:
        """Human-readable lines: estimates with intervals, fit per record and sensor, warnings."""
        lines = [f"fit {'converged' if self.converged else 'DID NOT CONVERGE'}: {self.message} "
                 f"({self.evaluations} evaluations, {self.wall_s:.1f} s)"]
        for f, s, e, (lo, hi) in zip(self.fields, self.start, self.estimate, self.interval):
            unit = "" if f.unit in ("", "-") else f" {f.unit}"
            lines.append(f"  {f.name:<12} {e:.6g}{unit}  95 % [{lo:.6g}, {hi:.6g}]  (start {s:.6g})")
        for src, per in self.fit.items():
            lines.append(f"  fit {src}: " + ", ".join(f"{k} {v:.2f} %" for k, v in per.items()))
        lines += [f"  warning: {w}" for w in self.warnings]
        return "\n".join(lines)


def check_record_for_rig(record: Record, rig: Rig, sensors=None, option: str = "record") -> tuple:
    """Check that a record can be fitted with a rig; return the sensors to use.

    Refused (one line): an input that is not the rig's drive's (``V`` for a DC motor, ``tau``
    for the torque drive), a constant input, a sensor the rig does not have, no sensor, a
    record shorter than one period of the first clamped mode.

    Parameters
    ----------
    record : Record
    rig : Rig
    sensors : sequence of str, optional
        Default: the record's sensors that the rig has (``v_tip`` and ``theta_dot`` only if
        the record holds them).
    option : str

    Returns
    -------
    tuple of str
    """
    from hubbeam_ctrl.calibrate.model import clamped_modes
    where = f"{option} {record.source}: " if record.source else f"{option}: "
    want = "V" if not rig.drive.is_ideal else "tau"
    if record.input_name != want:
        kind = "a DC motor: give its voltage as V [V]" if want == "V" else "a torque drive: give tau [N m]"
        raise ParameterError(f"{where}its input is {record.input_name} but the rig's drive is {kind}")
    record.check_input_varies()
    if sensors is None:
        have = rig_sensors(rig)
        extra = [s for s in record.sensors if s not in have]
        if extra:
            _check_sensors(rig, extra)
        sensors = tuple(s for s in record.sensors if s in have)
    else:
        sensors = _check_sensors(rig, sensors)
        missing = [s for s in sensors if s not in record.columns]
        if missing:
            raise ParameterError(f"{where}has no column {missing[0]}; it holds {', '.join(record.sensors)}")
    if not sensors:
        raise ParameterError(f"{where}holds no sensor of the rig ({', '.join(rig_sensors(rig))})")
    f1 = float(clamped_modes(rig, 1)[0][0])
    if record.duration < 1.0 / f1:
        raise ParameterError(f"{where}lasts {record.duration:.4g} s, shorter than one period of the first "
                             f"mode ({1 / f1:.4g} s at {f1:.4g} Hz)")
    return sensors


def predict(rig: Rig, record: Record, sensors, settings: ModelSettings | None = None) -> dict:
    """The rig's model series for a record's input (theta offset to the record's first angle).

    Parameters
    ----------
    rig : Rig
    record : Record
        Uniform in time (:meth:`Record.resampled`).
    sensors : sequence of str
    settings : ModelSettings, optional

    Returns
    -------
    dict
        Sensor -> ndarray (N,).
    """
    t = record.t - record.t[0]
    y = simulate_sensors(rig, t, record.input, sensors, settings)
    y.pop("stats")
    if "theta" in y and "theta" in record.columns:
        y["theta"] = y["theta"] + record.columns["theta"][0]
    return y


def validate_record(rig: Rig, record: Record, sensors=None, settings: ModelSettings | None = None) -> tuple:
    """Fit percentage of each sensor of a record not used in the fit.

    Parameters
    ----------
    rig : Rig
    record : Record
    sensors : sequence of str, optional
    settings : ModelSettings, optional

    Returns
    -------
    (dict, dict)
        Sensor -> fit [%], and sensor -> model series.
    """
    record = record.resampled()
    sensors = check_record_for_rig(record, rig, sensors, "--validate")
    y = predict(rig, record, sensors, settings)
    return {s: fit_percent(record.columns[s], y[s]) for s in sensors}, y


def check_bounds(fit_fields, bounds, option: str = "--bounds") -> tuple:
    """The search bounds of the fitted fields: each field's range, narrowed by ``bounds``.

    Parameters
    ----------
    fit_fields : sequence of FitField
        The fitted fields (:func:`resolve_fields`).
    bounds : dict or None
        Field name (or path) -> ``(lo, hi)`` in the field's unit; each within the field's range.
    option : str
        The bounds' name as the caller spelled it (starts the messages).

    Returns
    -------
    lo, hi : ndarray

    Raises
    ------
    ParameterError
        A name that is not fitted, bounds that are not finite, reversed, or outside the
        field's range (refused, not clipped).
    """
    lo = np.array([f.lo for f in fit_fields])
    hi = np.array([f.hi for f in fit_fields])
    for name, pair in (bounds or {}).items():
        k = next((i for i, f in enumerate(fit_fields) if name in (f.name, f.path)), None)
        if k is None:
            raise ParameterError(f"{option}: {name!r} is not a fitted field ({', '.join(f.name for f in fit_fields)})")
        a, b = (float(v) for v in pair)
        if not (math.isfinite(a) and math.isfinite(b)):
            raise ParameterError(f"{option}: {name} bounds must be finite, got {a:g}:{b:g}")
        if a > b:
            raise ParameterError(f"{option}: {name} has lo = {a:g} > hi = {b:g}")
        f = fit_fields[k]
        if a < f.lo or b > f.hi:        # refused, not clipped: the fit would not search what was asked
            raise ParameterError(f"{option}: {name} bounds {a:g}:{b:g} must lie within its range "
                                 f"[{f.lo:g}, {f.hi:g}] [{f.unit}]")
        lo[k], hi[k] = a, b
    return lo, hi


def _bounds(fit_fields, bounds, start, option="--bounds"):
    lo, hi = check_bounds(fit_fields, bounds, option)
    for k, f in enumerate(fit_fields):
        if not lo[k] <= start[k] <= hi[k]:
            raise ParameterError(f"{option}: the start of {f.name} ({start[k]:g}) is outside its bounds "
                                 f"[{lo[k]:g}, {hi[k]:g}]")
    return lo, hi


def _scales(fit_fields, start, rig) -> np.ndarray:
    out = []
    for f, s in zip(fit_fields, start):
        if s != 0.0:
            out.append(abs(s))
        elif f.table == "friction":
            stall = rig.drive.stall_torque if not rig.drive.is_ideal else rig.beam.tau_max
            out.append(0.01 * stall)
        elif f.key == "ratios":
            out.append(0.01)
        else:
            out.append(1.0)
    return np.array(out)


def _diagnose(J, scale, estimate, residual, fit_fields) -> tuple:
    """Standard deviations, correlations and identifiability warnings from the Jacobian."""
    m, p = J.shape
    warnings = []
    norms = np.linalg.norm(J, axis=0)
    dead = norms <= 1e-12 * max(1.0, norms.max())
    for k in np.nonzero(dead)[0]:
        warnings.append(f"{fit_fields[k].name} is not identifiable from these records: it does not change "
                        "the simulated sensors")
    s2 = float(residual @ residual) / max(m - p, 1)
    Jn = J[:, ~dead] / norms[~dead]
    std = np.full(p, np.inf)
    corr = np.full((p, p), np.nan)
    if Jn.shape[1]:
        u, sv, vt = np.linalg.svd(Jn, full_matrices=False)
        cond = sv[0] / max(sv[-1], 1e-300)
        cov_n = (vt.T / np.maximum(sv, 1e-300) ** 2) @ vt * s2
        idx = np.nonzero(~dead)[0]
        d = np.sqrt(np.diag(cov_n))
        std[idx] = d / norms[~dead] * scale[idx]
        corr[np.ix_(idx, idx)] = cov_n / np.outer(d, d)
        if cond > IDENTIFIABILITY_CONDITION:
            weak = vt[-1]
            who = [fit_fields[idx[k]].name for k in np.argsort(-np.abs(weak)) if abs(weak[k]) > 0.3]
            warnings.append(f"{', '.join(who)} are not separately identifiable from these records (condition "
                            f"number {cond:.3g} of the scaled Jacobian): only a combination is determined")
    for k, f in enumerate(fit_fields):
        if not dead[k] and estimate[k] != 0 and 1.96 * std[k] > 0.5 * abs(estimate[k]):
            warnings.append(f"{f.name} is poorly determined: its 95 % interval (+-{1.96 * std[k]:.3g}) is wider "
                            f"than half its value")
    return std, corr, warnings


def _least_squares(residual_of, x0, lo, hi, n_params, settings, label, enabled, evals_per_call=1):
    """SciPy's trf on a residual function with a forward-difference Jacobian and a progress bar."""
    from scipy.optimize import least_squares

    cache = {}
    budget = settings.max_evaluations * (n_params + 1)
    bar = progress_bar(budget, label, enabled=enabled)

    def fun(x):
        key = x.tobytes()
        if key not in cache:
            cache.clear()
            cache[key] = residual_of(x)
            bar.update(1)
        return cache[key]

    def jac(x):
        r0 = fun(x)
        J = np.empty((r0.size, x.size))
        for k in range(x.size):
            h = settings.difference_step * max(abs(x[k]), 1e-3)
            xk = x.copy()
            xk[k] = x[k] + h if x[k] + h <= hi[k] else x[k] - h
            if settings.central and x[k] - h >= lo[k] and x[k] + h <= hi[k]:
                xm = x.copy()
                xm[k] = x[k] - h
                J[:, k] = (residual_of(xk) - residual_of(xm)) / (2 * h)
                bar.update(2)
                continue
            J[:, k] = (residual_of(xk) - r0) / (xk[k] - x[k])
            bar.update(1)
        return J

    x0 = np.clip(x0, lo, hi)
    tol = settings.tolerance
    try:
        sol = least_squares(fun, x0, jac=jac, bounds=(lo, hi), method="trf", x_scale="jac",
                            max_nfev=settings.max_evaluations, ftol=tol, xtol=tol, gtol=tol)
    finally:
        bar.close()
    return sol


def fit_rig(rig: Rig, records, fit, *, bounds=None, sensors=None, settings: FitSettings | None = None,
            progress: bool = True) -> FitResult:
    """Fit rig fields to records by least squares on the nonlinear plant with the hardware.

    Parameters
    ----------
    rig : Rig
        The start: every field not fitted keeps its value.
    records : Record or sequence of Record
        Each starts at rest (hub and beam) and holds the rig's input (``V`` for a DC motor,
        ``tau`` for the torque drive) and some of its sensors; non-uniform times are
        resampled to the median period.
    fit : str or sequence of str
        The fields (:func:`resolve_fields`): ``"E,J_h,m_t,damping,friction"``.
    bounds : dict, optional
        Name -> ``(lo, hi)`` within each field's range.
    sensors : sequence of str, optional
        The sensors fitted (default every rig sensor each record holds).
    settings : FitSettings, optional
    progress : bool
        Show a progress bar (on a terminal).

    Returns
    -------
    FitResult
        With ``converged`` False (and the last estimate) when the optimiser stopped at its
        evaluation limit.
    """
    settings = settings or FitSettings()
    if not isinstance(rig, Rig):
        raise ParameterError(f"rig must be a Rig, got {type(rig).__name__}")
    records = [records] if isinstance(records, Record) else list(records)
    if not records or not all(isinstance(r, Record) for r in records):
        raise ParameterError("records must be one or more Record (calibrate.records.load_record)")
    fit_fields = resolve_fields(fit, rig)
    records = [r.resampled() for r in records]
    used = [check_record_for_rig(r, rig, sensors) for r in records]
    start = np.array([f.get(rig) for f in fit_fields])
    lo, hi = _bounds(fit_fields, bounds, start)
    scale = _scales(fit_fields, start, rig)
    spreads = [{s: float(np.linalg.norm(r.columns[s] - r.columns[s].mean())) for s in ss}
               for r, ss in zip(records, used)]
    for r, sp in zip(records, spreads):
        for s, v in sp.items():
            if v == 0.0:
                raise ParameterError(f"record {r.source}: sensor {s} is constant: nothing to fit")
    from hubbeam_ctrl.calibrate.model import clamped_modes
    period = 1.0 / float(clamped_modes(rig, 1)[0][0])
    longest = max(r.duration for r in records)
    horizons = [h * period for h in settings.horizon_periods if h * period < 0.8 * longest] + [math.inf]

    def residual_function(recs):
        sp_k = [{s: float(np.linalg.norm(r.columns[s] - r.columns[s].mean())) or sp[s] for s in ss}
                for r, ss, sp in zip(recs, used, spreads)]
        m = sum(len(r.t) * len(ss) for r, ss in zip(recs, used))
        failed = np.full(m, 10.0 / math.sqrt(m))

        def residual_of(x):
            try:
                trial = set_fields(rig, fit_fields, x * scale)
                parts = []
                for r, ss, sp in zip(recs, used, sp_k):
                    y = predict(trial, r, ss, settings.model)
                    parts += [(y[s] - r.columns[s]) / sp[s] for s in ss]
                out = np.concatenate(parts)
                return out if np.all(np.isfinite(out)) else failed
            except (HubbeamError, ParameterError):
                return failed
        return residual_of

    t0 = time.perf_counter()
    x, evaluations = start / scale, 0
    stages = horizons + [math.inf] * settings.restarts
    cost = math.inf
    for k, horizon in enumerate(stages):
        recs = [r if r.duration <= horizon else r.window(r.t[0], r.t[0] + horizon) for r in records]
        label = "fit" if len(stages) == 1 else f"fit {k + 1}/{len(stages)}"
        trial = _least_squares(residual_function(recs), x, lo / scale, hi / scale, len(fit_fields), settings,
                               label, progress)
        evaluations += int(trial.nfev)
        if k >= len(horizons):                  # a restart: kept only if it lowered the cost
            if not trial.cost < cost * (1 - 1e-6):
                break
        sol, x, cost = trial, trial.x, float(trial.cost)
    estimate = sol.x * scale
    converged = bool(sol.status > 0)
    message = sol.message if converged else f"did not converge ({sol.message}); the last estimate is kept"
    calibrated = set_fields(rig, fit_fields, estimate)
    std, corr, warnings = _diagnose(sol.jac, scale, estimate, sol.fun, fit_fields)
    if not converged:
        warnings.insert(0, f"the fit did not converge in {settings.max_evaluations} evaluations; the last "
                           "estimate is kept and not checked")
    fits = {}
    for r, ss in zip(records, used):
        y = predict(calibrated, r, ss, settings.model)
        fits[r.source or f"record {len(fits) + 1}"] = {s: fit_percent(r.columns[s], y[s]) for s in ss}
    for src, per in fits.items():
        for sensor, value in per.items():
            if not value >= settings.warn_fit_percent:
                warnings.append(f"the fit of {sensor} on {src} is only {value:.1f} % (below "
                                f"{settings.warn_fit_percent:g} %): a local minimum, a model that lacks something "
                                "or a noisy sensor; check the plots before trusting the estimate")
    return FitResult(fit_fields, start, estimate, std, corr, converged, message, evaluations, fits, warnings,
                     calibrated, time.perf_counter() - t0)


# -- modal table ---------------------------------------------------------------------------

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


def load_modal_table(path) -> ModalTable:
    """Read a modal table CSV (header ``spin [rad/s],m_t [kg],mode [-],frequency [Hz],damping [-]``;
    ``m_t`` and ``damping`` optional).

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    ModalTable
    """
    from hubbeam_ctrl.core.fileio import check_regular_file
    path = check_regular_file(path, "modal table")
    with open(path, encoding="utf-8") as fh:
        header = fh.readline()
        body = fh.read()
    names = []
    for item in header.strip().split(","):
        m = re.match(r"^\s*(\w+)\s*\[([^\]]*)\]\s*$", item)
        if not m or m.group(1) not in MODAL_TABLE_COLUMNS or m.group(2).strip() != MODAL_TABLE_COLUMNS[m.group(1)]:
            raise ParameterError(f"modal table {path}: header item {item.strip()[:40]!r} is not one of "
                                 + ", ".join(f"{k} [{u}]" for k, u in MODAL_TABLE_COLUMNS.items()))
        names.append(m.group(1))
    for need in ("spin", "mode", "frequency"):
        if need not in names:
            raise ParameterError(f"modal table {path}: needs a column {need} [{MODAL_TABLE_COLUMNS[need]}]")
    try:
        data = np.array([[float(c) for c in line.split(",")] for line in body.splitlines() if line.strip()])
    except ValueError:
        raise ParameterError(f"modal table {path}: a cell is not a number") from None
    data = data.reshape(-1, len(names))
    cols = {n: data[:, j] for j, n in enumerate(names)}
    k = len(data)
    return ModalTable(spin=cols["spin"], m_t=cols.get("m_t", np.full(k, np.nan)), mode=cols["mode"],
                      frequency=cols["frequency"], damping=cols.get("damping", np.full(k, np.nan)))


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
