"""Closed-loop comparison of the controllers on FOAM or CFOAM (``hubbeam compare``).

The top layer of the toolbox: it builds a scenario (reference, design model), designs
each controller on SFOAM, runs it on the nonlinear plant with
:func:`~hubbeam_ctrl.closedloop.simulate_closed_loop`, computes the metrics of
:mod:`hubbeam_ctrl.metrics` and writes ``metrics.csv``, ``metrics.json``, three PNG
plots and ``report.md``.

Scenarios
---------
``slew``
    Rest-to-rest rotation by the rigid-body angle of the paper's Eq. 44 profile,
    ``Theta = tau_m t_f^2 / (2 pi J_total)``, in the same ``t_f`` and with the same torque
    budget ``tau_max = tau_m``. The baseline is the open-loop Eq. 44 torque itself; the
    feedback controllers follow a smooth reference (:func:`controllers.slew_reference`)
    designed on SFOAM linearised at rest.
``spinup``
    Spin-up to ``w_f`` (default 3 rad/s, above TLAM's critical speed) along the corrected
    Eq. 43 profile in ``t_f``, then hold; design model linearised at ``w_f``. The baseline
    is the rigid-body feedforward torque alone.

Example
-------
>>> from hubbeam_ctrl.compare import run_compare, print_table
>>> m = run_compare(plant="foam", controllers="openloop,lqr", out_dir=None)  # doctest: +SKIP
>>> print_table(m)                                                           # doctest: +SKIP
"""

from __future__ import annotations

import csv
import io
import json
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .closedloop import ClosedLoopSettings, simulate_closed_loop
from .errors import ParameterError
from .fileio import atomic_write_text
from .metrics import METRIC_UNITS, closed_loop_metrics
from .models import build_model
from .params import Params

__all__ = ["SCENARIOS", "PLANTS", "DEFAULT_CONTROLLERS", "Scenario", "Comparison",
           "make_scenario", "compare", "run_compare", "write_outputs", "print_table",
           "format_table", "markdown_table", "TARGET_CONTROLLERS"]

SCENARIOS = ("slew", "spinup")
PLANTS = ("foam", "cfoam")
DEFAULT_CONTROLLERS = ("openloop", "pd", "lqr", "lqg", "mpc")
#: The controllers held to the targets of the slew (PD is only reported).
TARGET_CONTROLLERS = ("lqr", "lqg", "mpc")


def _number(name, value, unit, positive=True):
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)) \
            or not math.isfinite(value) or (positive and not value > 0):
        raise ParameterError(f"{name} must be a finite number{' > 0' if positive else ''} "
                             f"[{unit}], got {value!r}")
    return float(value)


@dataclass(frozen=True, eq=False)
class Scenario:
    """A closed-loop task: reference, torque budget, times and design point.

    Attributes
    ----------
    name : {"slew", "spinup"}
    plant : {"foam", "cfoam"}
    params : Params
    tau_max : float
        Torque budget [N m] (= Eq. 44's tau_m in the slew).
    t_f : float
        Maneuver time [s].
    t_end : float
        Simulated time [s].
    dt : float
        Controller sample time [s].
    design_spin : float
        Spin rate of the SFOAM linearisation [rad/s].
    target : float
        Slew angle Theta [rad] or final rate w_f [rad/s].
    reference : controllers.Reference
        Hub reference and feedforward torque of the feedback controllers.
    description : str
    """

    name: str
    plant: str
    params: Params
    tau_max: float
    t_f: float
    t_end: float
    dt: float
    design_spin: float
    target: float
    reference: object
    description: str

    def to_dict(self) -> dict:
        """Plain-data summary (JSON-ready)."""
        return {"scenario": self.name, "plant": self.plant, "tau_max_nm": self.tau_max,
                "tf_s": self.t_f, "t_end_s": self.t_end, "dt_s": self.dt,
                "design_spin_rad_s": self.design_spin,
                ("slew_angle_rad" if self.name == "slew" else "final_rate_rad_s"): self.target,
                "reference": self.reference.description, "params": self.params.to_dict(),
                "description": self.description}


