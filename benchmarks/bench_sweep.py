"""Sweep engine: cases per second per worker, parallel efficiency, Dask overhead, per-case overhead.

Prints one JSON object. Run: ``.venv/bin/python benchmarks/bench_sweep.py [--cases N] [--t-end S]``.

The study: the default slew (200 N m, t_f 10 s), LQR designed once on the base parameters
(Table 1, 5+5 modes), FOAM, 30 s, over ``--cases`` tip masses in [0, 0.5] kg (every case a
new plant, so every case builds its plant functions).

1. ``workers=1`` (in this process), then the local process pool with 2 workers, then a
   2-worker Dask ``LocalCluster`` (processes, one thread each): wall time, cases per second
   per worker, parallel efficiency ``T1 / (2 T2)``; the cluster's start-up is reported apart
   and the Dask overhead is ``T_dask / T_pool - 1`` (both without start-up; the pool's
   start-up is inside its wall time).
2. Per-case overhead: the wall time of a case beyond its closed-loop run (``sim_wall_s``),
   split into building a new plant (``setup_s`` and the stepper functions) and the rest; and
   with warm caches (the same 5 tip masses run again in this process).
   ``busy_fraction`` (time inside cases / (workers x wall)) separates engine overhead from a
   machine too loaded to give two cores.
3. The machine's own ceiling (the named alternative): a fixed single-threaded NumPy workload
   timed alone and as two processes at once. ``machine_two_process_efficiency`` is
   ``T_alone / T_concurrent``: two busy cores that slow each other (shared caches, SMT,
   a virtual machine's CPU share) cap any 2-worker engine there, and
   ``parallel_efficiency_of_machine_ceiling`` is the engine's efficiency relative to it.
4. The load of the machine (``os.getloadavg``) before and after, since the 2 cores may be shared.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time

import numpy as np

from hubbeam_ctrl.study.spec_files import load_spec
from hubbeam_ctrl.study.sweep import CaseCache, run_case, sweep


def spec_dict(n: int, t_end: float) -> dict:
    return {"study": {"scenario": "slew", "plant": "foam", "controllers": ["lqr"], "t_end": t_end},
            "grid": {"m_t": [float(v) for v in np.linspace(0.0, 0.5, n)]}}


def timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def overheads(df, wall: float, workers: int) -> dict:
    """Medians per case, and the fraction of the workers' wall time spent inside cases
    (``busy_fraction``: below 1 by the engine's own overhead and idle tails; a loaded
    machine slows the cases themselves, which this fraction does not hide)."""
    beyond = df["setup_s"] + df["wall_s"] - df["sim_wall_s"]
    return {"sim_wall_s_median": float(df["sim_wall_s"].median()),
            "sim_wall_s_sum": float(df["sim_wall_s"].sum()),
            "setup_s_median": float(df["setup_s"].median()),
            "beyond_run_ms_median": float(1e3 * beyond.median()),
            "busy_fraction": float((df["setup_s"] + df["wall_s"]).sum() / (workers * wall))}


def warm_overhead(t_end: float) -> dict:
    """The same 5 plants twice in this process: the second pass has every function built.
    ``sim_outside_loop_ms`` is the part spent inside ``simulate_closed_loop`` before and after
    its sample loop (tip outputs over all samples, reference, noise)."""
    spec = load_spec(spec_dict(5, t_end))
    cache = CaseCache()
    for case in spec.cases():
        run_case(case, spec, cache)
    out, inside = [], []
    for case in spec.cases():
        t0 = time.perf_counter()
        row = run_case(case, spec, cache)[0]
        out.append((time.perf_counter() - t0 - row["sim_wall_s"]) * 1e3)
        inside.append((row["wall_s"] - row["sim_wall_s"]) * 1e3)
    return {"warm_beyond_run_ms_median": float(np.median(out)), "warm_beyond_run_ms_max": float(np.max(out)),
            "warm_controller_sim_metrics_outside_loop_ms_median": float(np.median(inside))}


def _workload(_=None) -> float:
    """A fixed single-threaded CPU workload (small matrix products) [s of wall time]."""
    a = np.random.default_rng(0).normal(size=(60, 60))
    t0 = time.perf_counter()
    s = 0.0
    for _ in range(200_000):
        s += float(np.linalg.norm(a @ a[:, 0]))
    return time.perf_counter() - t0


def machine_ceiling() -> dict:
    """The workload alone, then in two processes at once: the machine's 2-process efficiency."""
    import multiprocessing as mp
    ctx = mp.get_context("spawn")
    with ctx.Pool(2) as pool:
        alone = float(np.median([pool.apply(_workload) for _ in range(3)]))
        both = float(np.median(pool.map(_workload, range(4), chunksize=1)))
    return {"workload_alone_s": alone, "workload_two_at_once_s": both,
            "machine_two_process_efficiency": alone / both}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=100)
    ap.add_argument("--t-end", type=float, default=30.0)
    ap.add_argument("--skip-dask", action="store_true")
    args = ap.parse_args()
    spec = load_spec(spec_dict(args.cases, args.t_end))
    load_before = os.getloadavg()
    one, t1 = timed(lambda: sweep(spec, workers=1, progress=False))
    two, t2 = timed(lambda: sweep(spec, workers=2, progress=False))
    n = args.cases
    out = {"machine": platform.machine(), "cpus": os.cpu_count(), "python": platform.python_version(),
           "cases": n, "t_end_s": args.t_end,
           "one_worker": {"wall_s": t1, "cases_per_s_per_worker": n / t1, **overheads(one, t1, 1)},
           "pool_two_workers": {"wall_s": t2, "cases_per_s_per_worker": n / t2 / 2, **overheads(two, t2, 2)},
           "parallel_efficiency": t1 / (2 * t2)}
    if not args.skip_dask:
        from distributed import Client, LocalCluster
        t0 = time.perf_counter()
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
                Client(cluster) as client:
            client.run(lambda: __import__("hubbeam_ctrl.study.sweep"))
            start = time.perf_counter() - t0
            dask_df, td = timed(lambda: sweep(spec, client=client, progress=False))
        out["dask_local_cluster_two_workers"] = {
            "startup_s": start, "wall_s": td, "cases_per_s_per_worker": n / td / 2,
            "overhead_vs_pool": td / t2 - 1, "overhead_vs_pool_with_startup": (td + start) / t2 - 1,
            **overheads(dask_df, td, 2)}
    out.update(warm_overhead(args.t_end))
    out["machine"] = {"arch": out["machine"], **machine_ceiling()}
    out["parallel_efficiency_of_machine_ceiling"] = (out["parallel_efficiency"]
                                                     / out["machine"]["machine_two_process_efficiency"])
    out["load_avg_before_after"] = [load_before[0], os.getloadavg()[0]]
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
