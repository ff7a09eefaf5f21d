"""Sweeps: numbers equal to single runs, the same on every engine, no lost work."""

import json
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from conftest import ENV

from hubbeam_ctrl.cli.main import main
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.study.compare import compare
from hubbeam_ctrl.study.compare_values import CompareSettings, DesignChoice, PlantChoice, RunChoice, ScenarioChoice
from hubbeam_ctrl.study.spec_files import load_spec
from hubbeam_ctrl.study.sweep import TIMING_COLUMNS, CaseCache, plan_batches, read_results, run_case, sweep

#: Plant modes of the engine tests: the design's 2, so that the tests of the engine (pool, cluster, resume,
#: cache) stay fast; the sweep on the default evaluation plant (10 modes here) is checked against compare()
#: in test_matched_rows_equal_single_comparisons, and the plant rule itself in test_evaluation.py.
ENGINE_PLANT_MODES = 2


def small(t_end=6.5, controllers=("openloop", "lqr", "lqg"), plant_modes=ENGINE_PLANT_MODES, **tables):
    """2+2 modes, a 1 s slew, FOAM; evaluated on ``plant_modes`` (None: the evaluation-plant rule)."""
    study = {"controllers": list(controllers), "t_f": 1.0, "t_end": t_end, **tables.pop("study", {})}
    if plant_modes is not None:
        study["plant_modes"] = plant_modes
    return {"study": study, "params": {"n_axial": 2, "n_transverse": 2}, **tables}


def same_numbers(a, b):
    cols = [c for c in a.columns if c not in TIMING_COLUMNS]
    assert list(a.columns) == list(b.columns)
    for c in cols:
        x, y = a[c].to_numpy(), b[c].to_numpy()
        if x.dtype.kind == "f":
            assert np.array_equal(x, y, equal_nan=True), c      # bit for bit
        else:
            assert list(x) == list(y), c


@pytest.mark.slow
def test_matched_rows_equal_single_comparisons():
    spec = load_spec(small(study={"design": "matched"}, grid={"m_t": [0.0, 0.3]}, plant_modes=None))
    df = sweep(spec, workers=1, progress=False)
    assert len(df) == 6 and list(df["controller"][:3]) == ["openloop", "lqr", "lqg"]
    for m_t in (0.0, 0.3):
        ref = compare(Params(m_t=m_t, n_axial=2, n_transverse=2), "slew", "openloop,lqr,lqg",
                      CompareSettings(run=RunChoice(t_end=6.5), scenario=ScenarioChoice(t_f=1.0))).metrics
        for name, m in ref.items():
            row = df[(df["m_t"] == m_t) & (df["controller"] == name)].iloc[0]
            for key in ("peak_tip_m", "residual_tip_max_m", "final_angle_error_rad", "residual_pct_of_openloop",
                        "torque_squared_integral_n2m2s"):
                assert row[key] == m[key], (m_t, name, key)
            assert row["error"] == "" and row["verdict"] == m.get("verdict")


def test_task_keys_give_the_numbers_of_compare():
    """A sweep with a slew angle, an input shaper, a design schedule and tolerances gives the
    numbers of compare() with the same options, bit for bit (same code path, same backend)."""
    tol = {"angle_error": 5e-4, "residual_delay": 1.0}
    spec = load_spec(small(controllers=("openloop", "lqr", "mpc"), study={"slew_angle": 0.1, "shaping": "zv",
                                                                      "schedule": 2, "tolerances": tol}))
    df = sweep(spec, workers=1, progress=False)
    ref = compare(Params(n_axial=2, n_transverse=2), "slew", "openloop,lqr,mpc",
                  CompareSettings(plant=PlantChoice(plant_modes=ENGINE_PLANT_MODES),
                                  design=DesignChoice(shaping="zv", schedule=2,
                                                      tolerances=spec.scenario_for(spec.params).tolerances),
                                  run=RunChoice(t_end=6.5), scenario=ScenarioChoice(t_f=1.0, slew_angle=0.1))).metrics
    for name, m in ref.items():
        row = df[df["controller"] == name].iloc[0]
        for key in ("peak_tip_m", "residual_tip_max_m", "final_angle_error_rad", "residual_pct_of_openloop"):
            assert row[key] == m[key], (name, key)
    assert abs(df[df["controller"] == "lqr"].iloc[0]["final_angle_error_rad"]) < 0.05 * 0.1