def make_scenario(scenario: str = "slew", *, plant: str = "cfoam", params: Params | None = None,
                  tau_max: float = 200.0, t_f: float = 10.0, t_end: float = 30.0,
                  dt: float = 0.01, w_f: float = 3.0, flatness: float = 3.0,
                  preview_s: float = 2.0) -> Scenario:
    """Build a :class:`Scenario` (validating every setting).

    Parameters
    ----------
    scenario : {"slew", "spinup"}
    plant : {"foam", "cfoam"}
    params : Params, optional
        Default: Table 1 (m_t = 0.1 kg at the tip).
    tau_max : float
        Torque budget [N m], > 0 (the slew's Eq. 44 amplitude).
    t_f : float
        Maneuver time [s], > 0.
    t_end : float
        Simulated time [s]; must exceed ``t_f + 5`` (the residual window).
    dt : float
        Controller sample time [s], > 0.
    w_f : float
        Spin-up final rate [rad/s] (spinup only).
    flatness : float
        Shape of the slew reference (see :func:`controllers.slew_reference`).
    preview_s : float
        Reference tabulated this long beyond ``t_end`` (MPC preview) [s].

    Returns
    -------
    Scenario
    """
    from controllers import slew_reference, spinup_reference
    if scenario not in SCENARIOS:
        raise ParameterError(f"scenario must be one of {', '.join(SCENARIOS)}, got {scenario!r}")
    if plant not in PLANTS:
        raise ParameterError(f"plant must be one of {', '.join(PLANTS)}, got {plant!r}")
    params = params if params is not None else Params()
    if not isinstance(params, Params):
        raise ParameterError(f"params must be a Params, got {type(params).__name__}")
    tau_max = _number("tau_max", tau_max, "N m")
    t_f = _number("tf", t_f, "s")
    t_end = _number("t_end", t_end, "s")
    dt = _number("dt", dt, "s")
    if t_end <= t_f + 5.0:
        raise ParameterError(f"t_end must exceed tf + 5 s = {t_f + 5:g} s (the residual-vibration "
                             f"window starts there), got {t_end:g} s")
    if dt > t_f / 10:
        raise ParameterError(f"dt must be at most tf/10 = {t_f / 10:g} s, got {dt:g} s")
    J = params.total_inertia
    horizon_end = t_end + preview_s
    if scenario == "slew":
        theta = tau_max * t_f ** 2 / (2 * math.pi * J)
        ref = slew_reference(theta, t_f, J, tau_max, dt, horizon_end, flatness=flatness)
        return Scenario("slew", plant, params, tau_max, t_f, t_end, dt, 0.0, theta, ref,
                        f"rest-to-rest slew by Theta = tau_m tf^2/(2 pi J_total) = {theta:.4f} rad "
                        f"(tau_m = {tau_max:g} N m, tf = {t_f:g} s, J_total = {J:.4g} kg m^2)")
    w_f = _number("wf", w_f, "rad/s", positive=False)
    ref = spinup_reference(w_f, t_f, J, dt, horizon_end, tau_max=tau_max)
    return Scenario("spinup", plant, params, tau_max, t_f, t_end, dt, w_f, w_f, ref,
                    f"spin-up to {w_f:g} rad/s in tf = {t_f:g} s (Eq. 43), then hold; "
                    f"design model linearised at {w_f:g} rad/s")


def _parse_controllers(controllers) -> tuple:
    from controllers import CONTROLLERS
    if isinstance(controllers, str):
        names = [c.strip().lower() for c in controllers.split(",") if c.strip()]
    else:
        names = [str(c).strip().lower() for c in controllers]
    if not names:
        raise ParameterError(f"controllers must name at least one of {', '.join(CONTROLLERS)}")
    bad = [n for n in names if n not in CONTROLLERS]
    if bad:
        raise ParameterError(f"controllers: unknown {', '.join(map(repr, bad))}; allowed: "
                             f"{', '.join(CONTROLLERS)}")
    if len(set(names)) != len(names):
        raise ParameterError(f"controllers: each may appear once, got {','.join(names)}")
    return tuple(names)


def _default_settings(name: str, sc: Scenario, horizon: int, solver: str):
    from controllers import (LQGSettings, LQRSettings, MPCSettings, OpenLoopSettings,
                             PDSettings)
    if name == "openloop":
        if sc.name == "slew":
            return OpenLoopSettings("eq44", sc.tau_max, sc.t_f)
        return OpenLoopSettings("feedforward", sc.tau_max, sc.t_f)
    if name == "pd":
        return PDSettings(tau_max=sc.tau_max)
    if name == "lqr":
        return LQRSettings(tau_max=sc.tau_max)
    if name == "lqg":
        return LQGSettings(tau_max=sc.tau_max)
    return MPCSettings(tau_max=sc.tau_max, horizon=horizon, solver=solver)


