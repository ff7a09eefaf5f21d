"""Issue 40's table, first slice: slews at 1.1, 1.2 and 1.3 T* (each beam's own
time-optimal slew) with the NMPC (controllers.nmpc), the linear MPC and LQR, and the NMPC's step time.

Prints one JSON object (``--out FILE`` also writes it). Run:
``.venv/bin/python benchmarks/bench_nmpc.py --out benchmarks/results/bench_nmpc.json`` (and
``--backend compiled --out benchmarks/results/bench_nmpc_compiled.json``: the step as its generated C).

Each case is ``compare`` on FOAM (the evaluation plant's modes, every option default) with the
task ``Slew(pi/2, factor * T*)``, every controller tracking the beam's own minimum-vibration slew
in ``t_f`` (``--reference optimal``, the default: ``hubbeam_ctrl.limit.min_vibration_slew`` on the
nonlinear model with the rig's drive, what ``hubbeam optimal`` plans) or the task's slew planned on
the linear design model (``--reference task``: at 1.1 T* on ``servo_link`` it leaves the hub 0.056
rad short at t_f, a plan the nonlinear beam with 30 % of L of deflection does not follow).
Reported per controller: verdict, settling time after t_f in first-mode periods (issue 40 asks
for at most one), residual tip vibration in % of L (at most 0.1 %), the final angle error
against the task's band, the peak torque against the limit; for the NMPC the median and 99th
percentile of its step's wall time against the sample time.
"""

from __future__ import annotations

import math
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from benchjson import bench_parser, emit  # noqa: E402

from controllers.scaling import first_mode  # noqa: E402
from hubbeam_ctrl import Params  # noqa: E402
from hubbeam_ctrl.core.errors import ParameterError  # noqa: E402
from hubbeam_ctrl.limit import time_optimal_slew  # noqa: E402
from hubbeam_ctrl.study import Slew, compare  # noqa: E402
from hubbeam_ctrl.study.compare_values import CompareSettings, DesignChoice

LAB = Params(L=1, rho=2700, A=9e-5, E=69e9, I=6.75e-11, J_h=0.02, r=0.05, m_t=0.05, tau_max=1.5)
BEAMS = {"table1": Params(), "lab": LAB, "servo_link": "servo_link"}
#: Slew angles [rad]: 90 degrees on every beam (on servo_link its DC drive in volts, friction,
#: encoder and half a sample of delay; LQR and MPC run through the rig's filter and volts stage, the
#: NMPC through the filter with the drive, viscous friction, current limit and delay in its
#: prediction, commanding volts: controllers.nmpc_drive). Table 1's beam turned 1 rad before the
#: controllers tracked the optimal plan: its 90 degrees at 1.1 T* is shorter than the rigid Eq. 44
#: profile can do, which the task reference's torque check refuses.
ANGLES = {"table1": math.pi / 2, "lab": math.pi / 2, "servo_link": math.pi / 2}


def _beam(name: str):
    """The beam's Params, or the preset rig."""
    from hubbeam_ctrl.plant.rig import load_rig
    return load_rig(BEAMS[name]) if isinstance(BEAMS[name], str) else BEAMS[name]


def _inner(ctrl):
    """The NMPC inside the rig's filter and drive stages."""
    while not hasattr(ctrl, "step_times_s") and hasattr(ctrl, "inner"):
        ctrl = ctrl.inner
    return ctrl
CONTROLLERS = ("lqr", "mpc", "nmpc")