def test_base_design_stays_at_the_base_and_the_cache_changes_nothing():
    spec = load_spec(small(grid={"m_t": [0.1, 0.4], "seed": [0, 5]}))
    cache = CaseCache()
    rows = {(c["m_t"], c["seed"]): run_case(c, spec, cache) for c in spec.cases()}
    assert cache.misses == 1 + 1 + 2 + 3      # scenario, design, plant x2, 3 controllers; the rest hits
    fresh = run_case({"m_t": 0.4, "seed": 5}, spec, CaseCache())
    assert [r["residual_tip_max_m"] for r in fresh] == [r["residual_tip_max_m"] for r in rows[(0.4, 5)]]
    # base design: at m_t = 0.1 (the base) the rows equal compare's on the base parameters
    ref = compare(Params(n_axial=2, n_transverse=2), "slew", "lqr",
                  CompareSettings(plant=PlantChoice(plant_modes=ENGINE_PLANT_MODES), run=RunChoice(t_end=6.5),
                                  scenario=ScenarioChoice(t_f=1.0))).metrics
    assert rows[(0.1, 0)][1]["residual_tip_max_m"] == ref["lqr"]["residual_tip_max_m"]
    matched = compare(Params(m_t=0.4, n_axial=2, n_transverse=2), "slew", "lqr",
                      CompareSettings(plant=PlantChoice(plant_modes=ENGINE_PLANT_MODES),
                                      run=RunChoice(t_end=6.5), scenario=ScenarioChoice(t_f=1.0))).metrics
    assert rows[(0.4, 0)][1]["residual_tip_max_m"] != matched["lqr"]["residual_tip_max_m"]
    # the seed moves only the sensor noise: LQG (sensors) changes, LQR (state) does not
    assert rows[(0.4, 0)][1]["residual_tip_max_m"] == rows[(0.4, 5)][1]["residual_tip_max_m"]
    assert rows[(0.4, 0)][2]["residual_tip_max_m"] != rows[(0.4, 5)][2]["residual_tip_max_m"]


def test_spin_rate_factor_keeps_the_design_at_the_base_rate():
    spec = load_spec(small(t_end=16.0, controllers=("lqr",), study={"scenario": "spinup", "w_f": 3.0, "t_f": 10.0},
                           grid={"w_f": [2.0, 3.0]}))
    df = sweep(spec, workers=1, progress=False)
    p = Params(n_axial=2, n_transverse=2)
    at_base = compare(p, "spinup", "lqr",
                      CompareSettings(plant=PlantChoice(plant_modes=ENGINE_PLANT_MODES),
                                      run=RunChoice(t_end=16.0),
                                      scenario=ScenarioChoice(t_f=10.0, w_f=3.0))).metrics["lqr"]
    matched = compare(p, "spinup", "lqr",
                      CompareSettings(plant=PlantChoice(plant_modes=ENGINE_PLANT_MODES),
                                      run=RunChoice(t_end=16.0),
                                      scenario=ScenarioChoice(t_f=10.0, w_f=2.0))).metrics["lqr"]
    assert df.loc[df["w_f"] == 3.0, "residual_tip_max_m"].item() == at_base["residual_tip_max_m"]
    # at 2 rad/s the task changes but the design stays linearised at 3 rad/s
    assert df.loc[df["w_f"] == 2.0, "residual_tip_max_m"].item() != matched["residual_tip_max_m"]
    redesigned = sweep(spec.replace(design="matched"), workers=1, progress=False)
    assert redesigned.loc[redesigned["w_f"] == 2.0, "residual_tip_max_m"].item() == matched["residual_tip_max_m"]