@dataclass
class Comparison:
    """Everything one comparison produced.

    Attributes
    ----------
    scenario : Scenario
    results : dict
        Controller name -> :class:`~hubbeam_ctrl.closedloop.ClosedLoopResult`.
    metrics : dict
        Controller name -> metrics dictionary (see :data:`hubbeam_ctrl.metrics.METRIC_UNITS`).
    wall_s : float
        Wall time of the comparison (design and simulation, without writing) [s].
    """

    scenario: Scenario
    results: dict
    metrics: dict
    wall_s: float = 0.0
    paths: dict = field(default_factory=dict)


def compare(plant: str = "cfoam", scenario: str = "slew", controllers=DEFAULT_CONTROLLERS, *,
            params: Params | None = None, tau_max: float = 200.0, t_f: float = 10.0,
            t_end: float = 30.0, dt: float = 0.01, w_f: float = 3.0,
            design_modes: int | None = None, horizon: int = 50, solver: str = "daqp",
            settings: dict | None = None, sim_settings: ClosedLoopSettings | None = None,
            progress: bool = False) -> Comparison:
    """Design the controllers on SFOAM and run them on the nonlinear plant.

    Parameters
    ----------
    plant : {"foam", "cfoam"}
    scenario : {"slew", "spinup"}
    controllers : str or sequence of str
        Any of ``openloop, pd, lqr, lqg, mpc`` (comma-separated string accepted).
    params : Params, optional
    tau_max : float
        Torque budget [N m].
    t_f, t_end, dt : float
        Maneuver time, simulated time and sample time [s].
    w_f : float
        Spin-up final rate [rad/s].
    design_modes : int, optional
        Transverse modes of the design model (default: the plant's).
    horizon : int
        MPC horizon [samples].
    solver : str
        MPC QP solver (see :data:`controllers.QP_SOLVERS`).
    settings : dict, optional
        Controller name -> settings object, replacing the defaults.
    sim_settings : ClosedLoopSettings, optional
        Plant integration and sensor settings (its ``dt`` is replaced by ``dt``).
    progress : bool
        Print one line per controller on stderr.

    Returns
    -------
    Comparison
    """
    from controllers import DesignModel, make_controller
    start = time.perf_counter()
    names = _parse_controllers(controllers)
    sc = make_scenario(scenario, plant=plant, params=params, tau_max=tau_max, t_f=t_f,
                       t_end=t_end, dt=dt, w_f=w_f)
    if design_modes is not None and (isinstance(design_modes, bool) or not isinstance(design_modes, int)
                                     or not 1 <= design_modes <= sc.params.n_transverse):
        raise ParameterError(f"design_modes must be an integer in 1..{sc.params.n_transverse} "
                             f"(the plant's transverse modes), got {design_modes!r}")
    settings = dict(settings or {})
    unknown = sorted(set(settings) - set(names))
    if unknown:
        raise ParameterError(f"settings given for controllers not run: {', '.join(unknown)}")
    design = DesignModel.build(sc.params, sc.design_spin, sc.dt, design_modes)
    sim = sim_settings or ClosedLoopSettings()
    if sim.dt != sc.dt:
        import dataclasses
        sim = dataclasses.replace(sim, dt=sc.dt)
    model = build_model(sc.plant, sc.params)
    ref = sc.reference
    results, metrics = {}, {}
    for name in names:
        st = settings.get(name) or _default_settings(name, sc, horizon, solver)
        ctrl = make_controller(name, design, st, ref)
        res = simulate_closed_loop(model, ctrl, sc.t_end, settings=sim,
                                   reference=(ref.theta_at, ref.theta_dot_at))
        results[name] = res
        metrics[name] = closed_loop_metrics(res, sc.t_f, tau_max=sc.tau_max)
        metrics[name]["scenario"] = sc.name
        if progress:
            m = metrics[name]
            print(f"compare {sc.plant}/{sc.name}: {name:8s} residual {m['residual_tip_max_m']:.3e} m, "
                  f"run {res.wall_s:.1f} s" + ("" if m["completed"] else f"  [{res.message}]"),
                  file=sys.stderr)
    if "openloop" in metrics:
        base = metrics["openloop"]["residual_tip_max_m"]
        for m in metrics.values():
            m["residual_pct_of_openloop"] = (100.0 * m["residual_tip_max_m"] / base
                                             if base and math.isfinite(base) else float("nan"))
    return Comparison(sc, results, metrics, time.perf_counter() - start)


