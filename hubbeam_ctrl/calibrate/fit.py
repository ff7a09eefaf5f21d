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
direction are named) or when its interval is wider than half its value.

The defaults come from the records (issue 38): the plant's bending modes from the band
they excite (:func:`~hubbeam_ctrl.calibrate.design.record_design`), the start from their
frequency responses (:func:`~hubbeam_ctrl.calibrate.start.frequency_start`). A fit is
``converged`` (:attr:`FitResult.status`) only when the optimiser stopped on its tolerance
and every record's sensor is fitted within :attr:`FitSettings.floor_margin` of the ceiling
its noise allows; otherwise the status says why ("not converged", "below the noise
ceiling", "stopped at --max-wall") and the last (or best) estimate is kept.

:func:`~hubbeam_ctrl.calibrate.table.fit_modal_table` fits the same fields to measured
frequencies and damping ratios against spin rate and tip mass, by modal analysis.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from hubbeam_ctrl.calibrate.drive import drive_plan
from hubbeam_ctrl.calibrate.fields import FIT_ALIASES, FitField, resolve_fields  # noqa: F401 (re-exported)
from hubbeam_ctrl.calibrate.intervals import rough_intervals
from hubbeam_ctrl.calibrate.model import ModelSettings, _check_sensors, rig_sensors, set_fields, simulate_sensors
from hubbeam_ctrl.calibrate.records import Record
from hubbeam_ctrl.calibrate.solver import (
    IDENTIFIABILITY_CONDITION,
    _bounds,
    _diagnose,
    _least_squares,
    _scales,
    check_bounds,
)
from hubbeam_ctrl.core.errors import HubbeamError, ParameterError
from hubbeam_ctrl.plant.rig import Rig

__all__ = ["FitSettings", "FitResult", "set_fields", "fit_rig", "fit_percent", "predict", "validate_record",
           "IDENTIFIABILITY_CONDITION", "check_record_for_rig", "check_bounds"]

#: After the frequency-response start, the short-horizon stages keep each field within this factor of it.
STAGE_BOUND = 1.15


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
        The simulated plant (its ``n_transverse`` is replaced by ``plant_modes``).
    plant_modes : int or None
        Bending modes of the fitted plant; None (default): from the records
        (:func:`~hubbeam_ctrl.calibrate.design.record_design`: every mode of the guess below
        the excited band's top, plus the first above it).
    frequency_start : bool
        Start from the records' frequency responses
        (:func:`~hubbeam_ctrl.calibrate.start.frequency_start`) instead of the given rig
        when they are coherent with the input (the given start's and this start's costs are
        reported; the plant's modes are then counted on this start).
    floor_margin : float
        "Converged" needs every record's sensor fitted within this many points of its noise
        ceiling (:func:`~hubbeam_ctrl.calibrate.design.fit_ceiling`) [%].
    rough_intervals : bool
        The 95 % intervals by :func:`~hubbeam_ctrl.calibrate.intervals.rough_intervals` (the
        cost probed at the intervals' scale: they hold when stick-slip friction makes it rough;
        about ``20 p`` more simulations of every record for ``p`` fields) instead of the
        Jacobian's ``s^2 (J' J)^-1`` alone (kept in :attr:`FitResult.std_jacobian`; the only one
        after a stop at ``max_wall``).
    max_wall : float or None
        Wall-time limit of the fit [s]: the optimiser stops, the best estimate so far is kept
        and the result says "stopped at --max-wall".
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
    plant_modes: int | None = None
    frequency_start: bool = True
    floor_margin: float = 1.0
    max_wall: float | None = None
    rough_intervals: bool = True

    def __post_init__(self):
        pm = self.plant_modes
        if pm is not None and (isinstance(pm, bool) or not isinstance(pm, int) or not 1 <= pm <= 20):
            raise ParameterError(f"plant_modes must be an integer in 1..20 or None (from the records), got {pm!r}")
        mw = self.max_wall
        if mw is not None and (not isinstance(mw, (int, float)) or not 0 < mw <= 1e6):
            raise ParameterError(f"max_wall must be in (0, 1e6] [s] or None, got {mw!r}")
        if not isinstance(self.max_evaluations, int) or not 1 <= self.max_evaluations <= 10000:
            raise ParameterError(f"max_evaluations must be an integer in 1..10000, got {self.max_evaluations!r}")
        if not isinstance(self.restarts, int) or not 0 <= self.restarts <= 10:
            raise ParameterError(f"restarts must be an integer in 0..10, got {self.restarts!r}")
        hp = self.horizon_periods
        if not isinstance(hp, tuple) or not all(isinstance(h, (int, float)) and 0.5 <= h <= 1e4 for h in hp):
            raise ParameterError(f"horizon_periods must be a tuple of numbers in [0.5, 10000], got {hp!r}")
        for name, lo, hi in (("tolerance", 1e-15, 0.1), ("difference_step", 1e-10, 0.1),
                             ("warn_fit_percent", -1e9, 100.0), ("floor_margin", 0.0, 100.0)):
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
        Start, estimate and standard deviation of each field [its unit]; ``1.96 std`` is the
        95 % half-width (:func:`~hubbeam_ctrl.calibrate.intervals.rough_intervals` for a fit
        to records, which includes the cost's roughness).
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
    design : RecordDesign or None
        The excited band, the plant's modes and the noise floor (records only).
    ceiling : dict
        Record source -> sensor -> the fit ceiling the noise allows [%].
    starts : dict
        The starts tried: name -> ``{"values", "cost"}``, and ``"won"`` -> the name.
    model : ModelSettings or None
        The plant the fit simulated.
    status : str
        ``"converged"``, ``"not converged"``, ``"below the noise ceiling"`` or ``"stopped at --max-wall"``.
    std_jacobian : ndarray or None
        The Jacobian's standard deviations, ``s^2 (J' J)^-1`` with white residuals [its unit].
    intervals : dict
        How the intervals were found: ``method`` (``"rough"`` or ``"jacobian"``) and, for
        ``"rough"``, the cost's ``roughness`` and ``noise_cost``, the ``evaluations`` spent, the
        noise's part of each 95 % half-width ``noise_half_width`` and the smoothed minimum's
        offset from the estimate ``shift`` [each field's unit].
    drive : DrivePlan or None
        The drive fields fixed because the records cannot separate them (and why), and the
        combinations they determine (:func:`~hubbeam_ctrl.calibrate.drive.drive_plan`).
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
    design: object = None
    ceiling: dict = field(default_factory=dict)
    starts: dict = field(default_factory=dict)
    model: object = None
    status: str = ""
    std_jacobian: np.ndarray | None = None
    intervals: dict = field(default_factory=dict)
    drive: object = None

    def __post_init__(self):
        if not self.status:
            self.status = "converged" if self.converged else "not converged"

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
                "fit_percent": self.fit, "fit_ceiling_percent": self.ceiling, "status": self.status,
                "starts": self.starts, "plant_modes": None if self.model is None else self.model.n_transverse,
                "design": None if self.design is None else self.design.to_dict(), "warnings": list(self.warnings),
                "drive": None if self.drive is None else self.drive.to_dict(),
                "intervals": {**self.intervals, **({} if self.std_jacobian is None else {
                    "std_jacobian": dict(zip(self.names, np.asarray(self.std_jacobian, dtype=float).tolist()))})}}

    def summary(self) -> str:
        """Human-readable lines: estimates with intervals, fit per record and sensor, warnings."""
        lines = [f"fit {'converged' if self.converged else self.status.upper()}: {self.message} "
                 f"({self.evaluations} evaluations, {self.wall_s:.1f} s)"]
        if self.design is not None:
            lines.append(f"  plant: {self.design.reason}" + ("" if self.model.n_transverse == self.design.plant_modes
                                                              else f"; fitted with {self.model.n_transverse} modes"))
        if "won" in self.starts:
            tried = [k for k in ("given", "frequency response") if k in self.starts]
            fits = self.starts.get("fits", {})
            lines.append("  starts: " + ", ".join(f"{k} (cost {self.starts[k]['cost']:.4g})" for k in tried)
                         + f"; fitted from {self.starts['won']}: "
                         + ", ".join(f"{k} fit cost {v['cost']:.4g}" for k, v in fits.items())
                         + (f"; the {self.starts['fit_won']} fit won" if len(fits) > 1 else ""))
        for f, s, e, (lo, hi) in zip(self.fields, self.start, self.estimate, self.interval):
            unit = "" if f.unit in ("", "-") else f" {f.unit}"
            lines.append(f"  {f.name:<12} {e:.6g}{unit}  95 % [{lo:.6g}, {hi:.6g}]  (start {s:.6g})")
        lines += [f"  {line}" for line in ([] if self.drive is None else self.drive.lines())]
        for src, per in self.fit.items():
            cap = self.ceiling.get(src, {})
            lines.append(f"  fit {src}: " + ", ".join(f"{k} {v:.2f} %" + (f" (noise ceiling {cap[k]:.2f} %)"
                                                                           if k in cap else "")
                                                       for k, v in per.items()))
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
        ``converged`` False with the last (or best) estimate and ``status`` saying why when
        the optimiser stopped at its evaluation limit or ``max_wall``, or the fit is below a
        sensor's noise ceiling by more than ``floor_margin``; ``design``, ``ceiling``,
        ``starts`` and ``model`` say what the records excite, the noise ceilings, the starts
        tried (and which won) and the plant fitted.
    """
    settings = settings or FitSettings()
    if not isinstance(rig, Rig):
        raise ParameterError(f"rig must be a Rig, got {type(rig).__name__}")
    records = [records] if isinstance(records, Record) else list(records)
    if not records or not all(isinstance(r, Record) for r in records):
        raise ParameterError("records must be one or more Record (calibrate.records.load_record)")
    asked = resolve_fields(fit, rig)
    records = [r.resampled() for r in records]
    used = [check_record_for_rig(r, rig, sensors) for r in records]
    fit_fields, drive = drive_plan(rig, records, asked)      # k_t and R: only k_t / R (calibrate.drive)
    gone = {n for f in asked if f.path in drive.fixed for n in (f.name, f.path)}
    bounds = {k: v for k, v in (bounds or {}).items() if k not in gone}
    start = np.array([f.get(rig) for f in fit_fields])
    lo, hi = _bounds(fit_fields, bounds, start)
    scale = _scales(fit_fields, start, rig)
    spreads = [{s: float(np.linalg.norm(r.columns[s] - r.columns[s].mean())) for s in ss}
               for r, ss in zip(records, used)]
    for r, sp in zip(records, spreads):
        for s, v in sp.items():
            if v == 0.0:
                raise ParameterError(f"record {r.source}: sensor {s} is constant: nothing to fit")
    from dataclasses import replace

    from hubbeam_ctrl.calibrate.design import record_design
    from hubbeam_ctrl.calibrate.model import clamped_modes
    from hubbeam_ctrl.calibrate.start import frequency_start
    t0 = time.perf_counter()
    deadline = math.inf if settings.max_wall is None else t0 + settings.max_wall
    design = record_design(rig, records, used)
    model = replace(settings.model, n_transverse=settings.plant_modes or design.plant_modes)

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
                    y = predict(trial, r, ss, model)
                    parts += [(y[s] - r.columns[s]) / sp[s] for s in ss]
                out = np.concatenate(parts)
                return out if np.all(np.isfinite(out)) else failed
            except (HubbeamError, ParameterError):
                return failed
        return residual_of

    whole = residual_function(records)
    starts = {"given": {"values": start.tolist(), "cost": 0.5 * float(np.sum(whole(start / scale) ** 2))}}
    x = start / scale
    if settings.frequency_start:
        fs = frequency_start(rig, records, used, fit_fields, start, lo, hi, design.band_hz, model.n_transverse)
        if fs is not None:
            xf = np.clip(fs.values / scale, lo / scale, hi / scale)
            starts["frequency response"] = {"values": (xf * scale).tolist(),
                                            "cost": 0.5 * float(np.sum(whole(xf) ** 2)),
                                            "fields": list(fs.varied), "log_magnitude_rms": fs.misfit}
            x = xf
    # a whole-record cost does not rank starts whose oscillations slip against the records (both
    # slip); the frequency responses do: their start is taken whenever there is one
    starts["won"] = "frequency response" if "frequency response" in starts else "given"
    start_rig = set_fields(rig, fit_fields, x * scale)
    if starts["won"] != "given":                # the plant's modes from the start, not from the guess
        design = record_design(start_rig, records, used)
        model = replace(settings.model, n_transverse=settings.plant_modes or design.plant_modes)
    period = 1.0 / float(clamped_modes(start_rig, 1)[0][0])
    longest = max(r.duration for r in records)
    # the short horizons guard a start whose oscillation slips against the records (a long PRBS slips
    # even from a start 1 % off in E); after the frequency-response start the short stages may move each
    # field only within STAGE_BOUND of it: the beginning of a log chirp holds little of the stiffness,
    # and a stage free to move it would leave it anywhere
    horizons = [h * period for h in settings.horizon_periods if h * period < 0.8 * longest] + [math.inf]
    slo, shi = lo / scale, hi / scale
    if starts["won"] != "given":               # the fields the frequency start placed
        placed = np.array([f.name in starts["frequency response"]["fields"] for f in fit_fields]) & (x > 0)
        slo = np.where(placed, np.maximum(slo, x / STAGE_BOUND), slo)
        shi = np.where(placed, np.minimum(shi, x * STAGE_BOUND), shi)
    def run(x, staged):
        """The stages from ``x``: (solution, evaluations, stage reached, stages)."""
        stages = (horizons if staged else [math.inf]) + [math.inf] * settings.restarts
        n_main = len(stages) - settings.restarts
        sol, cost, evaluations = None, math.inf, 0
        for k, horizon in enumerate(stages):
            recs = [r if r.duration <= horizon else r.window(r.t[0], r.t[0] + horizon) for r in records]
            label = "fit" if len(stages) == 1 else f"fit {k + 1}/{len(stages)}"
            final = math.isinf(horizon)
            trial = _least_squares(residual_function(recs), x, lo / scale if final else slo,
                                   hi / scale if final else shi, len(fit_fields), settings, label, progress,
                                   deadline)
            evaluations += int(trial.nfev)
            if trial.status == -2:                  # --max-wall: the best point so far
                return trial, evaluations, k, len(stages)
            if k >= n_main and not trial.cost < cost * (1 - 1e-6):   # a restart that did not lower the cost
                break
            sol, x, cost = trial, trial.x, float(trial.cost)
        return sol, evaluations, k, len(stages)

    def judge(sol):
        est = sol.x * scale
        trial_rig = set_fields(rig, fit_fields, est)
        fits = {}
        for r, ss in zip(records, used):
            y = predict(trial_rig, r, ss, model)
            fits[r.source or f"record {len(fits) + 1}"] = {s: fit_percent(r.columns[s], y[s]) for s in ss}
        short = {(src, s): design.ceiling[src][s] - v for src, per in fits.items() for s, v in per.items()
                 if not v >= design.ceiling[src][s] - settings.floor_margin}
        return fits, short

    # the plans: staged from the chosen start; after the frequency-response start, when the staged fit
    # does not reach the noise floor, the whole records at once from it (a log chirp's first seconds hold
    # little of the stiffness and the stages can leave it off): the lower cost wins
    plans = [("staged", x, True)] + ([("whole records", x, False)] if starts["won"] != "given" else [])
    evaluations, best = 0, None
    for name, x0, staged in plans:
        sol, n_ev, k, n_stages = run(x0, staged)
        evaluations += n_ev
        fits, short = judge(sol)
        cost = 0.5 * float(np.sum(whole(sol.x) ** 2)) if sol.fun is not None else math.inf
        starts.setdefault("fits", {})[name] = {"cost": cost, "values": (sol.x * scale).tolist()}
        if best is None or cost < best[0]:
            best = (cost, name, sol, fits, short, k, n_stages)
        if (sol.status > 0 and not short) or sol.status == -2:
            break
    _, starts["fit_won"], sol, fits, short, k, n_stages = best
    estimate = sol.x * scale
    calibrated = set_fields(rig, fit_fields, estimate)
    fun = sol.fun if sol.fun is not None else whole(sol.x)
    std, corr, warnings = _diagnose(sol.jac, scale, estimate, fun, fit_fields) if sol.jac.size else (
        np.full(len(fit_fields), np.inf), np.full((len(fit_fields),) * 2, np.nan), [])
    std_jacobian, intervals = std, {"method": "jacobian"}
    if sol.jac.size and settings.rough_intervals and sol.status != -2:     # not past --max-wall
        segments = [len(r.t) for r, ss in zip(records, used) for _ in ss]
        iv = rough_intervals(whole, sol.x, fun, sol.jac, segments, lo / scale, hi / scale,
                             step=settings.difference_step)
        std, corr, warnings = _diagnose(sol.jac, scale, estimate, fun, fit_fields, interval=iv)
        intervals = iv.summary(scale)
        warnings += iv.warnings()
    if sol.status == -2:
        status, converged = "stopped at --max-wall", False
        message = (f"stopped at --max-wall ({settings.max_wall:g} s) in stage {k + 1} of {n_stages}; the best "
                   "estimate so far is kept")
    elif sol.status <= 0:
        status, converged = "not converged", False
        message = f"did not converge ({sol.message}); the last estimate is kept"
        warnings.insert(0, f"the fit did not converge in {settings.max_evaluations} evaluations; the last "
                           "estimate is kept and not checked")
    elif short:
        (src, s), gap = max(short.items(), key=lambda kv: kv[1])
        status, converged = "below the noise ceiling", False
        message = (f"the optimiser stopped ({sol.message}) but the fit of {s} on {src} is {gap:.2f} points below "
                   f"the noise ceiling {design.ceiling[src][s]:.2f} % (more than {settings.floor_margin:g}): a "
                   "local minimum or a model that lacks something")
    else:
        status, converged, message = "converged", True, sol.message
    for src, per in fits.items():
        for sensor, value in per.items():
            if not value >= settings.warn_fit_percent:
                warnings.append(f"the fit of {sensor} on {src} is only {value:.1f} % (below "
                                f"{settings.warn_fit_percent:g} %): a local minimum, a model that lacks something "
                                "or a noisy sensor; check the plots before trusting the estimate")
    drive.evaluate(calibrated, {f.path: e for f, e in zip(fit_fields, estimate)},
                   {f.path: s for f, s in zip(fit_fields, std)})
    warnings += [f"{k} is not identifiable from these records: {v['reason']}" for k, v in drive.fixed.items()]
    return FitResult(fit_fields, start, estimate, std, corr, converged, message, evaluations, fits, warnings,
                     calibrated, time.perf_counter() - t0, design=design, ceiling=design.ceiling, starts=starts,
                     model=model, status=status, std_jacobian=std_jacobian, intervals=intervals, drive=drive)
