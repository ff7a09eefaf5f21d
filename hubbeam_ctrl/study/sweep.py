"""Robustness sweeps: every controller of a study on every plant of its spread.

:func:`sweep` runs the cases of a :class:`~hubbeam_ctrl.study.spec.StudySpec` (one closed-loop
run per case and controller) in this process (``workers=1``), on a local process pool (the
default: one worker per core) or on a Dask cluster (``client=``), and returns one row per
(case, controller). The engines run the same function (:func:`run_batch`) on batches of
cases, so the numbers are the same everywhere; each worker process keeps the plant models,
design models and controllers it has built (:class:`CaseCache`) and reuses them for the
next case (a controller designed on the base parameters is built once per worker).

With ``out_dir`` the rows are appended to ``out_dir/results.csv`` as cases finish (one
write per batch, whole lines only); ``resume=True`` skips the cases already there. The
folder remembers the spec's hash (``study.json``) and refuses a different spec.

Examples
--------
>>> from hubbeam_ctrl.study.sweep import sweep                       # doctest: +SKIP
>>> df = sweep({"study": {"controllers": ["lqr"]}, "grid": {"m_t": [0.0, 0.3]}})  # doctest: +SKIP
>>> df[["m_t", "controller", "residual_tip_max_m"]]                  # doctest: +SKIP
"""

from __future__ import annotations

import json
import math
import os
import time
from collections import OrderedDict

from controllers import CONTROLLERS, DesignModel, as_shaper, make_controller
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.sim.closedloop import simulate_closed_loop
from hubbeam_ctrl.sim.evaluation import evaluation_plant
from hubbeam_ctrl.study.compare import _design_schedule
from hubbeam_ctrl.study.judge import judge, residual_modes_for
from hubbeam_ctrl.study.rig_loop import on_rig, rig_closed_loop, rig_design, rig_settings, task_noise
from hubbeam_ctrl.study.settings_table import controller_settings
from hubbeam_ctrl.study.shaping import task_shaped_settings
from hubbeam_ctrl.study.spec import StudySpec
from hubbeam_ctrl.study.spec_files import load_spec

# the study folder on disk (results.csv, study.json, the lock); its names stay importable from here
# connecting to a Dask cluster; the name stays importable from here
from hubbeam_ctrl.study.sweep_cluster import _one_line, connect
from hubbeam_ctrl.study.sweep_store import _RESULTS, _frame, _StudyFolder, read_results, result_columns

__all__ = ["sweep", "check_workers", "MAX_WORKERS", "run_case", "run_batch", "CaseCache", "result_columns",
           "read_results", "connect", "plan_batches", "Engine", "TIMING_COLUMNS"]

#: Columns that hold wall times (they differ from run to run; everything else is deterministic).
TIMING_COLUMNS = ("setup_s", "wall_s", "sim_wall_s", "step_time_median_ms", "step_time_p99_ms")


# -- one case -------------------------------------------------------------------------------
class CaseCache:
    """What a worker process keeps between cases: plant models, design models, scenarios
    and controllers, keyed by everything that determines them (least recently used first
    out beyond ``size`` entries).

    Parameters
    ----------
    size : int
        Entries kept.
    """

    def __init__(self, size: int = 64):
        self.size = size
        self._items = OrderedDict()
        self.hits = self.misses = 0

    def get(self, key, build):
        """The entry of ``key``, built by ``build()`` on a miss.

        Parameters
        ----------
        key : hashable
            What the entry is (model, parameters, ...).
        build : callable
            Makes the entry on a miss.
        """
        if key in self._items:
            self._items.move_to_end(key)
            self.hits += 1
            return self._items[key]
        self.misses += 1
        value = build()
        self._items[key] = value
        if len(self._items) > self.size:
            self._items.popitem(last=False)
        return value


_PROCESS_CACHE = CaseCache()


def _task_key(spec: StudySpec) -> tuple:
    return (spec.scenario, spec.plant, spec.tau_max, spec.t_f, spec.t_end, spec.dt, spec.horizon,
            spec.solver, spec.design_modes, spec.plant_modes, spec.slew_angle, spec.shaping, spec.schedule,
            json.dumps(spec.tolerances, sort_keys=True))


