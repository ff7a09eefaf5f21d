"""The exact-beam plant (issue 23): 30 s closed loops on ANCF against FOAM in the same run.

Prints one JSON object and writes it to benchmarks/results/bench_exact.json. Run:
``.venv/bin/python benchmarks/bench_exact.py [--controllers lqr,pd] [--t-end 30] [--sections spinup]``.

Also the Fig. 6 spin-up over the reference's full 50 s (``spinup``): the exact plant through
``simulate_exact`` against ``hubbeam_ctrl/data/spinup_w5_tf30_ancf.csv`` (checked equal to
``../shared/reference/``), with FOAM against the same curve in the same run; the errors over the
first 30 s and over 50 s, relative to the curve's peak.

For each controller of the default slew (Table 1's beam): the comparison on FOAM (the named
alternative) and on ``plant="ancf"`` (Exudyn, the element and step rules), wall time of each
run, verdicts, peak tip deflection and residual RMS, and their relative differences. Also the
Eq. 44 open loop (200 N m, 10 s, continuous torque): peak and residual (max |v_tip| over
10-30 s... here the last 10 s of the run) of the exact beam against FOAM.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import time
from importlib.resources import files

import numpy as np

from hubbeam_ctrl import Params, SpinUp, TorquePulse, simulate
from hubbeam_ctrl.core.fileio import atomic_write_text
from hubbeam_ctrl.exact import ExactBeamPlant, element_rule
from hubbeam_ctrl.sim import simulate_exact
from hubbeam_ctrl.study import compare
from hubbeam_ctrl.study.compare_values import CompareSettings, PlantChoice, RunChoice


def eq44(t_end: float) -> dict:
    """Eq. 44 open loop on both plants (10-mode FOAM by IDAS, exact beam by the rule's 32 elements)."""
    params = Params(n_transverse=10)
    pulse = TorquePulse()
    t0 = time.perf_counter()
    foam = simulate("foam", pulse, t_end, params=params)
    t_foam = time.perf_counter() - t0
    plant = ExactBeamPlant(params, n_elements=element_rule(10), dt=0.01, substeps=30, torque_function=pulse)
    x = plant.initial_state()
    tips = [0.0]
    t0 = time.perf_counter()
    for _ in range(int(round(t_end / 0.01))):
        x = plant.step(x, 0.0)
        tips.append(plant.outputs["v_tip"])
    t_exact = time.perf_counter() - t0
    tips = np.array(tips)
    t = 0.01 * np.arange(len(tips))
    late = t >= 10.0
    out = {"peak_foam_m": float(np.max(np.abs(foam.v_tip))), "peak_exact_m": float(np.max(np.abs(tips))),
           "residual_foam_m": float(np.max(np.abs(foam.v_tip[foam.t >= 10.0]))),
           "residual_exact_m": float(np.max(np.abs(tips[late]))), "wall_foam_s": t_foam, "wall_exact_s": t_exact}
    out["peak_rel_diff"] = out["peak_exact_m"] / out["peak_foam_m"] - 1
    out["residual_rel_diff"] = out["residual_exact_m"] / out["residual_foam_m"] - 1
    return out


def spinup(t_end: float = 50.0) -> dict:
    """Fig. 6 spin-up (Table 1's beam without tip mass, w_f = 5 rad/s, t_f = 30 s, prescribed hub) on the
    exact plant (simulate_exact: 10 modes, 32 elements, FOAM's step rule at the reference's 0.05 s sampling)
    against the exact-beam reference curve; FOAM (IDAS, 10 modes) against the same curve in the same run."""
    ref = np.loadtxt(files("hubbeam_ctrl.data").joinpath("spinup_w5_tf30_ancf.csv"), delimiter=",", skiprows=1)
    shared = pathlib.Path(__file__).resolve().parents[1].parent / "shared" / "reference" / "spinup_w5_tf30_ancf.csv"
    same_as_shared = bool(shared.exists() and np.array_equal(np.loadtxt(shared, delimiter=",", skiprows=1), ref))
    params = Params(m_t=0.0, n_transverse=10)
    spin = SpinUp(w_f=5.0, t_f=30.0)
    t0 = time.perf_counter()
    ex = simulate_exact(spin, t_end, params=params, dt=0.05)
    wall_exact = time.perf_counter() - t0
    t0 = time.perf_counter()
    fo = simulate("foam", spin, t_end, params=params, dt=0.05)
    wall_foam = time.perf_counter() - t0
    keep = ref[:, 0] <= t_end + 1e-9
    r = ref[keep]
    assert np.allclose(ex.t, r[:, 0]) and np.allclose(fo.t, r[:, 0])
    peak_ref = float(np.max(np.abs(r[:, 3])))
    out = {"reference_same_as_shared": same_as_shared, "t_end_s": t_end, "substeps": ex.settings["substeps"],
           "step_s": ex.settings["step_s"], "elements": ex.settings["plant_elements"], "wall_exact_s": wall_exact,
           "wall_foam_s": wall_foam, "peak_ref_m": peak_ref}
    for name, res in (("exact", ex), ("foam", fo)):
        for window in (30.0, t_end):
            w = r[:, 0] <= window + 1e-9
            out[f"{name}_max_err_over_peak_0_{window:g}s"] = float(np.max(np.abs(res.v_tip[w] - r[w, 3])) / peak_ref)
        out[f"{name}_peak_m"] = float(np.max(np.abs(res.v_tip)))
        out[f"{name}_peak_rel_err"] = out[f"{name}_peak_m"] / peak_ref - 1
        late = r[:, 0] >= t_end - 10.0 - 1e-9
        out[f"{name}_residual_m"] = float(np.max(np.abs(res.v_tip[late])))
        out[f"{name}_max_u_tip_err_m"] = float(np.max(np.abs(res.u_tip - r[:, 4])))
    out["residual_ref_m"] = float(np.max(np.abs(r[r[:, 0] >= t_end - 10.0 - 1e-9, 3])))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--controllers", default=None, help="comma-separated (default: the slew's defaults)")
    ap.add_argument("--t-end", type=float, default=30.0)
    ap.add_argument("--skip-eq44", action="store_true")
    ap.add_argument("--sections", default="slew,eq44,spinup",
                    help="comma-separated of slew, eq44, spinup (default all; a subset writes "
                         "bench_exact_<sections>.json)")
    args = ap.parse_args()
    sections = [x.strip() for x in args.sections.split(",") if x.strip()]
    if args.skip_eq44 and "eq44" in sections:
        sections.remove("eq44")
    names = args.controllers.split(",") if args.controllers else None
    out = {"t_end_s": args.t_end}
    if "spinup" in sections:
        out["spinup"] = spinup()
    runs = {}
    for plant in (("foam", "ancf") if "slew" in sections else ()):
        t0 = time.perf_counter()
        comp = compare(None, "slew", names, CompareSettings(plant=PlantChoice(plant), run=RunChoice(t_end=args.t_end)))
        runs[plant] = {"wall_s": time.perf_counter() - t0,
                       "controllers": {n: {"verdict": m["verdict"], "peak_tip_m": m["peak_tip_m"],
                                           "residual_tip_rms_m": m["residual_tip_rms_m"],
                                           "run_wall_s": comp.results[n].wall_s}
                                       for n, m in comp.metrics.items()}}
    if runs:
        out["runs"] = runs
    out["agreement"] = {} if not runs else {
        n: {"same_verdict": runs["ancf"]["controllers"][n]["verdict"] == c["verdict"],
                            "residual_rel_diff": runs["ancf"]["controllers"][n]["residual_tip_rms_m"]
                            / c["residual_tip_rms_m"] - 1,
                            "peak_rel_diff": runs["ancf"]["controllers"][n]["peak_tip_m"] / c["peak_tip_m"] - 1}
                        for n, c in runs["foam"]["controllers"].items()}
    if "eq44" in sections:
        out["eq44"] = eq44(args.t_end)
    text = json.dumps(out, indent=2)
    print(text)
    full = set(sections) == {"slew", "eq44", "spinup"}
    path = pathlib.Path(__file__).parent / "results" / ("bench_exact.json" if full else
                                                        f"bench_exact_{'_'.join(sections)}.json")
    atomic_write_text(path, text + "\n")


if __name__ == "__main__":
    main()
