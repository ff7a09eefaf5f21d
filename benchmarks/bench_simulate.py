"""``hubbeam simulate``'s default torque run: today's IDAS path against the fixed-step path with
an error estimate, in the same run (issue 28, Speed). Prints one JSON object.

Run: ``.venv/bin/python benchmarks/bench_simulate.py [--repeats 5] [--backend auto] [--out F.json]``.

The run is the 30 s Eq. 44 torque pulse (200 N m, t_f = 10 s) on Table 1's beam with 5 + 5
modes, FOAM and CFOAM. For each model, warm (one call first: models, integrators and
compiled functions cached), the median and the fastest of ``--repeats`` calls [s, wall]:

1. ``idas``: :func:`hubbeam_ctrl.sim.simulate.simulate` at its default settings (rtol = atol
   = 1e-8), the path ``hubbeam simulate`` took until issue 28;
2. ``fixed_step_estimated``: :func:`hubbeam_ctrl.sim.estimated.simulate_estimated` (10 ms and
   20 ms runs, tolerance 1e-4), the new default of ``--maneuver torque``;
3. ``fixed_step_estimated_with_outputs``: the same with ``outputs=True`` (energy, momentum and
   ``q_theta`` on every sample, what ``--out`` needs);

and each one's relative error of the peak ``|v_tip|`` against a tight IDAS run (rtol = atol =
1e-11), plus the fixed-step path's own estimate of it. Targets: error <= 1e-4 in <= 0.05 s
(FOAM) and <= 0.1 s (CFOAM).
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import sys
import time

import numpy as np

from hubbeam_ctrl.plant.maneuvers import TorquePulse
from hubbeam_ctrl.sim.estimated import simulate_estimated
from hubbeam_ctrl.sim.simulate import simulate

TARGET_S = {"foam": 0.05, "cfoam": 0.1}


def _timed(fn, repeats):
    fn()                                   # warm-up
    walls, res = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = fn()
        walls.append(time.perf_counter() - t0)
    return res, {"median_s": statistics.median(walls), "fastest_s": min(walls)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--backend", default=None)
    ap.add_argument("--out")
    a = ap.parse_args(argv)
    man = TorquePulse(200.0, 10.0)
    out = {"benchmark": "simulate", "run": "Eq. 44, 200 N m, t_f 10 s, t_end 30 s, Table 1, 5+5 modes",
           "machine": platform.machine(), "python": platform.python_version(), "repeats": a.repeats, "models": {}}
    for model in ("foam", "cfoam"):
        tight = simulate(model, man, 30.0, rtol=1e-11, atol=1e-11, backend=a.backend)
        ref = float(np.max(np.abs(tight.v_tip)))
        row = {"reference_peak_tip_m": ref, "reference": "IDAS rtol = atol = 1e-11"}
        for name, fn in (("idas", lambda: simulate(model, man, 30.0, backend=a.backend)),
                         ("fixed_step_estimated", lambda: simulate_estimated(model, man, 30.0, backend=a.backend)),
                         ("fixed_step_estimated_with_outputs",
                          lambda: simulate_estimated(model, man, 30.0, backend=a.backend, outputs=True))):
            res, times = _timed(fn, a.repeats)
            row[name] = {**times, "peak_error": abs(float(np.max(np.abs(res.v_tip))) - ref) / ref,
                         "peak_error_estimate": res.stats.get("peak_error_estimate"),
                         "substeps": res.stats.get("substeps")}
        row["speed_up_median"] = row["idas"]["median_s"] / row["fixed_step_estimated"]["median_s"]
        fs = row["fixed_step_estimated"]
        row["meets_target"] = bool(fs["peak_error"] <= 1e-4 and fs["median_s"] <= TARGET_S[model])
        out["models"][model] = row
    text = json.dumps(out, indent=1)
    print(text)
    if a.out:
        with open(a.out, "w") as fh:
            fh.write(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