def run_case(case: dict, spec: StudySpec, cache: CaseCache | None = None) -> list:
    """Run every controller of ``spec`` on one case of its plant spread.

    This function and its two helpers (``_case_context``: scenario, design model, plant;
    ``_run_controller``: controller, closed-loop run, metrics) are the only code that calls
    the comparison API; adapt them when that API changes.

    Parameters
    ----------
    case : dict
        Factor -> value (one element of :meth:`StudySpec.cases`).
    spec : StudySpec
    cache : CaseCache, optional
        Reused plant models, design models and controllers (default: this process's).

    Returns
    -------
    list of dict
        One row per controller: the metrics of
        :func:`~hubbeam_ctrl.study.metrics.closed_loop_metrics` plus ``verdict`` (None until
        the metrics give one), ``residual_pct_of_openloop``, ``error`` (one line, or ""),
        ``setup_s`` (scenario, plant and design model of the case) [s], ``wall_s``
        (controller, run and metrics) [s] and ``sim_wall_s`` (the run alone) [s].
    """
    cache = _PROCESS_CACHE if cache is None else cache
    t0 = time.perf_counter()
    try:
        ctx = _case_context(case, spec, cache)
    except Exception as exc:  # noqa: BLE001 - a case that cannot be set up is a row with its error
        return [_error_row(name, spec, _one_line(exc)) for name in spec.controllers]
    setup = time.perf_counter() - t0
    rows = []
    for name in spec.controllers:
        t1 = time.perf_counter()
        try:
            row = _run_controller(name, ctx, spec, cache)
        except Exception as exc:  # noqa: BLE001
            row = _error_row(name, spec, _one_line(exc))
        row.update(setup_s=setup, wall_s=time.perf_counter() - t1)
        rows.append(row)
    _percent_of_openloop(rows)
    return rows


def _case_context(case: dict, spec: StudySpec, cache: CaseCache) -> dict:
    """Scenario, design model, plant model and simulator settings of one case (cached)."""
    plant_p, design_p = spec.plant_params(case), spec.design_params(case)
    w_f = float(case.get("w_f", spec.w_f))
    task = _task_key(spec)
    sc = cache.get(("scenario", task, design_p, w_f), lambda: spec.scenario_for(design_p, w_f))
    base = cache.get(("scenario", task, spec.params, spec.w_f), lambda: spec.scenario_for(spec.params))
    spin = sc.design_spin if spec.design == "matched" else base.design_spin
    dkey = ("design", design_p, spin, spec.dt, spec.design_modes)
    m = spec.design_modes or design_p.n_transverse
    # the same evaluation plant as compare(): the plant's physics, more modes than the design
    pkey = ("plant", spec.plant, plant_p, design_p, spin, spec.dt, m, spec.plant_modes)
    return {"scenario": sc, "key": (dkey, task, design_p, w_f),
            "design": cache.get(dkey, lambda: _rig_design(DesignModel.build(design_p, spin, spec.dt,
                                                                            spec.design_modes), spec.rig)),
            "plant": cache.get(pkey, lambda: evaluation_plant(spec.plant, design_p, spec.dt, m, spin,
                                                              plant_params=plant_p,
                                                              plant_modes=spec.plant_modes)),
            "sim": sc.closed_loop_settings(seed=int(case.get("seed", 0))),
            "hardware": None if spec.rig is None else rig_closed_loop(spec.rig, sc.closed_loop_settings())[1]}


def _run_controller(name: str, ctx: dict, spec: StudySpec, cache: CaseCache) -> dict:
    """One closed-loop run and its metrics (the controller built once per design and task)."""
    sc, table, cspec = ctx["scenario"], spec.settings.get(name), CONTROLLERS[name]
    ckey = ("controller", name, json.dumps(table, sort_keys=True, default=str), *ctx["key"], ctx["plant"].modes)

    def build():
        design = ctx["design"]
        shaper = as_shaper(design, spec.shaping) if spec.shaping and cspec.tracks_reference else None
        sched = _design_schedule(sc, spec.schedule, design.n_modes) if cspec.scheduled else None
        st = residual_modes_for(controller_settings(name, table, sc, spec.horizon, spec.solver),
                                ctx["plant"].modes)
        if "duration" not in (table or {}):
            st = task_shaped_settings(name, st, design, sc)[0]
        if spec.rig is None:
            return make_controller(name, design, st, sc.reference, shaping=shaper, schedule=sched)
        # on the rig exactly as compare(): integral action, observer, voltage (study.rig_loop)
        st = rig_settings(name, st, spec.rig, spec.integral)
        ctrl = make_controller(name, design, st, sc.reference, shaping=shaper, schedule=sched)
        return on_rig(ctrl, spec.rig, task_noise(sc, spec.rig), ctx["hardware"], spec.integral)
    ctrl = cache.get(ckey, build)
    res = simulate_closed_loop(ctx["plant"], ctrl, sc.t_end, settings=ctx["sim"],
                               reference=(sc.reference.theta_at, sc.reference.theta_dot_at), backend=spec.backend,
                               hardware=ctx["hardware"])
    row, _ = judge(res, ctrl, sc, ctx["plant"].params, name)
    row.update(scenario=sc.name, verdict=row.get("verdict"), error="", sim_wall_s=row["wall_s"])
    return row