def case(beam: str, factor: float, t_opt: float, horizon: int | None = None, backend: str = "vm",
         reference: str = "optimal") -> dict:
    params = _beam(beam)
    task = Slew(ANGLES[beam], factor * t_opt)
    t0 = time.perf_counter()
    settings = None
    if horizon is not None or backend != "vm":      # the NMPC's horizon or backend other than its default
        from controllers import NMPCSettings
        from hubbeam_ctrl.study.scenarios import make_scenario
        sc = make_scenario(task, params=getattr(params, "plant_params", params), t_end=None, reference=reference)
        own = NMPCSettings.for_scenario(sc).replace(backend=backend)
        settings = {"nmpc": own if horizon is None else own.replace(horizon=horizon)}
    c = compare(params, task, CONTROLLERS, CompareSettings(design=DesignChoice(settings=settings, reference=reference)))
    period = 2 * math.pi / first_mode(c.controllers["lqr"].design)
    out = {"t_f_s": task.duration, "first_period_s": period, "wall_s": time.perf_counter() - t0,
           "settle_angle_rad": c.scenario.bands["settle_angle"], "controllers": {}}
    for name in CONTROLLERS:
        m = c.metrics[name]
        settle = m.get("settling_time_s")
        row = {"verdict": m["verdict"], "settling_time_s": settle,
               "settle_after_tf_periods": None if settle is None else (settle - task.duration) / period,
               "residual_pct_of_L": m.get("residual_pct_of_L"), "final_angle_error_rad": m["final_angle_error_rad"],
               "peak_torque_nm": m["peak_torque_nm"], "tau_max_nm": getattr(params, "plant_params", params).tau_max,
               "peak_command": m["peak_command"], "command_unit": m.get("command_unit", "N m"),
               "within_drive_limits": bool(m["within_drive_limits"]),
               "peak_current_a": m.get("peak_current_a"),
               "loop_spectral_radius": m.get("loop_spectral_radius")}
        if name == "nmpc":
            nmpc = _inner(c.controllers[name])
            steps = np.asarray(nmpc.step_times_s)
            row.update(step_median_s=float(np.median(steps)), step_p99_s=float(np.percentile(steps, 99)),
                       dt_s=float(c.scenario.dt), model_modes=nmpc.model_modes, backend=backend,
                       qp_solver=nmpc.settings.qp_solver, qp_fallbacks=nmpc.stats()["qp_fallbacks"])
            row.update(_function_times(nmpc))
        step = getattr(getattr(params, "sensors", None), "encoder_step", 0.0)
        if step:                 # the final angle in the rig's encoder counts
            row["final_angle_error_counts"] = row["final_angle_error_rad"] / step
        out["controllers"][name] = row
    return out


def _function_times(nmpc, calls: int = 300) -> dict:
    """The step function alone (its generated C with ``backend="compiled"``), without the Python
    around it (reference window, shift, residual gain): median and 99th percentile of ``calls``
    calls on the controller's last plan, its reference window at the run's last sample [s] (at the
    slew's start, against the plan at its end, the QP can fail, which the generated C reports)."""
    x = nmpc._X[:, 0]
    xr, ur = nmpc._reference_window(nmpc._k_last or 0, nmpc.settings.horizon)
    args = (x, nmpc._X, nmpc._U[None, :], xr.T, ur[None, :], nmpc._W[0], nmpc._W[-1],
            *((0.0,) if getattr(nmpc, "_lag", False) else ()))          # the command in flight [V]
    times = []
    for _ in range(calls):
        t0 = time.perf_counter()
        nmpc.step_function(*args)
        times.append(time.perf_counter() - t0)
    return {"function_median_s": float(np.median(times)), "function_p99_s": float(np.percentile(times, 99))}


def table_lines(doc: dict) -> list:
    """docs/limit.md's table of this benchmark (a test keeps the page equal to the JSON)."""
    lines = ["| beam | t_f / T* | controller | verdict | settled after t_f [first-mode periods] | residual [% of L] | "
             "final angle error [rad] (encoder counts) | peak command (current) | step median / p99 [ms] (sample) |",
             "|---|---|---|---|---|---|---|---|---|"]
    for beam, b in doc["beams"].items():
        for f, c in b["factors"].items():
            if "not_run" in c:
                lines.append(f"| {beam} | {f} | - | not run: {c['not_run'].split(' (')[0]} | | | | | |")
                continue
            for name, r in c["controllers"].items():
                after = "-" if r["settle_after_tf_periods"] is None else f"{r['settle_after_tf_periods']:.2f}"
                step = (f"{1e3 * r['step_median_s']:.2f} / {1e3 * r['step_p99_s']:.2f} ({1e3 * r['dt_s']:g})"
                        if "step_median_s" in r else "")
                if r.get("backend") == "compiled" and "function_median_s" in r:     # the C function alone
                    step += f"; C {1e3 * r['function_median_s']:.2f} / {1e3 * r['function_p99_s']:.2f}"
                peak = f"{r['peak_command']:.4g} {r['command_unit']}"
                if r.get("peak_current_a") is not None:
                    peak += f", {r['peak_current_a']:.3g} A"
                angle = f"{r['final_angle_error_rad']:.2g}"
                if "final_angle_error_counts" in r:
                    angle += f" ({r['final_angle_error_counts']:+.1f} counts)"
                lines.append(f"| {beam} | {f} | {name} | {r['verdict']} | {after} | {r['residual_pct_of_L']:.3g} | "
                             f"{angle} | {peak} | {step} |")
    return lines


