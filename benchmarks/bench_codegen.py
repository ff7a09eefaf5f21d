"""Step time of the generated C controllers against the Python ones, and their code and data size.

Run: ``.venv/bin/python benchmarks/bench_codegen.py [--samples N] [--repeat R]``. Writes
``benchmarks/results/bench_codegen_<date>.json`` and prints it.

For PD, LQR (with its observer), LQG and MPC (horizon 50) on Table 1's beam at 100 Hz (5
design modes, the filters and the gain models with the 10 modes of the default evaluation
plant, so the LQG's filter has 22 states), the Python controller first runs the closed loop
on the evaluation plant; its sensor values are then replayed

* in C: a harness compiled with the generated source (``-O2``) times every
  ``<name>_step`` with ``clock_gettime`` (no ctypes call in the measurement; median, mean,
  99th percentile and maximum over the replays after the first: the machine is shared, so
  the median is the figure the targets are judged on);
* in Python: the same controller's call, timed the same way (``perf_counter``): the named
  alternative.

The C commands of the replay are checked against the Python ones (``max_diff_over_tau_max``).
Code and data size: ``size -A`` of the ``-O2`` object (``.text`` and ``.rodata``). Targets
(issue 26): LQG under 2 us, MPC horizon 50 under 50 us per step.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from controllers import LQG, LQR, MPC, PD, DesignModel, LQGSettings, LQRSettings, MPCSettings, slew_reference
from hubbeam_ctrl import Params
from hubbeam_ctrl.deploy import STRICT_FLAGS, ObservedLQR, ObservedMPC, compiler, to_c
from hubbeam_ctrl.sim import simulate_closed_loop

RESULTS = Path(__file__).parent / "results"
TARGETS_US = {"lqg": 2.0, "mpc": 50.0}

_HARNESS = r"""
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <time.h>
#include "NAME.h"
#include "replay.h"

static NAME_instance inst;

