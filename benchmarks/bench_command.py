"""Issue 36's command target on Table 1's default slew (no rig): is the command the hardware gets judged?

Run: ``.venv/bin/python benchmarks/bench_command.py [--out FILE]``

``compare`` with every default (the paper's beam, the Eq. 44 slew at 200 N m in 10 s, FOAM) with
the task's reference (since issue 36 a slew planned on the design model within the reference's
share of the torque limit) and, for comparison, the rigid body's reference (the default before):
per controller the verdict, the residual as a share of the open loop's, the largest command
change in one sample [N m], the time at the limit [s] and the peak command. The README quotes
this JSON (``benchmarks/results/bench_command.json``; ``tests/test_any_rig.py`` keeps the two equal).
"""

from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from benchjson import bench_parser, emit  # noqa: E402

from hubbeam_ctrl.study import compare  # noqa: E402
from hubbeam_ctrl.study.compare_values import CompareSettings, DesignChoice

CONTROLLERS = ("lqr", "lqg", "mpc")


def run(reference: str) -> dict:
    c = compare(None, "slew", ("openloop",) + CONTROLLERS, CompareSettings(design=DesignChoice(reference=reference)))
    out = {}
    for name in CONTROLLERS:
        m = c.metrics[name]
        out[name] = {"verdict": m["verdict"], "residual_pct_of_openloop": m["residual_pct_of_openloop"],
                     "peak_command_step": m["peak_command_step"], "time_at_limit_s": m["time_at_limit_s"],
                     "peak_command": m["peak_command"], "settling_time_s": m["settling_time_s"]}
    return {"description": c.scenario.description, "controllers": out}


def readme_sentence(doc: dict) -> str:
    """The README's sentence of these numbers (a test keeps it equal to the JSON)."""
    task, rigid = doc["task"]["controllers"], doc["rigid"]["controllers"]
    pct = ", ".join(f"{n.upper()} {task[n]['residual_pct_of_openloop']:.2f} %" for n in CONTROLLERS)
    step = " / ".join(f"{task[n]['peak_command_step']:.1f}" for n in CONTROLLERS)
    old = " / ".join(f"{rigid[n]['peak_command_step']:.0f}" for n in CONTROLLERS)
    return (f"{pct} of the open loop's residual vibration; the largest command step per sample "
            f"{step} N m (the rigid reference's: {old} N m)")


def main(argv=None) -> None:
    ap = bench_parser(__doc__)
    args = ap.parse_args(argv)
    emit({"task": run("task"), "rigid": run("rigid")}, args.out)


if __name__ == "__main__":
    main()
