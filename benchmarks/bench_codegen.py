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
Code and data size: ``size -A`` of the ``-O2`` object (``.text`` and ``.rodata``). The MPC's
QP has a second named alternative, CasADi's generated ``qrqp`` on the same recorded QPs
(``mpc_qp_alternative_qrqp``: does it compile with the strict flags, its includes, its plans'
distance from DAQP's). Targets
(issue 26): LQG under 2 us, MPC horizon 50 under 50 us per step.

``--robust`` measures the robust designs of issue 39 the same way instead (no qrqp alternative):
the multi-stage MPC over the payloads 0 / 0.1 / 0.5 kg (horizon 50: 148 torques) and the
H-infinity law for the same range, written to ``benchmarks/results/bench_codegen_robust.json``
(docs/deploy.md's robust table is generated from it).
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


def _qrqp_alternative(mpc, py, Y, cc, root) -> dict:
    """The named alternative for the MPC's QP: CasADi's code generation of ``qrqp``.

    Records every QP the Python MPC (DAQP) solves on the replay, then solves the same QPs with
    the ``qrqp`` C that CasADi generates: whether it compiles with the strict flags, and how far
    its plans are from DAQP's when compiled without them.
    """
    import casadi as ca
    recorded = []
    solver = mpc.solver
    original = solver.solve

    def recording(g, lba=None, uba=None, warm_start=True):
        z = original(g, lba, uba, warm_start)
        recorded.append((np.array(g), z.copy()))
        return z
    solver.solve = recording
    try:
        py.reset()
        for k in range(len(Y)):
            py(k * py.dt, Y[k])
    finally:
        solver.solve = original
    N = mpc.settings.horizon
    H = mpc._H
    A = ca.DM(np.zeros((0, N)))
    qp = ca.conic("mpc_qp", "qrqp", {"h": H.sparsity(), "a": A.sparsity()},
                  {"print_iter": False, "print_header": False, "print_info": False, "error_on_fail": False})
    folder = root / "qrqp"
    folder.mkdir()
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        qp.generate("qrqp_qp.c")
    finally:
        os.chdir(cwd)
    src = folder / "qrqp_qp.c"
    text = src.read_text()
    strict = subprocess.run([cc, *STRICT_FLAGS, "-O2", "-fPIC", "-shared", str(src), "-o", str(folder / "s.so"),
                             "-lm"], capture_output=True, text=True)
    lib = folder / "qrqp.so"
    subprocess.run([cc, "-O2", "-fPIC", "-shared", str(src), "-o", str(lib), "-lm"], check=True, capture_output=True)
    f = ca.external("mpc_qp", str(lib))
    lb = np.full(N, -mpc.tau_max)
    ub = np.full(N, mpc.tau_max)
    inproc = ca.conic("mpc_qp_inproc", "qrqp", {"h": H.sparsity(), "a": A.sparsity()},
                      {"print_iter": False, "print_header": False, "print_info": False, "error_on_fail": False})
    Hn = np.asarray(H.full(), dtype=float)
    diffs, diffs_inproc, failed, worse = [], [], 0, []
    times = []
    for g, z_daqp in recorded:
        t0 = time.perf_counter()
        sol = f(h=H, g=g, a=A, lbx=lb, ubx=ub)
        times.append(time.perf_counter() - t0)
        z_q = np.asarray(sol["x"]).ravel()
        diffs.append(float(np.max(np.abs(z_q - z_daqp))))
        if diffs[-1] > 1e-9 * mpc.tau_max:       # which plan is the minimiser? (lower cost, feasible)
            cost = [float(0.5 * z @ Hn @ z + g @ z) for z in (z_daqp, z_q)]
            worse.append({"daqp_cost": cost[0], "qrqp_cost": cost[1],
                          "qrqp_bound_violation_nm": float(max(0.0, np.max(np.abs(z_q)) - mpc.tau_max))})
        sol2 = inproc(h=H, g=g, a=A, lbx=lb, ubx=ub)
        failed += not inproc.stats().get("success", False)
        diffs_inproc.append(float(np.max(np.abs(np.asarray(sol2["x"]).ravel() - z_daqp))))
    diffs, diffs_inproc = np.array(diffs), np.array(diffs_inproc)
    worst = float(diffs.max())
    first_error = next((ln for ln in strict.stderr.splitlines() if "error" in ln), "")
    return {"qps": len(recorded), "compiles_with_strict_flags": strict.returncode == 0,
            "strict_first_error": first_error.strip()[:200],
            "includes": sorted(set(ln.strip() for ln in text.splitlines() if ln.startswith("#include"))),
            "max_plan_diff_over_tau_max": worst / mpc.tau_max,
            "median_plan_diff_over_tau_max": float(np.median(diffs)) / mpc.tau_max,
            "qps_off_by_more_than_1e-9_tau_max": int(np.sum(diffs > 1e-9 * mpc.tau_max)),
            "in_process_qrqp_failures": int(failed),
            "off_qps": worse[:5],
            "in_process_qrqp_max_plan_diff_over_tau_max": float(diffs_inproc.max()) / mpc.tau_max,
            "solve_us_median_via_casadi_external": float(np.median(times)) * 1e6}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--t-end", type=float, default=12.0, help="closed-loop run replayed [s]")
    ap.add_argument("--repeat", type=int, default=20, help="replays timed in C (the first is a warm-up)")
    ap.add_argument("--robust", action="store_true", help="the multi-stage MPC and H-infinity instead")
    args = ap.parse_args()
    cc = compiler()
    if cc is None:
        raise SystemExit("no C compiler: the benchmark needs one")
    p = Params()
    dt = 0.01
    design = DesignModel.build(p, 0.0, dt)
    ref = slew_reference(1.0, 6.0, p.total_inertia, 200.0, dt, args.t_end)
    if args.robust:
        return _robust(args, cc, design, ref)
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
        mpc = ctrls["mpc"]
        res = simulate_closed_loop("foam", ObservedMPC(mpc), args.t_end)
        Y = np.column_stack([res.theta, res.v[:, 0], res.root_moment])
        out["mpc_qp_alternative_qrqp"] = _qrqp_alternative(mpc, ObservedMPC(mpc), Y, cc, Path(tmp))
    out["load_after"] = os.getloadavg()
    RESULTS.mkdir(exist_ok=True)
    path = RESULTS / f"bench_codegen_{datetime.date.today().isoformat()}.json"
    path.write_text(json.dumps(out, indent=2) + "\n")
    print(json.dumps(out, indent=2))


#: The payload scenarios of the robust designs [kg]: ``--payload-range 0,0.5`` on Table 1 (tip mass 0.1 kg).
ROBUST_PAYLOADS = (0.0, 0.1, 0.5)


def _robust(args, cc, design, ref) -> None:
    """``--robust``: the multi-stage MPC and the H-infinity law, replayed like the others."""
    from controllers import HInfSettings, KalmanNoise, MultiStageMPC, MultiStageMPCSettings, make_controller
    from controllers.integral import ObservedFeedback
    ms = MultiStageMPC(design, MultiStageMPCSettings(horizon=50, residual_control=True, payloads=ROBUST_PAYLOADS),
                       ref)
    hinf = make_controller("hinf", design, HInfSettings(payloads=ROBUST_PAYLOADS), ref)
    out = {"benchmark": "codegen_robust", "machine": platform.machine(), "cpu_count": os.cpu_count(),
           "compiler": subprocess.run([cc, "--version"], capture_output=True, text=True).stdout.splitlines()[0],
           "flags": [*STRICT_FLAGS, "-O2"], "beam": "Table 1", "dt_s": design.dt, "design_modes": design.n_modes,
           "payloads_kg": list(ROBUST_PAYLOADS), "load_before": os.getloadavg(), "controllers": {}}
    with tempfile.TemporaryDirectory() as tmp:
        out["controllers"]["msmpc"] = _bench("msmpc", ms, ObservedFeedback(ms, KalmanNoise()), args.t_end,
                                             args.repeat, cc, Path(tmp))
        out["controllers"]["msmpc"].update(horizon=50, qp_torques=int(ms._n_u))
        out["controllers"]["hinf"] = _bench("hinf", hinf, hinf, args.t_end, args.repeat, cc, Path(tmp))
        out["controllers"]["hinf"]["order"] = hinf.order
    out["load_after"] = os.getloadavg()
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "bench_codegen_robust.json").write_text(json.dumps(out, indent=2) + "\n")
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