# -- output -----------------------------------------------------------------------------------
#: Columns of metrics.csv, in order.
CSV_FIELDS = (["controller", "plant", "scenario"] + list(METRIC_UNITS)
              + ["residual_pct_of_openloop", "within_torque_limit", "completed", "qp_solves",
                 "qp_fallbacks", "fallback_fraction", "wall_s", "message"])


def _clean(value):
    if isinstance(value, (np.floating, np.integer)):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _json_metrics(metrics: dict) -> list:
    return [{k: _clean(v) for k, v in m.items()} for m in metrics.values()]


def _targets(comparison: Comparison) -> list:
    """Rows ``(controller, residual_ok, torque_ok, angle_ok)`` of the slew targets."""
    m = comparison.metrics
    rows = []
    base = m.get("openloop", {}).get("residual_tip_max_m")
    for name, mm in m.items():
        res_ok = (base is not None and mm["residual_tip_max_m"] <= 0.01 * base) if name != "openloop" else None
        rows.append((name, res_ok, mm.get("within_torque_limit"),
                     abs(mm["final_angle_error_rad"]) <= 1e-3))
    return rows


def write_outputs(comparison: Comparison, out_dir) -> dict:
    """Write metrics.csv, metrics.json, tip_deflection.png, hub_angle.png, torque.png, report.md.

    Parameters
    ----------
    comparison : Comparison
    out_dir : str or Path
        Created if missing (its parent must exist).

    Returns
    -------
    dict
        File kind -> Path.
    """
    from .plots import save_figure
    from .plots_closedloop import plot_hub_angle, plot_torque, plot_tip_deflection
    out = Path(out_dir)
    if not out.parent.is_dir():
        raise ParameterError(f"out: folder {out.parent} does not exist")
    out.mkdir(exist_ok=True)
    sc, metrics, results = comparison.scenario, comparison.metrics, comparison.results
    paths = {}
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=CSV_FIELDS, extrasaction="ignore", lineterminator="\n")
    writer.writeheader()
    for m in metrics.values():
        writer.writerow({k: ("" if _clean(m.get(k)) is None else _clean(m.get(k))) for k in CSV_FIELDS})
    paths["csv"] = atomic_write_text(out / "metrics.csv", buf.getvalue())
    paths["json"] = atomic_write_text(out / "metrics.json",
                                      json.dumps(_json_metrics(metrics), indent=2) + "\n")
    title = f"{sc.plant.upper()}, {sc.name}: "
    figs = {
        "tip_deflection.png": plot_tip_deflection(results, sc.t_f, sc.t_f + 5.0,
                                                  title + "tip deflection (shaded: residual window)"),
        "hub_angle.png": plot_hub_angle(results, sc.t_f, title + "hub angle and error vs reference"),
        "torque.png": plot_torque(results, sc.tau_max, title + "hub torque (dotted: +-tau_max)"),
    }
    for fname, fig in figs.items():
        paths[fname] = save_figure(fig, out / fname)
    paths["report"] = atomic_write_text(out / "report.md", _report(comparison))
    comparison.paths = paths
    return paths


def _report(comparison: Comparison) -> str:
    sc = comparison.scenario
    lines = [f"# Closed-loop comparison: {sc.name} on {sc.plant.upper()}", "",
             f"- Scenario: {sc.description}.",
             f"- Feedback reference: {sc.reference.description}.",
             f"- Torque budget tau_max = {sc.tau_max:g} N m; sample time {sc.dt * 1e3:g} ms "
             f"(zero-order hold); t_end = {sc.t_end:g} s.",
             f"- Design model: SFOAM linearised at {sc.design_spin:g} rad/s; plant {sc.plant.upper()} "
             f"with {sc.params.n_axial} axial and {sc.params.n_transverse} transverse modes, "
             f"m_t = {sc.params.m_t:g} kg.",
             f"- Residual vibration: |v_tip| from tf + 5 s = {sc.t_f + 5:g} s to the end. "
             f"Settling: hub-angle error within 1 mrad and |v_tip| within 1 mm for good.",
             f"- Wall time of the comparison: {comparison.wall_s:.1f} s.", "",
             markdown_table(comparison.metrics), ""]
    if sc.name == "slew" and "openloop" in comparison.metrics:
        lines += ["## Targets (slew)", "",
                  "| controller | residual <= 1 % of open loop | abs(tau) <= tau_max | final error <= 1 mrad |",
                  "|---|---|---|---|"]
        yes = {True: "yes", False: "**no**", None: "-"}
        for name, r_ok, t_ok, a_ok in _targets(comparison):
            note = " (reported only)" if name == "pd" else ""
            lines.append(f"| {name}{note} | {yes[r_ok]} | {yes[t_ok]} | {yes[a_ok]} |")
        lines.append("")
    notes = [f"- {name}: {m['message']}" for name, m in comparison.metrics.items() if not m["completed"]]
    notes += [f"- {name}: {m['qp_fallbacks']} of {m['qp_solves']} QPs failed and fell back to LQR"
              for name, m in comparison.metrics.items() if m.get("qp_fallbacks")]
    if notes:
        lines += ["## Notes", ""] + notes + [""]
    lines += ["## Plots", "", "![tip deflection](tip_deflection.png)", "",
              "![hub angle](hub_angle.png)", "", "![torque](torque.png)", ""]
    return "\n".join(lines)