def _error_row(name: str, spec: StudySpec, message: str) -> dict:
    return {"controller": name, "plant": spec.plant, "scenario": spec.scenario, "completed": False,
            "verdict": None, "error": message, "message": message}


def _percent_of_openloop(rows: list) -> None:
    base = next((r.get("residual_tip_max_m") for r in rows if r["controller"] == "openloop"), None)
    for r in rows:
        value = r.get("residual_tip_max_m")
        ok = base is not None and value is not None and math.isfinite(base) and base > 0
        r["residual_pct_of_openloop"] = 100.0 * value / base if ok else float("nan")


def run_batch(batch: list, spec: StudySpec) -> list:
    """Run ``[(case_id, case), ...]`` with this process's cache; rows carry ``case`` and
    the factor values (what every engine ships to a worker).

    Parameters
    ----------
    batch : list of (int, dict)
    spec : StudySpec

    Returns
    -------
    list of dict
    """
    out = []
    for case_id, case in batch:
        for row in run_case(case, spec):
            out.append({"case": case_id, **{f: case.get(f) for f in spec.factors}, **row})
    return out


def _failed_batch(batch: list, spec: StudySpec, message: str) -> list:
    return [{"case": cid, **{f: case.get(f) for f in spec.factors}, **_error_row(n, spec, message)}
            for cid, case in batch for n in spec.controllers]


# -- batches and engines ------------------------------------------------------------------------
def plan_batches(cases: list, workers: int, per_worker: int = 4, cap: int = 32) -> list:
    """Split ``[(case_id, case)]`` into batches of decreasing size (guided self-scheduling).

    Cases that share a plant stay together (each worker then builds a plant once per
    batch), the first batches are large (little scheduling overhead) and the last ones hold
    one case each (the workers finish together).

    Parameters
    ----------
    cases : list of (int, dict)
    workers : int
        Worker processes.
    per_worker : int
        Each batch takes ``1/(per_worker * workers)`` of the remaining cases.
    cap : int
        Largest batch.

    Returns
    -------
    list of list
    """
    order = sorted(cases, key=lambda c: json.dumps({k: v for k, v in c[1].items() if k not in ("seed", "w_f")},
                                                   sort_keys=True))
    batches, i = [], 0
    while i < len(order):
        size = min(cap, max(1, math.ceil((len(order) - i) / (per_worker * workers))))
        batches.append(order[i:i + size])
        i += size
    return batches


#: Most local worker processes (a pool's semaphore and file descriptors bound it; far above any core count).
MAX_WORKERS = 1024


def check_workers(workers) -> int:
    """Return ``workers``; raise unless it is an integer in 1..:data:`MAX_WORKERS`.

    Parameters
    ----------
    workers : int
        Local worker processes.
    """
    if isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= MAX_WORKERS:
        raise ParameterError(f"workers must be an integer in 1..{MAX_WORKERS}, got {workers!r}")
    return workers


def available_processors() -> int:
    """The processors this process may run on (its affinity; ``os.cpu_count()`` where that is unknown).

    Returns
    -------
    int
    """
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


#: How often a pool worker checks that the process that started it is still there [s].
PARENT_CHECK_S = 0.5


def _process_gone(pid: int) -> bool:
    """True when process ``pid`` has exited (a zombie counts as exited)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except OSError:
        return False
    try:
        with open(f"/proc/{pid}/stat", "rb") as fh:
            return fh.read().rsplit(b")", 1)[1].split()[0] in (b"Z", b"X")
    except (OSError, IndexError):
        return False


def _watch_parent(pid: int) -> None:
    while not _process_gone(pid):
        time.sleep(PARENT_CHECK_S)
    os._exit(1)


def _worker_init(parent_pid: int) -> None:
    """Pool worker set-up: Ctrl-C is the main process's to handle (it stops the workers), and a
    worker whose main process has gone (SIGTERM, SIGKILL) exits instead of finishing its batch
    while holding the terminal's pipes."""
    import signal
    import threading
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=_watch_parent, args=(parent_pid,), daemon=True, name="hubbeam-parent").start()