def test_a_failing_case_is_a_row_and_the_study_goes_on(monkeypatch):
    """A case that raises becomes an error row; the others run. (Samples outside a factor's
    range are refused up front since issue 28, so the failure is injected.)"""
    import sys
    sweep_module = sys.modules["hubbeam_ctrl.study.sweep"]     # the package's `sweep` is the function
    run = sweep_module._run_controller

    def failing(name, ctx, spec, cache):
        if abs(ctx["plant"].params.m_t - 0.2) < 1e-12:
            raise RuntimeError("injected failure at m_t = 0.2")
        return run(name, ctx, spec, cache)
    monkeypatch.setattr(sweep_module, "_run_controller", failing)
    spec = load_spec(small(controllers=("lqr",), grid={"m_t": [0.0, 0.2, 0.4]}))
    df = sweep(spec, workers=1, progress=False)
    bad = (df["m_t"] - 0.2).abs() < 1e-12
    assert bad.sum() == 1 and len(df) == 3
    assert all("injected failure" in e for e in df.loc[bad, "error"])
    assert df.loc[bad, "residual_tip_max_m"].isna().all() and not df.loc[bad, "completed"].any()
    assert (df.loc[~bad, "error"] == "").all() and df.loc[~bad, "residual_tip_max_m"].notna().all()


def test_batches_keep_plants_together_and_shrink():
    cases = list(enumerate({"m_t": m, "seed": s} for s in range(5) for m in (0.0, 0.1, 0.2, 0.3)))
    batches = plan_batches(cases, workers=2)
    assert sorted(c[0] for b in batches for c in b) == list(range(20))
    sizes = [len(b) for b in batches]
    assert sizes == sorted(sizes, reverse=True) and sizes[0] > 1 and sizes[-1] == 1
    flat = [c[1]["m_t"] for b in batches for c in b]
    assert flat == sorted(flat)               # the five seeds of one plant are neighbours


def test_pool_equals_in_process_and_output_folder_rules(tmp_path):
    spec = load_spec(small(grid={"m_t": [0.0, 0.2, 0.4], "seed": [0, 1]}))
    one = sweep(spec, workers=1, progress=False)
    out = tmp_path / "study"
    pool = sweep(spec, workers=2, progress=False, out_dir=out)
    same_numbers(one, pool)
    same_numbers(one, read_results(out, spec))
    text = (out / "results.csv").read_text()
    with pytest.raises(ParameterError, match="pass --resume"):
        sweep(spec, workers=1, progress=False, out_dir=out)
    other = load_spec(small(grid={"m_t": [0.0, 0.2]}))
    for resume in (False, True):
        with pytest.raises(ParameterError, match="different study spec"):
            sweep(other, workers=1, progress=False, out_dir=out, resume=resume)
    assert (out / "results.csv").read_text() == text          # nothing overwritten
    again = sweep(spec, workers=1, progress=False, out_dir=out, resume=True)   # nothing left to run
    assert (out / "results.csv").read_text() == text
    same_numbers(one, again)


# -- a real Dask cluster ----------------------------------------------------------------------
def _start(args):
    return subprocess.Popen([sys.executable, "-m", *args], env=ENV, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)


@pytest.fixture
def dask_cluster(tmp_path):
    """A scheduler and two single-threaded worker processes (no nanny) on localhost."""
    distributed = pytest.importorskip("distributed")
    sched_file = tmp_path / "scheduler.json"
    procs = [_start(["distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", "0",
                     "--no-dashboard", "--scheduler-file", str(sched_file)])]
    try:
        deadline = time.time() + 60
        while not sched_file.exists() and time.time() < deadline:
            time.sleep(0.2)
        workers = [_start(["distributed.cli.dask_worker", "--scheduler-file", str(sched_file), "--nthreads", "1",
                           "--no-nanny", "--no-dashboard", "--preload", "hubbeam_ctrl.study.sweep",
                           "--name", f"w{i}"]) for i in range(2)]
        procs += workers
        client = distributed.Client(scheduler_file=str(sched_file), timeout=60)
        client.wait_for_workers(2, timeout=180)
        yield client, workers
        client.close()
    finally:
        for p in procs[::-1]:
            if p.poll() is None:
                p.terminate()
                try:
                    p.wait(10)
                except subprocess.TimeoutExpired:
                    p.kill()


