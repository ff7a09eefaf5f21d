"""MPC time per step, beside python-control's own MPC on the same problem; compare wall time.

Prints one JSON object. Run: ``.venv/bin/python benchmarks/bench_mpc.py [--pc-solves N]``.

1. Our MPC (condensed dense QP, CasADi ``conic``), horizon 50, 10 ms samples, |tau| <= 200
   N m, on the default slew in closed loop on FOAM (3001 steps), for 2 and 5 transverse
   modes and the solvers daqp, qpoases and qrqp: median and 99th percentile of the
   controller call (Python call included).
2. python-control's ``control.optimal`` (SciPy SLSQP) on the same QP: the discrete
   design model, the same Q, R and terminal weight P, the same torque bound, solved from
   the closed-loop state at t = t_f = 10 s (regulation to rest at the slew angle). It takes
   tens of seconds per solve, so only ``--pc-solves`` solves are timed and the per-step and
   per-run times are scaled from them. Its first move and plan cost are compared with ours.
3. The plant stepper alone (ms per 10 ms sample) on FOAM and CFOAM.
4. The wall time of ``hubbeam compare --plant foam`` with the defaults (all five
   controllers), as a subprocess (interpreter start and imports included).
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from controllers import MPC, DesignModel, MPCSettings, slew_reference
from hubbeam_ctrl import Params, build_model
from hubbeam_ctrl.cli.compare import stdout_to_stderr
from hubbeam_ctrl.sim import PlantStepper, simulate_closed_loop

HORIZON = 50
DT = 0.01
TAU_MAX = 200.0


def ours(n_modes: int, solver: str) -> dict:
    p = Params(n_transverse=n_modes)
    design = DesignModel.build(p, 0.0, DT)
    J = p.total_inertia
    theta = TAU_MAX * 10.0 ** 2 / (2 * math.pi * J)
    ref = slew_reference(theta, 10.0, J, TAU_MAX, DT, 32.0)
    mpc = MPC(design, MPCSettings(horizon=HORIZON, solver=solver, tau_max=TAU_MAX), ref)
    res = simulate_closed_loop("foam", mpc, 30.0, params=p)
    st = res.step_time_s * 1e3
    w = res.t >= 15.0
    return {"n_modes": n_modes, "solver": solver, "steps": int(len(st)),
            "median_ms": float(np.median(st)), "p99_ms": float(np.percentile(st, 99)),
            "max_ms": float(np.max(st)), "qp_fallbacks": mpc.stats()["qp_fallbacks"],
            "residual_tip_max_m": float(np.max(np.abs(res.v_tip[w]))),
            "_result": res, "_design": design, "_mpc": mpc}


def plan_cost(design, mpc, x0, u):
    """Our cost of a plan ``u`` from ``x0`` (regulation to 0): sum x'Qx + R u^2 + x_N' P x_N."""
    Q, R = mpc.settings.weights.matrices(design)
    x = np.array(x0, dtype=float)
    J = 0.0
    for k, uk in enumerate(u):
        J += float(R[0, 0]) * uk ** 2
        x = design.Ad @ x + design.Bd[:, 0] * uk
        J += float(x @ (mpc.P if k == len(u) - 1 else Q) @ x)
    return J


def python_control(design, x0, n_solves: int) -> dict:
    import control
    import control.optimal as opt
    mpc = MPC(design, MPCSettings(horizon=HORIZON, tau_max=TAU_MAX))   # regulation to rest
    Q, R = mpc.settings.weights.matrices(design)
    sysd = control.ss(design.Ad, design.Bd, np.eye(design.n_x), 0, DT)
    timepts = DT * np.arange(HORIZON)                 # HORIZON inputs u_0..u_{N-1}
    cost = opt.quadratic_cost(sysd, Q, R)
    term = opt.quadratic_cost(sysd, mpc.P, 0 * R)
    cons = [opt.input_range_constraint(sysd, -TAU_MAX, TAU_MAX)]
    times, first, plans = [], [], []
    for _ in range(n_solves):
        t0 = time.perf_counter()
        out = opt.solve_optimal_trajectory(sysd, timepts, x0, cost, cons, terminal_cost=term,
                                           print_summary=False)
        times.append(time.perf_counter() - t0)
        u = np.asarray(out.inputs).ravel()
        plans.append(u)
        first.append(float(u[0]))
    mpc.reset()
    ours_plan = mpc.plan(0.0, x0)
    u_pc = plans[-1]
    n = min(len(u_pc), HORIZON)
    return {"solves": n_solves, "seconds_per_solve": [float(t) for t in times],
            "median_ms_per_step": float(np.median(times) * 1e3),
            "scaled_run_s_3001_steps": float(np.median(times) * 3001),
            "success": bool(out.success), "first_move_nm": first[-1],
            "ours_first_move_nm": float(ours_plan[0]),
            "first_move_diff_nm": abs(first[-1] - float(ours_plan[0])),
            "plan_max_diff_nm": float(np.max(np.abs(u_pc[:n] - ours_plan[:n]))),
            "cost_python_control": plan_cost(design, mpc, x0, u_pc[:HORIZON]),
            "cost_ours": plan_cost(design, mpc, x0, ours_plan)}


def stepper_ms(name: str, n: int = 500) -> float:
    st = PlantStepper(build_model(name))
    s = st.initial_state()
    st.step(s, 100.0)
    t0 = time.perf_counter()
    for _ in range(n):
        s = st.step(s, 100.0)
    return (time.perf_counter() - t0) / n * 1e3


def compare_wall() -> dict:
    exe = Path(sys.executable).with_name("hubbeam")
    cmd = [str(exe) if exe.exists() else sys.executable, "compare", "--plant", "foam",
           "--json"]
    if not exe.exists():
        cmd = [sys.executable, "-m", "hubbeam_ctrl.cli.main", "compare", "--plant", "foam", "--json"]
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        proc = subprocess.run(cmd + ["--out", str(Path(tmp) / "cmp")], capture_output=True, text=True)
        wall = time.perf_counter() - t0
    out = {"command": "hubbeam compare --plant foam --out DIR --json", "wall_s": wall,
           "returncode": proc.returncode}
    if proc.returncode == 0:
        data = json.loads(proc.stdout)
        out["residual_tip_max_m"] = {d["controller"]: d["residual_tip_max_m"] for d in data}
    else:
        out["stderr"] = proc.stderr[-500:]
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pc-solves", type=int, default=2,
                    help="python-control solves timed per mode count (each takes ~10-60 s)")
    ap.add_argument("--solvers", default="daqp,qpoases,qrqp")
    ap.add_argument("--no-compare", action="store_true", help="skip the hubbeam compare timing")
    args = ap.parse_args(argv)
    with stdout_to_stderr():          # keep native libraries' banners out of the JSON
        report = _run(args)
    print(json.dumps(report, indent=2))
    return 0


def _run(args) -> dict:
    report = {"machine": {"python": platform.python_version(), "cpus": __import__("os").cpu_count()},
              "problem": {"horizon": HORIZON, "dt_s": DT, "tau_max_nm": TAU_MAX,
                          "closed_loop": "default slew on FOAM, 30 s, 3001 controller calls"},
              "ours": [], "python_control": [], "target_median_ms_2_modes": 0.5}
    for n_modes in (2, 5):
        base = None
        for solver in args.solvers.split(","):
            r = ours(n_modes, solver)
            if base is None:
                base = r
            report["ours"].append({k: v for k, v in r.items() if not k.startswith("_")})
            print(f"ours {n_modes} modes {solver}: median {r['median_ms']:.3f} ms, "
                  f"p99 {r['p99_ms']:.3f} ms", file=sys.stderr)
        if args.pc_solves > 0:
            res, design = base["_result"], base["_design"]
            k = int(round(10.0 / DT))         # end of the slew: beam ringing, hub at Theta
            n = design.n_x // 2
            nq = res.q.shape[1]
            idx = np.r_[0, nq - design.n_modes:nq]
            x0 = np.concatenate([res.q[k, idx], res.v[k, idx]])
            x0[0] -= base["_mpc"]._xref[k][0]                          # regulation error
            x0[n] -= base["_mpc"]._xref[k][n]
            pc = python_control(design, x0, args.pc_solves)
            pc["n_modes"] = n_modes
            pc["state_from_t_s"] = float(res.t[k])
            report["python_control"].append(pc)
            print(f"python-control {n_modes} modes: {pc['median_ms_per_step']:.0f} ms per solve",
                  file=sys.stderr)
    report["stepper_ms_per_sample"] = {"foam": stepper_ms("foam"), "cfoam": stepper_ms("cfoam")}
    if not args.no_compare:
        report["hubbeam_compare_foam"] = compare_wall()
    two = [r for r in report["ours"] if r["n_modes"] == 2 and r["solver"] == "daqp"]
    if two:
        report["target_met_2_modes"] = two[0]["median_ms"] <= 0.5
    return report


if __name__ == "__main__":
    sys.exit(main())
