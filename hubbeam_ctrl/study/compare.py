"""Closed-loop comparison of the controllers on FOAM or CFOAM (``hubbeam compare``).

The top layer of the toolbox: it builds a scenario (reference, design model), designs
each controller on SFOAM, runs it on the nonlinear plant with
:func:`~hubbeam_ctrl.sim.closedloop.simulate_closed_loop`, computes the metrics of
:mod:`hubbeam_ctrl.study.metrics` and writes ``metrics.csv``, ``metrics.json``, three PNG
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
>>> from hubbeam_ctrl.study import run_compare, print_table
>>> m = run_compare(plant="foam", controllers="openloop,lqr", out_dir=None)  # doctest: +SKIP
>>> print_table(m)                                                           # doctest: +SKIP
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time
from dataclasses import dataclass, field

from controllers import (
    CONTROLLERS,
    DesignModel,
    LQGSettings,
    LQRSettings,
    MPCSettings,
    OpenLoopSettings,
    PDSettings,
    make_controller,
)
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.models import build_model
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.sim.closedloop import ClosedLoopSettings, simulate_closed_loop
from hubbeam_ctrl.study.metrics import closed_loop_metrics
from hubbeam_ctrl.study.report import write_outputs
from hubbeam_ctrl.study.scenarios import Scenario, make_scenario

__all__ = ["DEFAULT_CONTROLLERS", "TARGET_CONTROLLERS", "Comparison", "compare", "run_compare"]

DEFAULT_CONTROLLERS = ("openloop", "pd", "lqr", "lqg", "mpc")
#: The controllers held to the targets of the slew (PD is only reported).
TARGET_CONTROLLERS = ("lqr", "lqg", "mpc")


def _parse_controllers(controllers) -> tuple:
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
    if name == "openloop":
        if sc.name == "slew":
            return OpenLoopSettings("eq44", sc.baseline_tau_m, sc.t_f)
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
        Controller name -> :class:`~hubbeam_ctrl.sim.results.Result` (closed loop).
    metrics : dict
        Controller name -> metrics dictionary (see :data:`hubbeam_ctrl.study.metrics.METRIC_UNITS`).
    wall_s : float
        Wall time of the comparison (design and simulation, without writing) [s].
    """

    scenario: Scenario
    results: dict
    metrics: dict
    wall_s: float = 0.0
    paths: dict = field(default_factory=dict)


def compare(plant: str = "cfoam", scenario="slew", controllers=DEFAULT_CONTROLLERS, *,
            params: Params | None = None, tau_max: float | None = None, t_f: float = 10.0,
            t_end: float = 30.0, dt: float = 0.01, w_f: float = 3.0, slew_angle: float | None = None,
            design_modes: int | None = None, horizon: int = 50, solver: str = "daqp",
            settings: dict | None = None, sim_settings: ClosedLoopSettings | None = None,
            progress: bool = False) -> Comparison:
    """Design the controllers on SFOAM and run them on the nonlinear plant.

    Parameters
    ----------
    plant : {"foam", "cfoam"}
    scenario : {"slew", "spinup"} or Slew or SpinUp
        Scenario name or task in physical terms (see :func:`make_scenario`).
    controllers : str or sequence of str
        Any of ``openloop, pd, lqr, lqg, mpc`` (comma-separated string accepted).
    params : Params, optional
    tau_max : float, optional
        Torque budget [N m], at most ``params.tau_max`` (default: the motor's limit).
    t_f, t_end, dt : float
        Maneuver time, simulated time and sample time [s].
    w_f : float
        Spin-up final rate [rad/s].
    slew_angle : float, optional
        Slew angle [rad] (default: the Eq. 44 angle of ``tau_max`` and ``t_f``).
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
    start = time.perf_counter()
    names = _parse_controllers(controllers)
    sc = make_scenario(scenario, plant=plant, params=params, tau_max=tau_max, t_f=t_f,
                       t_end=t_end, dt=dt, w_f=w_f, slew_angle=slew_angle)
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
        Controller name -> metrics (see :data:`hubbeam_ctrl.study.metrics.METRIC_UNITS`), in the
        order run; pass it to :func:`print_table`.
    """
    comparison = compare(plant, scenario, controllers, **options)
    if out_dir is not None:
        write_outputs(comparison, out_dir)
    return comparison.metrics