int main(void)
{
    struct timespec a, b;
    double cmd;
    long r, k;
    for (r = 0; r < REPEAT; ++r) {
        NAME_reset(&inst);
        for (k = 0; k < NSAMP; ++k) {
            double ns;
            clock_gettime(CLOCK_MONOTONIC, &a);
            NAME_step(&inst, Y[k], 0, &cmd);
            clock_gettime(CLOCK_MONOTONIC, &b);
            ns = (b.tv_sec - a.tv_sec) * 1e9 + (b.tv_nsec - a.tv_nsec);
            if (r == 0) printf("%.17g\n", cmd);
            else printf("T %.0f\n", ns);
        }
    }
    return 0;
}
"""


def _replay_header(Y: np.ndarray, repeat: int) -> str:
    rows = ",\n".join("{" + ", ".join("%.17g" % v for v in y) + "}" for y in Y)
    return f"#define NSAMP {len(Y)}\n#define REPEAT {repeat}\nstatic const double Y[NSAMP][3] = {{\n{rows}\n}};\n"


def _size(obj: Path) -> dict:
    out = subprocess.run(["size", "-A", str(obj)], capture_output=True, text=True, check=True).stdout
    sizes = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) >= 2 and parts[0].startswith("."):
            sizes[parts[0]] = sizes.get(parts[0], 0) + int(parts[1])
    return {"text_bytes": sizes.get(".text", 0),
            "rodata_bytes": sum(v for k, v in sizes.items() if k.startswith(".rodata"))}


def _bench(kind, ctrl, py, t_end, repeat, cc, root) -> dict:
    res = simulate_closed_loop("foam", py, t_end)
    Y = np.column_stack([res.theta, res.v[:, 0], res.root_moment])       # noise-free replay of the run
    n = len(Y)
    # Python: the same controller on the same sensor values
    py_times = []
    py_cmds = []
    for r in range(max(1, repeat // 5)):
        py.reset()
        for k in range(n):
            t0 = time.perf_counter()
            tau = py(k * py.dt, Y[k])
            py_times.append(time.perf_counter() - t0)
            if r == 0:
                py_cmds.append(tau)
    code = to_c(ctrl, root / kind)
    folder = Path(code.folder)
    (folder / "replay.h").write_text(_replay_header(Y, repeat))
    (folder / "main.c").write_text(_HARNESS.replace("NAME", code.name))
    exe = folder / "bench"
    subprocess.run([cc, *STRICT_FLAGS, "-O2", str(folder / "main.c"), str(code.source_path), "-o", str(exe),
                    "-lm"], check=True, capture_output=True, text=True)
    subprocess.run([cc, *STRICT_FLAGS, "-O2", "-c", str(code.source_path), "-o", str(folder / "ctrl.o")],
                   check=True)
    lines = subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout.splitlines()
    c_cmds = np.array([float(x) for x in lines[:n]])
    ns = np.array([float(x.split()[1]) for x in lines[n:]])
    sizes = _size(folder / "ctrl.o")
    entry = {
        "states": int(len(code.law.arrays.get("X0", []))), "samples": n, "repeat": repeat,
        "c_step_us_median": float(np.median(ns)) / 1e3, "c_step_us_mean": float(np.mean(ns)) / 1e3,
        "c_step_us_p99": float(np.percentile(ns, 99)) / 1e3, "c_step_us_max": float(np.max(ns)) / 1e3,
        "python_step_us_median": float(np.median(py_times)) * 1e6,
        "python_step_us_mean": float(np.mean(py_times)) * 1e6,
        "speedup_median": float(np.median(py_times)) * 1e9 / float(np.median(ns)),
        "max_diff_over_tau_max": float(np.max(np.abs(c_cmds - np.array(py_cmds))) / ctrl.tau_max),
        "code_text_bytes": sizes["text_bytes"], "rodata_bytes": sizes["rodata_bytes"],
        "data_bytes_declared": code.data_bytes,
        "source_bytes": len(code.source.encode()), "header_bytes": len(code.header.encode()),
    }
    if kind in TARGETS_US:
        entry["target_us"] = TARGETS_US[kind]
        entry["meets_target"] = entry["c_step_us_median"] < TARGETS_US[kind]
    if kind == "mpc":
        entry["horizon"] = ctrl.settings.horizon
    return entry


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--t-end", type=float, default=12.0, help="closed-loop run replayed [s]")
    ap.add_argument("--repeat", type=int, default=20, help="replays timed in C (the first is a warm-up)")
    args = ap.parse_args()
    cc = compiler()
    if cc is None:
        raise SystemExit("no C compiler: the benchmark needs one")
    p = Params()
    dt = 0.01
    design = DesignModel.build(p, 0.0, dt)
    ref = slew_reference(1.0, 6.0, p.total_inertia, 200.0, dt, args.t_end)
    ctrls = {
        "pd": PD(design, reference=ref),
        "lqr": LQR(design, LQRSettings(residual_control=True), reference=ref),
        "lqg": LQG(design, LQGSettings(residual_control=True), reference=ref),
        "mpc": MPC(design, MPCSettings(horizon=50, residual_control=True), reference=ref),
    }
    load0 = os.getloadavg()
    out = {"benchmark": "codegen", "machine": platform.machine(), "cpu_count": os.cpu_count(),
           "compiler": subprocess.run([cc, "--version"], capture_output=True, text=True).stdout.splitlines()[0],
           "flags": [*STRICT_FLAGS, "-O2"], "beam": "Table 1", "dt_s": dt, "design_modes": design.n_modes,
           "load_before": load0, "controllers": {}}
    with tempfile.TemporaryDirectory() as tmp:
        for kind, ctrl in ctrls.items():
            py = ObservedLQR(ctrl) if kind == "lqr" else ObservedMPC(ctrl) if kind == "mpc" else ctrl
            out["controllers"][kind] = _bench(kind, ctrl, py, args.t_end, args.repeat, cc, Path(tmp))
    out["load_after"] = os.getloadavg()
    RESULTS.mkdir(exist_ok=True)
    path = RESULTS / f"bench_codegen_{datetime.date.today().isoformat()}.json"
    path.write_text(json.dumps(out, indent=2) + "\n")
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