_TABLE = [
    ("controller", "controller", "{}"),
    ("peak_tip_m", "peak v_tip m", "{:.4f}"),
    ("residual_tip_max_m", "resid max m", "{:.2e}"),
    ("residual_tip_rms_m", "resid rms m", "{:.2e}"),
    ("residual_pct_of_openloop", "% of OL", "{:.3g}"),
    ("angle_error_tf_rad", "err(tf) rad", "{:.2e}"),
    ("final_angle_error_rad", "err(end) rad", "{:.2e}"),
    ("settling_time_s", "settle s", "{:.2f}"),
    ("peak_torque_nm", "peak tau Nm", "{:.1f}"),
    ("torque_squared_integral_n2m2s", "int tau^2", "{:.3g}"),
    ("step_time_median_ms", "step med ms", "{:.3f}"),
    ("step_time_p99_ms", "step p99 ms", "{:.3f}"),
]


def _cells(m: dict) -> list:
    cells = []
    for key, _, fmt in _TABLE:
        v = _clean(m.get(key))
        cells.append("-" if v is None else (fmt.format(v) if not isinstance(v, str) else v))
    if not m.get("completed", True):
        cells[0] += " (stopped)"
    if m.get("qp_fallbacks"):
        cells[0] += f" [{m['qp_fallbacks']} fb]"
    return cells


def format_table(metrics: dict) -> str:
    """The metrics as an aligned plain-text table."""
    rows = [[h for _, h, _ in _TABLE]] + [_cells(m) for m in metrics.values()]
    widths = [max(len(r[i]) for r in rows) for i in range(len(_TABLE))]
    return "\n".join("  ".join(c.rjust(w) if i else c.ljust(w) for i, (c, w) in enumerate(zip(r, widths)))
                     for r in rows)


def markdown_table(metrics: dict) -> str:
    """The metrics as a Markdown table."""
    head = [h for _, h, _ in _TABLE]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(_cells(m)) + " |" for m in metrics.values()]
    return "\n".join(lines)


def print_table(metrics, file=None) -> None:
    """Print the metrics of :func:`run_compare` (or a :class:`Comparison`) as a table."""
    if isinstance(metrics, Comparison):
        metrics = metrics.metrics
    print(format_table(metrics), file=file or sys.stdout)


def run_compare(plant: str = "cfoam", scenario: str = "slew", controllers=DEFAULT_CONTROLLERS,
                out_dir=None, **options) -> dict:
    """Run :func:`compare` and write its outputs to ``out_dir`` (if given).

    Parameters
    ----------
    plant : {"foam", "cfoam"}
    scenario : {"slew", "spinup"}
    controllers : str or sequence of str
    out_dir : str or Path, optional
        Folder for metrics.csv, metrics.json, the PNG plots and report.md.
    **options
        Keyword arguments of :func:`compare` (``params``, ``tau_max``, ``t_f``, ``t_end``,
        ``dt``, ``w_f``, ``design_modes``, ``horizon``, ``solver``, ``settings``...).

    Returns
    -------
    dict
        Controller name -> metrics (see :data:`hubbeam_ctrl.metrics.METRIC_UNITS`), in the
        order run; pass it to :func:`print_table`.
    """
    comparison = compare(plant, scenario, controllers, **options)
    if out_dir is not None:
        write_outputs(comparison, out_dir)
    return comparison.metrics