@pytest.mark.slow
def test_dask_cluster_bit_equal_and_survives_a_killed_worker(dask_cluster, tmp_path):
    client, workers = dask_cluster
    spec = load_spec(small(t_end=12.0, grid={"m_t": [0.0, 0.1, 0.2, 0.3, 0.4, 0.5], "seed": [0, 1]}))
    assert len(spec.cases()) == 12
    out = tmp_path / "cluster"
    result = {}
    thread = threading.Thread(target=lambda: result.setdefault(
        "df", sweep(spec, client=client, progress=False, out_dir=out)))
    thread.start()
    results = out / "results.csv"
    deadline = time.time() + 300
    while time.time() < deadline and not (results.exists() and len(results.read_text().splitlines()) > 1):
        time.sleep(0.05)
    workers[1].send_signal(signal.SIGKILL)          # mid-study: most cases still to run
    killed_after = len(results.read_text().splitlines()) - 1
    thread.join(600)
    df = result["df"]
    assert killed_after < 3 * 12
    assert sorted(df["case"].unique()) == list(range(12)) and len(df) == 36
    assert (df["error"] == "").all()
    same_numbers(sweep(spec, workers=1, progress=False), df)


# -- the command line -----------------------------------------------------------------------------
def _cli(*args, **kw):
    return subprocess.run([sys.executable, "-m", "hubbeam_ctrl.cli", *args], env=ENV, capture_output=True,
                          text=True, timeout=600, **kw)


def _write_spec(path, data):
    lines = []
    for table, content in data.items():
        lines.append(f"[{table}]")
        lines += [f"{k} = {json.dumps(v)}" for k, v in content.items()]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_cli_bad_input_exits_2_with_one_line(tmp_path, capsys):
    spec = _write_spec(tmp_path / "bad.toml", small(grid={"tip_mass": [0.1]}))
    assert main(["sweep", str(spec), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "unknown factor 'tip_mass'" in err
    assert not (tmp_path / "o").exists()
    good = _write_spec(tmp_path / "good.toml", small(grid={"m_t": [0.1]}))
    assert main(["sweep", str(good), "--out", str(tmp_path / "o"), "--scheduler", "tcp://127.0.0.1:9",
                 "--scheduler-timeout", "1"]) == 2
    err = capsys.readouterr().err
    assert "no Dask scheduler answered" in err and err.count("\n") == 1
    assert main(["sweep", str(good), "--out", str(tmp_path / "o"), "--settings", str(tmp_path / "none.toml")]) == 2
    assert "settings: file" in capsys.readouterr().err


def test_cli_sweep_in_process(tmp_path, capsys):
    good = _write_spec(tmp_path / "good.toml", small(controllers=("lqr",), grid={"m_t": [0.1, 0.3]}))
    assert main(["sweep", str(good), "--out", str(tmp_path / "o"), "--workers", "1", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["n_cases"] == 2 and out["n_failed"] == 0
    assert out["summary"][0]["residual_tip_max_m_worst"] == read_results(tmp_path / "o")["residual_tip_max_m"].max()
    assert {"summary.csv", "report.md", "robustness_m_t.png", "stable_region.png"} <= set(out["files"])


@pytest.mark.slow
def test_cli_resume_after_a_kill_redoes_nothing(tmp_path):
    spec = _write_spec(tmp_path / "s.toml", small(t_end=20.0, controllers=("openloop", "lqr"),
                                                  grid={"m_t": [0.0, 0.1, 0.2, 0.3, 0.4, 0.5]}))
    out = tmp_path / "o"
    proc = subprocess.Popen([sys.executable, "-m", "hubbeam_ctrl.cli", "sweep", str(spec), "--out", str(out),
                             "--workers", "1", "--json"], env=ENV, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    results = out / "results.csv"
    deadline = time.time() + 300
    while time.time() < deadline and not (results.exists() and len(results.read_text().splitlines()) >= 5):
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    before = results.read_text()
    n_before = len(before.splitlines()) - 1
    assert 4 <= n_before < 12                               # killed mid-study
    r = _cli("sweep", str(spec), "--out", str(out), "--json")
    assert r.returncode == 2 and "--resume" in r.stderr      # finished cases are not redone silently
    r = _cli("sweep", str(spec), "--out", str(out), "--workers", "1", "--resume", "--json")
    assert r.returncode == 0, r.stderr
    after = results.read_text()
    assert after.startswith(before)                         # finished rows kept byte for byte
    df = read_results(out)
    assert len(df) == 12 and not df.duplicated(["case", "controller"]).any()
    assert json.loads(r.stdout)["n_cases"] == 6
    for name in ("summary.csv", "report.md", "robustness_m_t.png", "stable_region.png"):
        assert (out / name).exists()