def prose_numbers(vm: dict, compiled: dict) -> dict:
    """The numbers docs/limit.md's prose quotes, as it prints them, from the two runs' JSON (the step on
    CasADi's virtual machine and as generated C); a test keeps the page equal to them."""
    def rows(doc, name="nmpc"):
        return [(beam, f, c["controllers"][name]) for beam, b in doc["beams"].items()
                for f, c in b["factors"].items() if "not_run" not in c]

    def span(values, fmt):
        lo, hi = min(values), max(values)
        return format(lo, fmt) if format(lo, fmt) == format(hi, fmt) else f"{format(lo, fmt)}-{format(hi, fmt)}"
    nm = rows(vm)
    servo_vm = [r["step_median_s"] for beam, _, r in nm if beam == "servo_link"]
    servo_c = [r["step_median_s"] for beam, _, r in rows(compiled) if beam == "servo_link"]
    return {"NMPC_SETTLE_MAX": f"{max(r['settle_after_tf_periods'] for _, _, r in nm):.2f}",
            "NMPC_RESID_MAX": f"{max(r['residual_pct_of_L'] for _, _, r in nm):.2g}",
            "MPC_LAB11": f"{vm['beams']['lab']['factors']['1.1']['controllers']['mpc']['settle_after_tf_periods']:.2f}",
            "NMPC_VM_SERVO": span([1e3 * t for t in servo_vm], ".2f"),
            "NMPC_VM_SERVO_P99": span([1e3 * r["step_p99_s"] for beam, _, r in nm if beam == "servo_link"], ".2f"),
            "NMPC_C_MED": span([1e3 * r["function_median_s"] for _, _, r in rows(compiled)], ".2f"),
            "NMPC_C_P99": span([1e3 * r["function_p99_s"] for _, _, r in rows(compiled)], ".2f"),
            "NMPC_VM_RATIO": span([a / b for a, b in zip(servo_vm, servo_c)], ".1f")}


def main(argv=None) -> None:
    """Slew each of ``--beams`` with the NMPC and the linear controllers; print the JSON."""
    ap = bench_parser(__doc__)
    ap.add_argument("--beams", default="table1,lab,servo_link")
    ap.add_argument("--factors", default="1.1,1.2,1.3")
    ap.add_argument("--horizon", type=int, default=None, help="the NMPC's horizon [samples] (default its own)")
    ap.add_argument("--backend", default="vm", choices=("vm", "compiled"),
                    help="the NMPC's step on CasADi's virtual machine or as its generated C")
    ap.add_argument("--reference", default="optimal", choices=("optimal", "task"),
                    help="what every controller tracks: the beam's minimum-vibration slew in t_f on its nonlinear "
                         "model (optimal) or the slew planned on the linear design model (task)")
    args = ap.parse_args(argv)
    doc = {"horizon": args.horizon, "backend": args.backend, "reference": args.reference, "beams": {}}
    for beam in args.beams.split(","):
        t_opt = time_optimal_slew(_beam(beam), ANGLES[beam]).duration_s
        doc["beams"][beam] = {"t_opt_s": t_opt, "factors": {}}
        for f in (float(x) for x in args.factors.split(",")):
            try:
                doc["beams"][beam]["factors"][f"{f:g}"] = case(beam, f, t_opt, args.horizon, args.backend,
                                                               args.reference)
            except ParameterError as exc:      # a task the Eq. 44 baseline cannot do: said, not run
                doc["beams"][beam]["factors"][f"{f:g}"] = {"not_run": str(exc)}
    emit(doc, args.out)


if __name__ == "__main__":
    main()
