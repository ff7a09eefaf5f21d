"""The paper beam designed for a 0-0.5 kg payload range: LQR, LQG and MPC on FOAM plants at
0, 0.1, 0.3 and 0.5 kg (issue target: each <= 2 % of that plant's open-loop residual). Prints JSON.

Run: ``.venv/bin/python benchmarks/bench_payload.py [--out F.json]`` (about 2-4 min on 2 cores with
a C compiler). The suite's ``tests/test_payload.py::test_paper_beam_designed_for_0_to_half_a_kilo``
runs the LQR at the ends of the range (the range design's search dominates its time: 52
candidate evaluations on three grid payloads per controller); this runs all three controllers
at the four payloads and checks the same conditions, printing each row.
"""

from __future__ import annotations

import os
import platform
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from benchjson import bench_parser, emit  # noqa: E402

from hubbeam_ctrl.study import CompareSettings, PayloadChoice, payload_comparison, payload_table  # noqa: E402

MASSES = (0.0, 0.1, 0.3, 0.5)


def run() -> dict:
    """All three controllers at the four payloads; rows and whether each meets the target."""
    t0 = time.perf_counter()
    pc = payload_comparison(None, "slew", "openloop,lqr,lqg,mpc",
                            CompareSettings(payload=PayloadChoice(payload_range=(0.0, 0.5))), masses=MASSES)
    print(payload_table(pc), file=sys.stderr)
    rows = []
    for r in pc.rows():
        if r["controller"] == "openloop":
            continue
        mm = pc.comparisons[r["payload_kg"]].metrics[r["controller"]]
        ok = r["residual_pct_of_openloop"] <= 2.0 and r["peak_torque_nm"] <= 200.0 + 1e-9 and (
            r["verdict"] == "settled" or (r["verdict"] == "unstable" and mm["loop_certificate"] == "grows"
                                          and mm["loop_damping_needed"] <= 1e-3))
        rows.append({"payload_kg": r["payload_kg"], "controller": r["controller"], "verdict": r["verdict"],
                     "residual_pct_of_openloop": r["residual_pct_of_openloop"],
                     "loop_damping_needed": mm.get("loop_damping_needed"), "meets": bool(ok)})
    return {"rows": rows, "all_meet": all(r["meets"] for r in rows),
            "design_masses_kg": {n: d.design_mass for n, d in pc.designs.items()},
            "wall_s": time.perf_counter() - t0}


def main(argv=None) -> int:
    """Entry point; prints the JSON and writes it to ``--out`` when given."""
    ap = bench_parser(__doc__)
    args = ap.parse_args(argv)
    doc = {"benchmark": "payload_range", "machine": {"python": platform.python_version(), "cpus": os.cpu_count()},
           **run()}
    emit(doc, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
