"""Residual vibration of every default controller against the plant's integration step (issue 28).

Run: ``.venv/bin/python benchmarks/bench_substeps.py --beam paper|lab --substeps 0,30,20,12,8,6 [--out F.json]``
(``0``: the substep rule's own count, ``sim.substep_rule``: 30 on the paper's beam, 96 on the lab arm).

Each count runs the default ``compare`` (FOAM evaluation plant, five controllers) with
``sim_settings={"substeps": n}``: the paper's beam (Table 1, the Eq. 44 slew, 10 s) or the lab
arm (``L=1, rho=2700, A=9e-5, E=69e9, I=6.75e-11, J_h=0.02, r=0.05, m_t=0.05, tau_max=1.5``,
``Slew(1.5708, 1.2)``). Prints and writes, per count, each controller's ``residual_tip_max_m``,
its verdict, its deviation from the rule's run and from the 30-substep run [%], and the wall
time of the comparison [s] (compile included; the machine is shared).
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time

from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.study.compare import compare
from hubbeam_ctrl.study.tasks import Slew

LAB_ARM = Params(L=1, rho=2700, A=9e-5, E=69e9, I=6.75e-11, J_h=0.02, r=0.05, m_t=0.05, tau_max=1.5)


def run(beam: str, substeps: int) -> dict:
    """One default comparison with ``substeps`` plant steps per sample (0: the rule's)."""
    kw = {"sim_settings": {"substeps": substeps} if substeps else None}
    t0 = time.perf_counter()
    c = compare(**kw) if beam == "paper" else compare(scenario=Slew(1.5708, 1.2), params=LAB_ARM, **kw)
    return {"substeps": {n: r.settings.get("substeps") for n, r in c.results.items()},
            "residual_tip_max_m": {n: m["residual_tip_max_m"] for n, m in c.metrics.items()},
            "verdict": {n: m["verdict"] for n, m in c.metrics.items()},
            "wall_s": time.perf_counter() - t0}


def deviations(runs: dict) -> None:
    """Add each run's deviation [%] from the rule's run ("0") and from the 30-substep run."""
    for ref_key, label in (("0", "pct_vs_rule"), ("30", "pct_vs_30")):
        if ref_key not in runs:
            continue
        ref = runs[ref_key]["residual_tip_max_m"]
        for r in runs.values():
            r[label] = {n: 100.0 * (v / ref[n] - 1.0) for n, v in r["residual_tip_max_m"].items()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--beam", choices=["paper", "lab"], default="paper")
    ap.add_argument("--substeps", default="0,30,20,12,8,6")
    ap.add_argument("--out")
    a = ap.parse_args(argv)
    runs = {}
    for n in (int(s) for s in a.substeps.split(",")):
        runs[str(n)] = run(a.beam, n)
        print(n, json.dumps(runs[str(n)]), file=sys.stderr, flush=True)
    deviations(runs)
    out = {"benchmark": "substeps", "beam": a.beam, "machine": platform.machine(),
           "python": platform.python_version(), "runs": runs}
    text = json.dumps(out, indent=1)
    print(text)
    if a.out:
        with open(a.out, "w") as fh:
            fh.write(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
