"""The MPC on a DC motor as generated C (issue 36): C against Python, the voltage rows' activity, the step time.

Run: ``.venv/bin/python benchmarks/bench_mpc_dc.py [--factors 1.1,1.2] [--repeat 20] [--out FILE]``.

For each factor, ``compare`` slews ``servo_link`` 90 degrees in ``factor * T*`` (its time-optimal slew)
with the MPC as ``compare --rig`` runs it (filter on the encoder and tachometer, integral action, the
QP with the voltage limit through back-EMF, the drive's static inverse: volts out). The Python
controller's closed loop is recorded (sensor values in, volts out, and every DAQP solve: how many
plans have a voltage row at its bound, and how many the first step's); the C generated from it is
compiled with the strict flags and ``-O2`` into a harness that replays the recorded sensor values
``repeat`` times and times every ``<name>_step`` with ``clock_gettime`` (median, 99th percentile,
maximum over the replays after the first; the machine is shared: the median is the figure to judge)
and reports the active-set iterations of each solve. ``max_diff_over_v_max``: the C volts against the
Python volts on the same sensor values. The replay is open loop, valid where the controller's own
dynamics do not magnify rounding: on ``servo_link`` they do not (3e-12 of V_max over the whole run);
on ``servo_payload`` (a full sample of delay) a 1e-15 difference grows 1.75 times a sample in a replay
(measured), so there the C is to be compared in closed loop, in the Python controller's place on the
plant (as ``tests/test_codegen_mpc_dc.py`` does on ``servo_link``).
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from benchjson import bench_parser, emit  # noqa: E402

from controllers.mpc import DirectDAQP  # noqa: E402
from hubbeam_ctrl.deploy import STRICT_FLAGS, compiler, to_c  # noqa: E402
from hubbeam_ctrl.limit import time_optimal_slew  # noqa: E402
from hubbeam_ctrl.plant.rig import load_rig  # noqa: E402
from hubbeam_ctrl.sim import simulate_closed_loop  # noqa: E402
from hubbeam_ctrl.sim.hardware import Hardware  # noqa: E402
from hubbeam_ctrl.study import Slew, compare  # noqa: E402

_HARNESS = r"""
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <time.h>
#include "mpc.h"
#include "replay.h"

static mpc_instance inst;