def _pool_context():
    import multiprocessing as mp
    if "forkserver" in mp.get_all_start_methods():
        ctx = mp.get_context("forkserver")
        ctx.set_forkserver_preload(["hubbeam_ctrl.study.sweep"])
        return ctx
    return mp.get_context("spawn")


class Engine:
    """Where batches run: this process, a local process pool, or a Dask cluster.

    Use it as a context manager; the pool (and with it each worker's :class:`CaseCache`)
    lives until the ``with`` block ends, so repeated :meth:`run` calls (a tuner's
    generations) reuse warm workers.

    Parameters
    ----------
    workers : int, optional
        Local worker processes (default: one per core); 1 runs in this process.
    client : distributed.Client, optional
        Run on this Dask cluster (``workers`` is then ignored).
    retries : int
        Dask: reruns of a task whose worker raised; a task whose worker died is rerun by the
        scheduler (up to its ``allowed-failures``). Pool: fresh pools for batches lost with a
        dead worker.
    """

    def __init__(self, workers: int | None = None, client=None, retries: int = 2):
        if workers is not None:
            check_workers(workers)
        self.client, self.retries = client, retries
        self.workers = _dask_workers(client) if client is not None else (workers or available_processors())
        self._pool = None

    def __enter__(self):
        return self

    def __exit__(self, exc_type, *exc):
        if exc_type is None:
            self.close()
        else:
            self.terminate()
        return False

    def close(self) -> None:
        """Shut the local pool down (a Dask client stays open: it is the caller's)."""
        if self._pool is not None:
            self._pool.shutdown(cancel_futures=True)
            self._pool = None

    def terminate(self, timeout: float = 5.0) -> None:
        """Stop the local pool now: its workers are sent SIGTERM (SIGKILL after ``timeout``),
        queued batches are dropped and nothing is waited for beyond that; a second Ctrl-C
        meanwhile is ignored, so an interrupted sweep cannot hang in its clean-up.

        Parameters
        ----------
        timeout : float
            Seconds the workers get to exit before they are killed.
        """
        pool, self._pool = self._pool, None
        if pool is None:
            return
        import signal
        import threading
        main = threading.current_thread() is threading.main_thread()
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None
        try:
            processes = list((getattr(pool, "_processes", None) or {}).values())
            for proc in processes:
                if proc.is_alive():
                    proc.terminate()
            pool.shutdown(wait=False, cancel_futures=True)
            deadline = time.monotonic() + timeout
            for proc in processes:
                proc.join(max(0.0, deadline - time.monotonic()))
                if proc.is_alive():
                    proc.kill()
                    proc.join(1.0)
        finally:
            if main:
                signal.signal(signal.SIGINT, previous if previous is not None else signal.default_int_handler)

    def run(self, jobs: list, sink) -> None:
        """Run ``[(batch, spec), ...]`` with :func:`run_batch`; ``sink(batch, spec, rows)`` gets
        each batch's rows as it finishes (in completion order).

        Parameters
        ----------
        jobs : list
            ``[(batch, spec), ...]``.
        sink : callable
            ``sink(batch, spec, rows)``, called as each batch finishes.
        """
        if self.client is not None:
            self._run_dask(jobs, sink)
        elif self.workers == 1 or sum(len(b) for b, _ in jobs) <= 1:
            for batch, spec in jobs:
                sink(batch, spec, run_batch(batch, spec))
        else:
            self._run_pool(jobs, sink)

    def _submit_pool(self, jobs):
        from concurrent.futures import ProcessPoolExecutor
        if self._pool is None:
            self._pool = ProcessPoolExecutor(self.workers, mp_context=_pool_context(),
                                             initializer=_worker_init, initargs=(os.getpid(),))
        return {self._pool.submit(run_batch, b, s): (b, s) for b, s in jobs}

    def _run_pool(self, jobs, sink) -> None:
        from concurrent.futures import as_completed
        from concurrent.futures.process import BrokenProcessPool
        for _ in range(self.retries + 1):
            lost = []
            futures = self._submit_pool(jobs)
            for fut in as_completed(futures):
                batch, spec = futures[fut]
                try:
                    sink(batch, spec, fut.result())
                except BrokenProcessPool:
                    lost.append((batch, spec))
                except Exception as exc:  # noqa: BLE001
                    sink(batch, spec, _failed_batch(batch, spec, _one_line(exc)))
            if not lost:
                return
            self.close()
            jobs = lost
        for batch, spec in jobs:
            sink(batch, spec, _failed_batch(batch, spec, "worker process died on this case"))

    def _run_dask(self, jobs, sink) -> None:
        from distributed import as_completed
        futures = {self.client.submit(run_batch, b, s, retries=self.retries, pure=False): (b, s)
                   for b, s in jobs}
        # the client's own loop: as_completed would otherwise look for a default client, and
        # connect() makes none (set_as_default=False keeps the caller's global state alone)
        for fut in as_completed(list(futures), loop=self.client.loop):
            batch, spec = futures[fut]
            try:
                sink(batch, spec, fut.result())
            except Exception as exc:  # noqa: BLE001 - KilledWorker etc.: rows with the error
                sink(batch, spec, _failed_batch(batch, spec, _one_line(exc)))
            fut.release()


