"""The exact-beam plant (issue 23): 30 s closed loops on ANCF against FOAM in the same run.

Prints one JSON object and writes it to benchmarks/results/bench_exact.json. Run:
``.venv/bin/python benchmarks/bench_exact.py [--controllers lqr,pd] [--t-end 30]``.

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

import numpy as np

from hubbeam_ctrl import Params, TorquePulse, simulate
from hubbeam_ctrl.core.fileio import atomic_write_text
from hubbeam_ctrl.exact import ExactBeamPlant, element_rule
from hubbeam_ctrl.study import compare


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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--controllers", default=None, help="comma-separated (default: the slew's defaults)")
    ap.add_argument("--t-end", type=float, default=30.0)
    ap.add_argument("--skip-eq44", action="store_true")
    args = ap.parse_args()
    names = args.controllers.split(",") if args.controllers else None
    out = {"t_end_s": args.t_end}
    runs = {}
    for plant in ("foam", "ancf"):
        t0 = time.perf_counter()
        comp = compare(plant, "slew", names, t_end=args.t_end)
        runs[plant] = {"wall_s": time.perf_counter() - t0,
                       "controllers": {n: {"verdict": m["verdict"], "peak_tip_m": m["peak_tip_m"],
                                           "residual_tip_rms_m": m["residual_tip_rms_m"],
                                           "run_wall_s": comp.results[n].wall_s}
                                       for n, m in comp.metrics.items()}}
    out["runs"] = runs
    out["agreement"] = {n: {"same_verdict": runs["ancf"]["controllers"][n]["verdict"] == c["verdict"],
                            "residual_rel_diff": runs["ancf"]["controllers"][n]["residual_tip_rms_m"]
                            / c["residual_tip_rms_m"] - 1,
                            "peak_rel_diff": runs["ancf"]["controllers"][n]["peak_tip_m"] / c["peak_tip_m"] - 1}
                        for n, c in runs["foam"]["controllers"].items()}
    if not args.skip_eq44:
        out["eq44"] = eq44(args.t_end)
    text = json.dumps(out, indent=2)
    print(text)
    path = pathlib.Path(__file__).parent / "results" / "bench_exact.json"
    atomic_write_text(path, text + "\n")


if __name__ == "__main__":
    main()
