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

``--process`` (issue 37, everyday speed) measures instead what a user sees: whole processes of
``hubbeam simulate --model M --maneuver torque --t-end 30 --json`` (the same run), today's tree
against ``--baseline`` (default ``32e9d65``, main before issue 37's speed work; exported with
``git archive``, the same virtual environment and build cache), alternating, ``--repeats`` each
after one warm-up: the run's own ``wall_s`` of the JSON (the number the issue quotes: the run
in a new process, with the model built and the compiled functions loaded, without start-up) and
the process's wall and CPU time; medians and fastest. The printed numbers of the two trees must
be equal (``same_numbers``). Targets on ``wall_s``: CFOAM 0.1 s, FOAM 0.05 s.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

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


def _process(env: dict, model: str) -> dict:
    """One ``hubbeam simulate ... --json`` process: its JSON, wall and CPU [s]."""
    cmd = [sys.executable, "-m", "hubbeam_ctrl", "simulate", "--model", model, "--maneuver", "torque",
           "--t-end", "30", "--json"]
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, env=env, cwd=env["BENCH_CWD"], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    out = proc.stdout.read()
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{' '.join(cmd)} failed")
    doc = json.loads(out.decode().strip().splitlines()[-1])
    return {"json": doc, "wall_s": wall, "cpu_s": usage.ru_utime + usage.ru_stime}


def _processes(a) -> dict:
    """``--process``: whole processes of today's tree and the baseline's, alternating."""
    from bench_compare import _export  # the benchmarks folder is on sys.path
    work = Path(tempfile.mkdtemp(prefix="bench_simulate_"))
    try:
        (work / "baseline").mkdir()
        _export(a.baseline, work / "baseline")
        env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
        env["BENCH_CWD"] = str(work)
        trees = {"baseline": {**env, "PYTHONPATH": str(work / "baseline")},
                 "current": {**env, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}}
        out = {"benchmark": "simulate --process", "run": "hubbeam simulate --model M --maneuver torque --t-end 30 "
               "--json (Eq. 44, 200 N m, t_f 10 s, Table 1, 5+5 modes)", "baseline": a.baseline,
               "machine": platform.machine(), "cpus": os.cpu_count(), "python": platform.python_version(),
               "load_average_1min_start": os.getloadavg()[0], "repeats": a.repeats, "targets_wall_s": TARGET_S,
               "models": {}}
        for model in ("foam", "cfoam"):
            runs = {t: [] for t in trees}
            for t, e in trees.items():
                _process(e, model)                        # warm-up: build cache, file cache
            for _ in range(a.repeats):
                for t, e in trees.items():
                    runs[t].append(_process(e, model))
            row = {}
            for t, rr in runs.items():
                w = [r["json"]["wall_s"] for r in rr]
                row[t] = {"run_wall_median_s": statistics.median(w), "run_wall_fastest_s": min(w),
                          "process_wall_median_s": statistics.median(r["wall_s"] for r in rr),
                          "process_cpu_median_s": statistics.median(r["cpu_s"] for r in rr),
                          "run_walls_s": w}
            strip = [{k: v for k, v in r["json"].items() if k != "wall_s"} for t in trees for r in runs[t]]
            row["same_numbers"] = all(x == strip[0] for x in strip)
            row["speedup_run_wall_median"] = (row["baseline"]["run_wall_median_s"]
                                              / row["current"]["run_wall_median_s"])
            row["meets_target"] = bool(row["current"]["run_wall_median_s"] <= TARGET_S[model] and row["same_numbers"])
            out["models"][model] = row
        out["load_average_1min_end"] = os.getloadavg()[0]
        return out
    finally:
        shutil.rmtree(work, ignore_errors=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--backend", default=None)
    ap.add_argument("--process", action="store_true", help="whole processes against --baseline (issue 37)")
    ap.add_argument("--baseline", default="32e9d65", help="git revision of the baseline tree (with --process)")
    ap.add_argument("--out")
    a = ap.parse_args(argv)
    if a.process:
        text = json.dumps(_processes(a), indent=1)
        print(text)
        if a.out:
            Path(a.out).write_text(text + "\n")
        return 0
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