int main(void)
{
    struct timespec a, b;
    double cmd;
    long r, k;
    for (r = 0; r < REPEAT; ++r) {
        mpc_reset(&inst);
        for (k = 0; k < NSAMP; ++k) {
            double ns;
            clock_gettime(CLOCK_MONOTONIC, &a);
            mpc_step(&inst, Y[k], 0, &cmd);
            clock_gettime(CLOCK_MONOTONIC, &b);
            ns = (b.tv_sec - a.tv_sec) * 1e9 + (b.tv_nsec - a.tv_nsec);
            if (r == 0) printf("%.17g %d\n", cmd, inst.iterations);
            else printf("T %.0f\n", ns);
        }
    }
    printf("F %ld\n", inst.failures);
    return 0;
}
"""


def _activity(records, limit: float) -> tuple:
    """``(plans with a voltage row at its bound, plans with the first step's at its bound)``."""
    rows = first = 0
    for Az, lo, hi in records:
        at = (np.abs(Az - hi) <= 1e-9 * limit) | (np.abs(Az - lo) <= 1e-9 * limit)
        rows += bool(at.any())
        first += bool(at[0])
    return rows, first


def case(rig, factor: float, t_star: float, repeat: int, cc: str, root: Path) -> dict:
    """One slew: the Python closed loop recorded, the C replayed and timed."""
    records, seen = [], []
    solve = DirectDAQP.solve

    def recording(self, g, lba=None, uba=None, warm_start=True):
        z = solve(self, g, lba, uba, warm_start)
        records.append((self, self._A @ z, np.array(lba), np.array(uba)))
        return z
    DirectDAQP.solve = recording
    try:
        c = compare(rig, Slew(math.pi / 2, factor * t_star), "mpc")
        sc, py = c.scenario, c.controllers["mpc"]
        # the MPC's own solves (the planner's, when the slew is planned with its tip rows, are not)
        records = [r[1:] for r in records if r[0] is py.inner.inner.solver]
        rows, first = _activity(records, py.inner.inner.settings.emf_torque_limit)
        n_plans = len(records)

        class Recorder:                     # the Python controller, recording what it reads and returns
            def __getattr__(self, name):
                return getattr(py, name)

            def __call__(self, t, y):
                seen.append((np.array(y, dtype=float), py(t, y)))
                return seen[-1][1]
        py.reset()
        simulate_closed_loop(c.plant, Recorder(), sc.t_end, settings=sc.closed_loop_settings(),
                             reference=(sc.reference.theta_at, sc.reference.theta_dot_at),
                             hardware=Hardware.from_rig(rig))
    finally:
        DirectDAQP.solve = solve
    folder = root / f"mpc_{factor:g}"
    folder.mkdir()
    code = to_c(py, folder / "c")
    src = Path(code.folder)
    Y = np.array([y for y, _ in seen])
    width = Y.shape[1]
    rows_text = ",\n".join("{" + ", ".join("%.17g" % v for v in y) + "}" for y in Y)
    (src / "replay.h").write_text(f"#define NSAMP {len(Y)}\n#define REPEAT {repeat}\n"
                                  f"static const double Y[NSAMP][{width}] = {{\n{rows_text}\n}};\n")
    (src / "main.c").write_text(_HARNESS)
    exe = src / "bench"
    subprocess.run([cc, *STRICT_FLAGS, "-O2", str(src / "main.c"), str(code.source_path), "-o", str(exe), "-lm"],
                   check=True, capture_output=True, text=True)
    lines = subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout.splitlines()
    n = len(Y)
    volts = np.array([float(x.split()[0]) for x in lines[:n]])
    iters = np.array([int(x.split()[1]) for x in lines[:n]])
    ns = np.array([float(x.split()[1]) for x in lines[n:] if x.startswith("T ")])
    failures = int(lines[-1].split()[1])
    v_max = rig.drive.V_max
    return {"t_f_s": factor * t_star, "samples": n, "dt_s": sc.dt, "horizon": py.inner.inner.settings.horizon,
            "plans": n_plans, "plans_with_a_voltage_row_at_its_bound": rows,
            "plans_with_the_first_steps_voltage_at_its_bound": first,
            "max_diff_over_v_max": float(np.max(np.abs(volts - np.array([v for _, v in seen])))) / v_max,
            "peak_volts": float(np.max(np.abs(volts))), "v_max": v_max,
            "iterations_median": float(np.median(iters)), "iterations_max": int(iters.max()),
            "c_failures": failures, "repeat": repeat,
            "c_step_us_median": float(np.median(ns)) / 1e3, "c_step_us_p99": float(np.percentile(ns, 99)) / 1e3,
            "c_step_us_max": float(np.max(ns)) / 1e3}


def table_lines(doc: dict) -> list:
    """docs/deploy.md's table of this benchmark (a test keeps the page equal to the JSON)."""
    lines = ["| t_f / T* | plans with a voltage row at its bound (first step's) | peak [V] | "
             "max abs(C - Python) / V_max | iterations median / max | C step median / p99 / max [us] (sample) |",
             "|---|---|---|---|---|---|"]
    for f, r in doc["factors"].items():
        lines.append(f"| {f} | {r['plans_with_a_voltage_row_at_its_bound']} of {r['plans']} "
                     f"({r['plans_with_the_first_steps_voltage_at_its_bound']}) | {r['peak_volts']:.3g} of "
                     f"{r['v_max']:g} | {r['max_diff_over_v_max']:.1e} | {r['iterations_median']:g} / "
                     f"{r['iterations_max']} | {r['c_step_us_median']:.1f} / {r['c_step_us_p99']:.1f} / "
                     f"{r['c_step_us_max']:.0f} ({1e6 * r['dt_s']:g}) |")
    return lines


def main(argv=None) -> None:
    """Slew servo_link at each factor of T* with the MPC; print the JSON."""
    ap = bench_parser(__doc__)
    ap.add_argument("--factors", default="1.1,1.2")
    ap.add_argument("--repeat", type=int, default=20, help="replays timed in C (the first is not timed)")
    args = ap.parse_args(argv)
    cc = compiler()
    if cc is None:
        raise SystemExit("no C compiler: the benchmark needs one")
    rig = load_rig("servo_link")
    t_star = time_optimal_slew(rig, math.pi / 2).duration_s
    doc = {"rig": "servo_link", "angle_rad": math.pi / 2, "t_star_s": t_star, "flags": [*STRICT_FLAGS, "-O2"],
           "load_before": os.getloadavg(), "factors": {}}
    with tempfile.TemporaryDirectory() as tmp:
        for f in (float(x) for x in args.factors.split(",")):
            doc["factors"][f"{f:g}"] = case(rig, f, t_star, args.repeat, cc, Path(tmp))
    doc["load_after"] = os.getloadavg()
    emit(doc, args.out)


if __name__ == "__main__":
    main()