# -- the study ----------------------------------------------------------------------------------
def sweep(spec, *, workers: int | None = None, client=None, progress: bool = True, out_dir=None,
          resume: bool = False):
    """Run a robustness study: every controller on every case of the plant spread.

    Parameters
    ----------
    spec : StudySpec, dict or path of a TOML file
    workers : int, optional
        Local worker processes (default: one per core); 1 runs in this process. Ignored
        with ``client``.
    client : distributed.Client, optional
        Run on this Dask cluster instead (see :func:`connect`).
    progress : bool
        tqdm bar on stderr (cases done, failed, ETA).
    out_dir : str or Path, optional
        Folder for ``results.csv`` (appended as cases finish) and ``study.json``.
    resume : bool
        Skip the cases already in ``out_dir/results.csv``.

    Returns
    -------
    pandas.DataFrame
        One row per (case, controller): ``case``, the factor values, ``controller``, the
        metrics, ``verdict``, ``error`` (one line, empty when the run worked) and the wall
        times ``setup_s``, ``wall_s``, ``sim_wall_s`` [s] (see :data:`TIMING_COLUMNS`).
    """
    spec = load_spec(spec)
    Engine(workers)  # validates workers before anything is written
    cases = list(enumerate(spec.cases()))
    if out_dir is None:
        return _run_cases(spec, cases, workers, client, progress, None)
    with _StudyFolder(out_dir, spec, resume) as folder:
        _run_cases(spec, [c for c in cases if c[0] not in folder.done], workers, client, progress, folder.results)
        try:
            return read_results(folder.out, spec)
        except (ValueError, TypeError, KeyError) as exc:
            raise ParameterError(f"out: {folder.out / _RESULTS} is damaged ({_one_line(exc)}); "
                                 "choose another --out") from None


def _run_cases(spec: StudySpec, cases: list, workers, client, progress: bool, results):
    """Run ``cases`` on the engine; rows appended to ``results`` (a :class:`_ResultsFile`) as
    they come, and returned as a DataFrame when there is no file."""
    from hubbeam_ctrl.core.progress import progress_bar
    rows = []
    bar = progress_bar(len(cases), "sweep", enabled=progress)     # quiet off a terminal and under --json
    failed = 0

    def sink(batch, _spec, batch_rows):
        nonlocal failed
        if results is not None:
            results.append(batch_rows)
        rows.extend(batch_rows)
        failed += len({r["case"] for r in batch_rows if r.get("error") or r.get("completed") is False})
        bar.update(len(batch))
        bar.set_postfix(failed=failed)

    try:
        with Engine(workers, client) as engine:
            engine.run([(b, spec) for b in plan_batches(cases, engine.workers)], sink)
    finally:
        bar.close()
    return None if results is not None else _frame(rows, spec)


def _dask_workers(client) -> int:
    try:
        return max(1, sum(client.nthreads().values()))
    except Exception:  # noqa: BLE001
        return 1


def _rig_design(design, rig):
    """The design on the sweep's rig (:func:`~hubbeam_ctrl.study.rig_loop.rig_design`), or itself."""
    return design if rig is None else rig_design(design, rig)
