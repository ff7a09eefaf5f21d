"""Robust tuning of the LQR/LQG/MPC weights over a study's plant spread (``hubbeam tune``).

The weights are searched in a **scaled, dimensionless form**: each weight is
``w_k = 10**x_k / s_k**2`` with the task's own scales ``s_k`` (:func:`weight_scales`: the
slew angle or spin-up angle, that angle per ``t_f``, the beam length ``L`` and ``L / t_f``
for the tip and the modes, ``tau_max`` for the torque). ``x = 0`` is Bryson's rule; the
*scaled defaults* (:func:`scaled_default_weights`) are the toolbox's default weights,
tuned for the paper's beam and slew, carried to any beam and task through the same scales
(on the paper's default slew they are the defaults exactly). The torque weight stays at
its scaled default (scaling every weight together leaves the design unchanged).

The objective of one run (:func:`case_objective`) is the residual vibration in decades of
``L``, plus a torque-effort penalty, a settling penalty and a final-angle penalty; the
objective of a candidate is its worst case (or a quantile) over the spec's cases. SciPy's
``differential_evolution`` (vectorised, the scaled defaults in the initial population)
searches ``x`` within ``decades`` of the scaled defaults; each generation's candidates run
as one batch of cases on the sweep engine (:class:`~hubbeam_ctrl.study.sweep.Engine`).
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import time
from dataclasses import dataclass, field

import numpy as np

from controllers import Weights
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.fileio import atomic_write_text, output_folder
from hubbeam_ctrl.core.progress import progress_bar
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.study.scenarios import make_scenario
from hubbeam_ctrl.study.settings_table import settings_to_toml
from hubbeam_ctrl.study.spec import StudySpec
from hubbeam_ctrl.study.spec_files import load_spec
from hubbeam_ctrl.study.sweep import Engine, plan_batches

__all__ = ["TUNABLE", "TUNED_WEIGHTS", "TuneOptions", "TuneResult", "tune", "weight_scales",
           "scaled_weights", "scaled_default_weights", "case_objective", "write_tune_outputs"]

#: Controllers whose weights can be tuned.
TUNABLE = ("lqr", "lqg", "mpc")
#: Weights searched (the torque weight stays at its scaled default).
TUNED_WEIGHTS = ("angle", "rate", "tip", "tip_rate", "modal")
_ALL_WEIGHTS = TUNED_WEIGHTS + ("torque",)
#: Objective of a run that failed or did not complete (10 L of residual vibration).
FAILED_OBJECTIVE = 1.0


#: Largest ``tune.maxiter`` and ``tune.popsize``, and most closed-loop runs one tuning may take.
MAX_MAXITER, MAX_POPSIZE, MAX_TUNE_RUNS = 10_000, 1_000, 1_000_000

#: Largest ``tune.decades``: the weights ``10^x`` searched stay within 1e-10..1e10 of the scaled
#: defaults (far past any useful design; beyond it the optimiser's bounds overflow).
MAX_DECADES = 10.0
#: Smallest ``tune.decades``: narrower, the weights searched differ from the scaled defaults by less
#: than 2.3e-6 of themselves (at 1e-300 the bounds round to the defaults: no search, one run).
MIN_DECADES = 1e-6
#: Largest ``tune.seed`` (a 64-bit signed integer, as the other seeds: ``SensorSettings.seed``, ``excitation``).
MAX_SEED = 2 ** 63 - 1


@dataclass(frozen=True)
class TuneOptions:
    """Settings of :func:`tune` (the spec's ``[tune]`` table).

    Attributes
    ----------
    objective : str or float
        ``"worst"`` (the largest objective over the cases) or a quantile in (0, 1].
    effort_weight : float
        Penalty per unit of ``int tau^2 dt / (tau_max^2 t_f)`` [decades], >= 0.
    settling_weight : float
        Penalty per unit of ``settling time / t_end`` (1 when not settled) [decades], >= 0.
    angle_weight : float
        Penalty per unit of ``|final angle error| / angle scale`` [decades], >= 0.
    decades : float
        Search ``x_k`` within this many decades of the scaled defaults, in [1e-6, 10].
    maxiter : int
        Generations of differential evolution, >= 1.
    popsize : int
        Population per searched weight (SciPy's ``popsize``), >= 1.
    seed : int
        Seed of the optimiser.
    tol : float
        Relative convergence tolerance of the population's objective spread, > 0.
    """

    objective: str | float = "worst"
    effort_weight: float = 0.1
    settling_weight: float = 0.1
    angle_weight: float = 10.0
    decades: float = 2.0
    maxiter: int = 8
    popsize: int = 4
    seed: int = 0
    tol: float = 0.01

    def __post_init__(self):
        if not (self.objective == "worst" or (isinstance(self.objective, (int, float))
                                             and not isinstance(self.objective, bool)
                                             and 0 < self.objective <= 1)):
            raise ParameterError(f"tune.objective must be 'worst' or a quantile in (0, 1], got {self.objective!r}")
        for name in ("effort_weight", "settling_weight", "angle_weight"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v >= 0):
                raise ParameterError(f"tune.{name} must be a finite number >= 0, got {v!r}")
        for name in ("decades", "tol"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v > 0):
                raise ParameterError(f"tune.{name} must be a finite number > 0, got {v!r}")
        if not MIN_DECADES <= self.decades <= MAX_DECADES:
            raise ParameterError(f"tune.decades must be in [{MIN_DECADES:g}, {MAX_DECADES:g}] (the weights searched "
                                 f"within 10^-decades..10^decades of the scaled defaults), got {self.decades:g}")
        for name, hi in (("maxiter", MAX_MAXITER), ("popsize", MAX_POPSIZE)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= hi:
                raise ParameterError(f"tune.{name} must be an integer in 1..{hi}, got {v!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or not 0 <= self.seed <= MAX_SEED:
            raise ParameterError(f"tune.seed must be an integer in 0..{MAX_SEED}, got {self.seed!r}")

    @classmethod
    def from_dict(cls, table: dict | None) -> "TuneOptions":
        """From the ``[tune]`` table (unknown keys are an error).

        Parameters
        ----------
        table : dict or None
            The spec's ``[tune]`` table.
        """
        table = dict(table or {})
        known = {f.name for f in dataclasses.fields(cls)}
        bad = sorted(set(table) - known)
        if bad:
            raise ParameterError(f"tune: unknown key(s) {', '.join(bad)}; allowed: {', '.join(sorted(known))}")
        return cls(**table)


# -- the dimensionless weights ---------------------------------------------------------------
def weight_scales(scenario, params: Params) -> dict:
    """Scales ``s_k`` of the weights for a task: ``w_k s_k**2`` is dimensionless.

    Parameters
    ----------
    scenario : Scenario
        Gives the angle (slew ``Theta``, or ``w_f t_f`` of a spin-up) [rad], ``t_f`` [s] and
        ``tau_max`` [N m].
    params : Params
        Gives the beam length ``L`` [m].

    Returns
    -------
    dict
        ``angle`` [rad], ``rate`` [rad/s], ``tip`` [m], ``tip_rate`` [m/s], ``modal`` [m],
        ``torque`` [N m].
    """
    angle = abs(scenario.target) * (1.0 if scenario.name == "slew" else scenario.t_f)
    angle = angle if angle > 0 else 1.0
    return {"angle": angle, "rate": angle / scenario.t_f, "tip": params.L, "tip_rate": params.L / scenario.t_f,
            "modal": params.L, "torque": scenario.tau_max}


@functools.lru_cache(maxsize=1)
def _paper_x_cached() -> tuple:
    sc = make_scenario("slew", plant="foam")
    s, w = weight_scales(sc, sc.params), Weights()
    return tuple((k, math.log10(getattr(w, k) * s[k] ** 2)) for k in _ALL_WEIGHTS)


def _paper_x() -> dict:
    """The default weights in dimensionless form on the paper's default slew."""
    return dict(_paper_x_cached())


def scaled_weights(x: dict, scenario, params: Params) -> Weights:
    """:class:`~controllers.Weights` from dimensionless log-weights ``x`` (missing keys: the
    scaled defaults).

    Parameters
    ----------
    x : dict
        Weight name -> ``log10(w s**2)``.
    scenario : Scenario
    params : Params

    Returns
    -------
    Weights
    """
    s, base = weight_scales(scenario, params), _paper_x()
    return Weights(**{k: 10.0 ** float(x.get(k, base[k])) / s[k] ** 2 for k in _ALL_WEIGHTS})


def scaled_default_weights(scenario, params: Params) -> Weights:
    """The default weights carried to this beam and task through :func:`weight_scales`.

    Parameters
    ----------
    scenario : Scenario
        The task (its scales).
    params : Params
        The beam.
    """
    return scaled_weights({}, scenario, params)


# -- objective -------------------------------------------------------------------------------------
def case_objective(row: dict, scales: dict, options: TuneOptions, t_f: float, t_end: float) -> float:
    """Objective of one run [decades]: ``log10(residual / L)`` plus the penalties of ``options``.

    Parameters
    ----------
    row : dict
        A sweep row (metrics of one run).
    scales : dict
        :func:`weight_scales` of the task.
    options : TuneOptions
    t_f, t_end : float
        Maneuver and simulated time [s].

    Returns
    -------
    float
        :data:`FAILED_OBJECTIVE` for a run that failed or stopped.
    """
    res = row.get("residual_tip_max_m")
    if row.get("error") or not row.get("completed") or res is None or not math.isfinite(res):
        return FAILED_OBJECTIVE
    effort = row["torque_squared_integral_n2m2s"] / (scales["torque"] ** 2 * t_f)
    settle = row.get("settling_time_s")
    settle = settle / t_end if settle is not None and math.isfinite(settle) else 1.0
    angle = abs(row["final_angle_error_rad"]) / scales["angle"]
    value = (math.log10(max(res / scales["tip"], 1e-12)) + options.effort_weight * effort
             + options.settling_weight * settle + options.angle_weight * angle)
    return min(value, FAILED_OBJECTIVE)


def _aggregate(values, objective) -> float:
    values = np.asarray(values, dtype=float)
    return float(values.max() if objective == "worst" else np.quantile(values, objective))


# -- the search ------------------------------------------------------------------------------------
@dataclass
class TuneResult:
    """What :func:`tune` found.

    Attributes
    ----------
    controller : str
    x : dict
        Best dimensionless log-weights.
    weights : Weights
        Best weights (absolute).
    objective, default_objective : float
        Aggregated objective of the best weights and of the scaled defaults [decades].
    worst_residual_m, default_worst_residual_m : float
        Largest residual vibration over the cases, tuned and scaled defaults [m].
    history : list of float
        Best objective after each generation.
    n_runs : int
        Closed-loop runs made.
    wall_s : float
        Wall time [s].
    rows, default_rows : list of dict
        Sweep rows of the best candidate and of the scaled defaults.
    """

    controller: str
    x: dict
    weights: Weights
    objective: float
    default_objective: float
    worst_residual_m: float
    default_worst_residual_m: float
    history: list = field(default_factory=list)
    n_runs: int = 0
    wall_s: float = 0.0
    rows: list = field(default_factory=list)
    default_rows: list = field(default_factory=list)

    def settings_table(self) -> dict:
        """``{controller: {"weights": {...}}}``: the tuned weights as plain data (for TOML)."""
        return {self.controller: {"weights": {k: float(getattr(self.weights, k)) for k in _ALL_WEIGHTS}}}


class _Evaluator:
    """Runs candidates (dimensionless x vectors) on the engine and scores them."""

    def __init__(self, spec: StudySpec, controller: str, options: TuneOptions, engine: Engine):
        self.spec, self.controller, self.options, self.engine = spec, controller, options, engine
        self.sc = spec.scenario_for(spec.params)
        self.scales = weight_scales(self.sc, spec.params)
        self.cases = list(enumerate(spec.cases()))
        self.n_runs = 0
        self.seen = {}        # tuple(x) -> (objective, rows)

    def candidate_spec(self, x) -> StudySpec:
        w = scaled_weights(dict(zip(TUNED_WEIGHTS, x)), self.sc, self.spec.params)
        table = dict(self.spec.settings.get(self.controller, {}))
        table["weights"] = {**table.get("weights", {}), **{k: getattr(w, k) for k in _ALL_WEIGHTS}}
        return dataclasses.replace(self.spec, controllers=(self.controller,), settings={self.controller: table})

    def __call__(self, X) -> np.ndarray:
        X = np.atleast_2d(np.asarray(X, dtype=float).T).reshape(-1, len(TUNED_WEIGHTS))
        keys = [tuple(float(v) for v in x) for x in X]
        todo = [k for k in dict.fromkeys(keys) if k not in self.seen]
        jobs, owner = [], {}
        for k in todo:
            spec = self.candidate_spec(k)
            for batch in plan_batches(self.cases, 1, per_worker=1):
                jobs.append((batch, spec))
                owner[id(spec)] = k
        rows = {k: [] for k in todo}
        self.engine.run(jobs, lambda batch, spec, out: rows[owner[id(spec)]].extend(out))
        for k in todo:
            self.n_runs += len(rows[k])
            vals = [case_objective(r, self.scales, self.options, self.sc.t_f, self.sc.t_end) for r in rows[k]]
            self.seen[k] = (_aggregate(vals, self.options.objective), sorted(rows[k], key=lambda r: r["case"]))
        return np.array([self.seen[k][0] for k in keys])


def _worst_residual(rows) -> float:
    vals = [r.get("residual_tip_max_m") for r in rows]
    vals = [v if v is not None and math.isfinite(v) and not r.get("error") else math.inf for v, r in zip(vals, rows)]
    return float(max(vals)) if vals else math.nan


def tune(spec, controller: str, *, options: TuneOptions | None = None, workers: int | None = None,
         client=None, progress: bool = True) -> TuneResult:
    """Search a controller's weights for the best worst case (or quantile) over the spec's cases.

    Parameters
    ----------
    spec : StudySpec, dict or path
        The plant spread (its cases) and the task; its ``[tune]`` table gives the options
        unless ``options`` is passed.
    controller : {"lqr", "lqg", "mpc"}
    options : TuneOptions, optional
    workers : int, optional
        Local worker processes (default one per core; 1: this process).
    client : distributed.Client, optional
        Evaluate on a Dask cluster.
    progress : bool
        One line per generation on stderr.

    Returns
    -------
    TuneResult
    """

    from scipy.optimize import differential_evolution
    raw = spec
    spec = load_spec(spec)
    if controller not in TUNABLE:
        raise ParameterError(f"controller must be one of {', '.join(TUNABLE)}, got {controller!r}")
    if options is None:
        table = raw.get("tune") if isinstance(raw, dict) else _tune_table(raw)
        options = TuneOptions.from_dict(table)
    _check_tune_budget(spec, options)
    start = time.perf_counter()
    x0 = np.array([_paper_x()[k] for k in TUNED_WEIGHTS])
    bounds = [(v - options.decades, v + options.decades) for v in x0]
    history = []
    bar = progress_bar(options.maxiter, f"tune {controller}", enabled=progress)   # quiet off a terminal
    with Engine(workers, client) as engine, bar:
        ev = _Evaluator(spec, controller, options, engine)
        default = float(ev(x0[:, None])[0])

        def report(intermediate_result):
            history.append(float(intermediate_result.fun))
            bar.update(1)
            bar.set_postfix(best=f"{history[-1]:.4f}", defaults=f"{default:.4f}", runs=ev.n_runs)

        res = differential_evolution(ev, bounds, x0=x0, maxiter=options.maxiter, popsize=options.popsize,
                                     tol=options.tol, rng=np.random.default_rng(options.seed), polish=False,
                                     vectorized=True, updating="deferred", callback=report)
    best_key = min(ev.seen, key=lambda k: ev.seen[k][0])
    best, rows = ev.seen[best_key]
    x = dict(zip(TUNED_WEIGHTS, best_key))
    return TuneResult(controller, x, scaled_weights(x, ev.sc, spec.params), best, default,
                      _worst_residual(rows), _worst_residual(ev.seen[tuple(map(float, x0))][1]),
                      history or [float(res.fun)], ev.n_runs, time.perf_counter() - start, rows,
                      ev.seen[tuple(map(float, x0))][1])


def _check_tune_budget(spec, options: TuneOptions) -> None:
    """Refuse a search of more than :data:`MAX_TUNE_RUNS` closed-loop runs, naming the keys."""
    n_cases = len(spec.cases())
    per_generation = options.popsize * len(TUNED_WEIGHTS)
    runs = (options.maxiter + 1) * per_generation * n_cases
    if runs > MAX_TUNE_RUNS:
        raise ParameterError(f"tune.maxiter ({options.maxiter}) + 1 generations x tune.popsize ({options.popsize}) "
                             f"x {len(TUNED_WEIGHTS)} weights x {n_cases} cases = {runs:.6g} closed-loop runs, "
                             f"more than the {MAX_TUNE_RUNS} one tuning runs; lower them or the spec's cases")


def _tune_table(path):
    from hubbeam_ctrl.core.reading import read_toml
    from hubbeam_ctrl.study.spec_files import MAX_SPEC_BYTES
    try:
        return read_toml(path, "spec: file", MAX_SPEC_BYTES).get("tune")
    except ParameterError:
        return None            # load_spec has already reported a bad file


def write_tune_outputs(result: TuneResult, out_dir) -> dict:
    """Write ``tuned_settings.toml``, ``tune.json`` and ``convergence.png`` to ``out_dir``.

    Parameters
    ----------
    result : TuneResult
        What :func:`tune` found.
    out_dir : str or Path
        Created if missing (its parent must exist); the figure needs Matplotlib.

    Returns
    -------
    dict
        File kind -> Path.
    """
    from hubbeam_ctrl.plots.plant import save_figure
    from hubbeam_ctrl.plots.study import plot_convergence
    out = output_folder(out_dir)
    head = (f"# hubbeam tune: {result.controller} weights, objective {result.objective:.4f} "
            f"(scaled defaults {result.default_objective:.4f}); worst residual {result.worst_residual_m:.3e} m "
            f"(scaled defaults {result.default_worst_residual_m:.3e} m)\n")
    toml = head + settings_to_toml(result.settings_table())
    paths = {"settings": atomic_write_text(out / "tuned_settings.toml", toml)}
    summary = {k: v for k, v in dataclasses.asdict(result).items() if k not in ("rows", "default_rows", "weights")}
    summary["weights"] = result.settings_table()[result.controller]["weights"]
    paths["json"] = atomic_write_text(out / "tune.json", json.dumps(summary, indent=2, default=float) + "\n")
    fig = plot_convergence(result.history, result.default_objective, title=f"hubbeam tune {result.controller}")
    paths["plot"] = save_figure(fig, out / "convergence.png")
    return paths
