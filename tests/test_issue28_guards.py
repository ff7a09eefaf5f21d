"""Issue 28, general guards: every input file through one guarded reader, loaders, resume,
budgets, CLI numbers, API arguments, disk-full. One line, the option or key named, no traceback."""

import os
import threading

import pytest

from hubbeam_ctrl.cli.main import main

GOOD_SPEC = """[study]
controllers = ["lqr"]
t_f = 1.0
t_end = 6.5
plant_modes = 2
[params]
n_axial = 2
n_transverse = 2
[grid]
m_t = [0.1]
"""


def _one_line(capsys, status, expected_status=2):
    err = capsys.readouterr().err
    assert status == expected_status, err
    assert err.count("\n") == 1 and err.startswith("hubbeam: error: ") and "Traceback" not in err, err
    return err


# -- spec and --settings files: the reader of --params ---------------------------------------------
def _bad_files(tmp_path):
    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)
    binary = tmp_path / "binary.toml"
    binary.write_bytes(b"\x89PNG\r\n\x1a\n\xff\xfe" * 10)
    big = tmp_path / "big.toml"
    big.write_text("# " + "x" * 5_000_000 + "\n")
    return {"fifo": (fifo, "not a regular file"), "device": ("/dev/zero", "not a regular file"),
            "folder": (tmp_path, "not a regular file"), "binary": (binary, "not UTF-8"),
            "big": (big, "larger than"), "missing": (tmp_path / "none.toml", "does not exist")}


@pytest.mark.parametrize("kind", ["fifo", "device", "folder", "binary", "big", "missing"])
def test_spec_and_settings_files_are_read_with_the_guards(tmp_path, capsys, kind):
    path, text = _bad_files(tmp_path)[kind]
    good = tmp_path / "good.toml"
    good.write_text(GOOD_SPEC)
    done = []
    for argv, what in ((["sweep", str(path), "--out", str(tmp_path / "o")], "spec: file"),
                       (["sweep", str(good), "--out", str(tmp_path / "o"), "--settings", str(path)], "settings: file"),
                       (["tune", str(path), "--controller", "lqr", "--out", str(tmp_path / "t")], "spec: file")):
        worker = threading.Thread(target=lambda a=argv: done.append(main(a)), daemon=True)
        worker.start()
        worker.join(60)
        assert not worker.is_alive(), f"{argv} hangs"              # a FIFO or /dev/zero must not block
        err = _one_line(capsys, done[-1])
        assert what in err and text in err, err
    assert not (tmp_path / "o").exists() and not (tmp_path / "t").exists()


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads every file")
def test_unreadable_spec_is_one_line(tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text(GOOD_SPEC)
    path.chmod(0)
    err = _one_line(capsys, main(["sweep", str(path), "--out", str(tmp_path / "o")]))
    assert "cannot be read" in err


@pytest.mark.parametrize("text, needle", [
    ("study = 1\n", "spec: study must be a table"),
    ("params = \"x\"\n", "spec: params must be a table"),
    ("[settings]\nlqr = 1\n", "settings.lqr must be a table"),
    ("[study]\nt_f = \"x\"\n", "t_f"),
    ("[study]\ncontrollers = 1\n", "study.controllers"),
])
def test_mistyped_spec_values_are_one_line(tmp_path, capsys, text, needle):
    path = tmp_path / "s.toml"
    path.write_text(text)
    err = _one_line(capsys, main(["sweep", str(path), "--out", str(tmp_path / "o")]))
    assert needle in err, err


def test_mistyped_settings_file_is_one_line(tmp_path, capsys):
    good = tmp_path / "good.toml"
    good.write_text(GOOD_SPEC)
    bad = tmp_path / "settings.toml"
    bad.write_text("settings = 1\n")
    err = _one_line(capsys, main(["sweep", str(good), "--out", str(tmp_path / "o"), "--settings", str(bad)]))
    assert "settings:" in err and "[settings.NAME]" in err


# -- .npz / .mat loaders -------------------------------------------------------------------------------
def _rewrite_npz(src, dst, meta=None, arrays=None):
    import json

    import numpy as np
    with np.load(src) as data:
        content = {k: data[k] for k in data.files}
    m = json.loads(str(content["metadata"]))
    m.update(meta or {})
    content["metadata"] = np.array(json.dumps(m))
    content.update(arrays or {})
    np.savez(dst, **content)
    return dst


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    """A model, a controller and a result saved by the toolbox (small)."""
    from controllers import CONTROLLERS, DesignModel, make_controller
    from controllers.export import save_controller
    from hubbeam_ctrl import Params, TorquePulse, simulate
    from hubbeam_ctrl.linear.export import save_model
    from hubbeam_ctrl.linear.statespace import linearize
    from hubbeam_ctrl.study.scenarios import make_scenario
    folder = tmp_path_factory.mktemp("saved")
    p = Params(n_axial=1, n_transverse=1)
    save_model(linearize("sfoam", spin=0.0, params=p), folder / "model.npz")
    sc = make_scenario("slew", plant="foam", params=p, t_f=1.0, t_end=6.5, dt=0.01)
    design = DesignModel.build(p, sc.design_spin, 0.01, 1)
    ctrl = make_controller("lqr", design, CONTROLLERS["lqr"].settings.for_scenario(sc), sc.reference)
    for suffix in ("npz", "mat"):
        save_controller(ctrl, folder / f"ctrl.{suffix}")
    simulate("foam", TorquePulse(10.0, 0.5), 0.5, params=p).save(folder / "result.npz")
    return folder


def test_zip_bomb_is_refused_on_its_unpacked_size(saved, tmp_path, monkeypatch):
    import numpy as np

    from hubbeam_ctrl.core import npz
    from hubbeam_ctrl.core.errors import ParameterError
    from hubbeam_ctrl.sim.results import load_result
    bomb = tmp_path / "bomb.npz"
    with np.load(saved / "result.npz") as data:
        content = {k: data[k] for k in data.files}
    content["extra"] = np.zeros(4_000_000)                       # 32 MB unpacked, ~30 kB on disk
    np.savez_compressed(bomb, **content)
    assert bomb.stat().st_size < 200_000
    monkeypatch.setattr(npz, "MAX_NPZ_BYTES", 16_000_000)
    import tracemalloc
    tracemalloc.start()
    with pytest.raises(ParameterError, match="unpack to .* bytes, more than the 16000000 read"):
        load_result(bomb)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 4_000_000                                      # nothing was unpacked


@pytest.mark.parametrize("loader, name", [("model", "model.npz"), ("controller", "ctrl.npz"),
                                          ("result", "result.npz")])
def test_an_array_header_announcing_more_than_it_holds_is_refused(saved, tmp_path, loader, name):
    import zipfile

    from hubbeam_ctrl.core.errors import ParameterError
    liar = tmp_path / name
    import shutil
    shutil.copy(saved / name, liar)
    header = b"\x93NUMPY\x01\x00" + b"v\x00" + b"{'descr': '<f8', 'fortran_order': False, 'shape': (400000000000,), }"
    header = header[:8] + (len(header) - 10).to_bytes(2, "little") + header[10:]
    with zipfile.ZipFile(liar, "a") as zf:
        zf.writestr("huge.npy", header + b"\x00" * 16)
    with pytest.raises(ParameterError, match="announces 3200000000000 bytes but holds"):
        _load(loader, liar)


def _load(loader, path):
    if loader == "model":
        from hubbeam_ctrl.linear.export import load_model
        return load_model(path)
    if loader == "controller":
        from controllers.export import load_controller
        return load_controller(path)
    from hubbeam_ctrl.sim.results import load_result
    return load_result(path)


@pytest.mark.parametrize("loader, name, meta, needle", [
    ("controller", "ctrl.npz", {"dt": float("nan")}, "dt nan is not a finite sample time"),
    ("controller", "ctrl.npz", {"dt": -0.01}, "dt -0.01 is not a finite sample time"),
    ("controller", "ctrl.npz", {"version": 99}, "format version 99"),
    ("controller", "ctrl.npz", {"format": "something-else"}, "format tag 'something-else'"),
    ("model", "model.npz", {"dt": float("nan")}, "dt nan"),
    ("model", "model.npz", {"version": 2}, "format version 2"),
    ("model", "model.npz", {"format": "hubbeam-controller"}, "format tag 'hubbeam-controller'"),
    ("result", "result.npz", {"settings": {"dt": float("nan")}}, r"settings.dt is not a finite number"),
    ("result", "result.npz", {"settings": {"rtol": [1e-8, float("inf")]}}, r"settings.rtol\[1\] is not a finite"),
])
def test_loaders_refuse_nan_and_foreign_tags(saved, tmp_path, loader, name, meta, needle):
    from hubbeam_ctrl.core.errors import ParameterError
    bad = _rewrite_npz(saved / name, tmp_path / name, meta=meta)
    with pytest.raises(ParameterError, match=needle) as err:
        _load(loader, bad)
    assert "\n" not in str(err.value)
    _load(loader, saved / name)                                     # the original loads


def test_mat_controller_with_a_foreign_version_is_refused(saved, tmp_path):
    import json

    import numpy as np
    from scipy.io import loadmat, savemat

    from hubbeam_ctrl.core.errors import ParameterError
    data = {k: v for k, v in loadmat(saved / "ctrl.mat").items() if not k.startswith("__")}
    meta = json.loads(str(np.asarray(data["hubbeam_metadata"]).ravel()[0]))
    meta["version"] = 7
    data["hubbeam_metadata"] = json.dumps(meta)
    savemat(tmp_path / "ctrl.mat", data)
    with pytest.raises(ParameterError, match="format version 7"):
        _load("controller", tmp_path / "ctrl.mat")


# -- sweep folders: resume repairs or refuses, one sweep at a time, nothing half-made ---------------
def _study(tmp_path, name="study"):
    from hubbeam_ctrl.study.spec_files import load_spec
    from hubbeam_ctrl.study.sweep import sweep
    spec = load_spec({"study": {"controllers": ["openloop"], "t_f": 1.0, "t_end": 6.5, "plant_modes": 2},
                      "params": {"n_axial": 2, "n_transverse": 2}, "grid": {"m_t": [0.0, 0.1, 0.2]}})
    out = tmp_path / name
    df = sweep(spec, workers=1, progress=False, out_dir=out)
    return spec, out, df


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    return _study(tmp_path_factory.mktemp("finished"))


def _copy(finished, tmp_path):
    import shutil
    spec, out, df = finished
    dst = tmp_path / "copy"
    shutil.copytree(out, dst)
    return spec, dst, df


def test_resume_drops_duplicate_foreign_and_incomplete_rows(finished, tmp_path):
    import numpy as np

    from hubbeam_ctrl.study.sweep import TIMING_COLUMNS, read_results, sweep
    spec, out, df = _copy(finished, tmp_path)
    path = out / "results.csv"
    header, *rows = path.read_text().splitlines()
    by_case = {int(r.split(",", 1)[0]): r for r in rows}
    foreign = "999" + by_case[0][1:]
    other_ctrl = by_case[1].replace(",openloop,", ",lqr,")
    damaged = [header, by_case[0], by_case[1], by_case[1], foreign, other_ctrl]
    path.write_text("\n".join(damaged) + "\n" + by_case[2][:30])           # and a line cut short
    again = sweep(spec, workers=1, progress=False, out_dir=out, resume=True)
    assert sorted(again["case"]) == [0, 1, 2] and not again.duplicated(["case", "controller"]).any()
    lines = path.read_text().splitlines()
    assert lines[:3] == [header, by_case[0], by_case[1]]            # kept byte for byte, first
    assert len(lines) == 4 and "999" not in {ln.split(",", 1)[0] for ln in lines}
    for c in df.columns:
        if c not in TIMING_COLUMNS and df[c].dtype.kind == "f":
            assert np.array_equal(df[c].to_numpy(), again[c].to_numpy(), equal_nan=True), c
    assert len(read_results(out)) == 3


@pytest.mark.parametrize("damage, needle", [
    ({"study.json": b"{not json"}, "study.json is damaged (not JSON"),
    ({"study.json": b"[1, 2]"}, "study.json is damaged (no spec_hash)"),
    ({"study.json": b"{\"spec_hash\": 5}"}, "study.json is damaged (no spec_hash)"),
    ({"study.json": b"\xff\xfe\x00garbage"}, "study.json is damaged (not JSON"),
    ({"study.json": None}, "study.json is damaged (not a regular file"),
    ({"results.csv": b"\x89PNG\r\n\x1a\n\xff"}, "results.csv is damaged (not UTF-8"),
    ({"results.csv": b"case,x,y\n1,2,3\n"}, "results.csv has other columns"),
    ({"results.csv": b"\x00\x00\x00\n"}, "results.csv is damaged (NUL bytes)"),
])
def test_resume_on_a_damaged_folder_is_one_line(finished, tmp_path, damage, needle):
    from hubbeam_ctrl.core.errors import ParameterError
    from hubbeam_ctrl.study.sweep import sweep
    spec, out, _ = _copy(finished, tmp_path)
    for name, data in damage.items():
        (out / name).unlink()
        if data is None:
            (out / name).mkdir()
        else:
            (out / name).write_bytes(data)
    import re
    with pytest.raises(ParameterError, match=re.escape(needle)) as err:
        sweep(spec, workers=1, progress=False, out_dir=out, resume=True)
    assert "\n" not in str(err.value)


def test_a_second_sweep_on_the_same_folder_is_refused(finished, tmp_path):
    import fcntl

    from hubbeam_ctrl.core.errors import ParameterError
    from hubbeam_ctrl.study.sweep import sweep
    spec, out, _ = _copy(finished, tmp_path)
    before = (out / "results.csv").read_bytes()
    with open(out / ".hubbeam-sweep.lock", "a") as held:          # what a running sweep holds
        fcntl.flock(held, fcntl.LOCK_EX)
        with pytest.raises(ParameterError, match="another sweep is running"):
            sweep(spec, workers=1, progress=False, out_dir=out, resume=True)
    assert (out / "results.csv").read_bytes() == before
    sweep(spec, workers=1, progress=False, out_dir=out, resume=True)    # free again
    assert (out / "results.csv").read_bytes() == before


def test_disk_full_exits_1_in_one_line_and_leaves_no_empty_folder(tmp_path, capsys, monkeypatch):
    import errno
    spec_file = tmp_path / "s.toml"
    spec_file.write_text(GOOD_SPEC)

    def full(*_a, **_k):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    monkeypatch.setattr(os, "fsync", full)                        # the first append of results.csv
    err = _one_line(capsys, main(["sweep", str(spec_file), "--out", str(tmp_path / "o"), "--workers", "1"]),
                    expected_status=1)
    assert "No space left on device" in err and "results.csv" in err
    assert not (tmp_path / "o").exists()


def test_disk_full_on_an_atomic_write_is_not_bad_input(tmp_path, monkeypatch):
    import errno

    from hubbeam_ctrl.core.errors import ParameterError, ResourceError
    from hubbeam_ctrl.core.fileio import atomic_write_text

    def full(*_a, **_k):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    monkeypatch.setattr(os, "replace", full)
    with pytest.raises(ResourceError, match="No space left") as err:
        atomic_write_text(tmp_path / "x.txt", "hello")
    assert not isinstance(err.value, ParameterError) and list(tmp_path.iterdir()) == []


# -- sweeps and tune budgeted like compare -----------------------------------------------------------
_BASE = {"study": {"controllers": ["openloop", "lqr"], "t_f": 1.0, "t_end": 6.5},
         "params": {"n_axial": 2, "n_transverse": 2}}


def _spec_with(**tables):
    import copy
    data = copy.deepcopy(_BASE)
    for table, content in tables.items():
        data.setdefault(table, {}).update(content)
    return data


@pytest.mark.parametrize("tables, needle", [
    ({"grid": {"m_t": [i * 1e-3 for i in range(1000)], "E": [6e10 + i * 1e7 for i in range(1000)]}},
     r"^grid\.m_t \(1000\) x grid\.E \(1000\) give 1e\+06 cases, more than the 100000"),
    ({"random": {"n": 10**12, "m_t": {"dist": "uniform", "low": 0.0, "high": 0.2}}}, r"^random\.n must be an integer in 1\.\.100000"),  # noqa: E501
    ({"study": {"t_end": 1e9}}, r"^study\.t_end = 1e\+09 s at study\.dt = 0\.01 s .* needs about .* of memory.*lower study\.t_end"),  # noqa: E501
    ({"study": {"plant_modes": 0}}, r"^study\.plant_modes must be an integer in 1\.\.20, got 0"),
    ({"study": {"design_modes": 21}}, r"^study\.design_modes must be an integer in 1\.\.20, got 21"),
    ({"study": {"horizon": 100000}}, r"^study\.horizon: no controller of study\.controllers \(openloop, lqr\) uses it"),
    ({"study": {"controllers": ["mpc"], "horizon": 3000}}, r"^study\.t_end = 6\.5 s .* with study\.horizon = 3000 needs"),  # noqa: E501
    ({"study": {"controllers": ["openloop"], "shaping": "zv"}}, r"^study\.shaping: no controller .* tracks a reference"),  # noqa: E501
    ({"random": {"n": 50, "m_t": {"dist": "normal", "mean": 0.05, "std": 0.1}}},
     r"^random\.m_t: the sample -?[0-9.e-]+ is outside its range .*truncate the distribution"),
])
def test_sweep_specs_are_budgeted_up_front(tables, needle):
    import time

    from hubbeam_ctrl.core.errors import ParameterError
    from hubbeam_ctrl.study.spec_files import load_spec
    t0 = time.perf_counter()
    with pytest.raises(ParameterError, match=needle) as err:
        load_spec(_spec_with(**tables))
    assert "\n" not in str(err.value) and len(str(err.value)) < 400
    assert time.perf_counter() - t0 < 10


def test_a_truncated_distribution_inside_the_range_is_accepted():
    from hubbeam_ctrl.study.spec_files import load_spec
    spec = load_spec(_spec_with(random={"n": 50, "m_t": {"dist": "normal", "mean": 0.05, "std": 0.1,
                                                         "low": 0.0, "high": 0.3}}))
    assert all(0.0 <= c["m_t"] <= 0.3 for c in spec.cases())


@pytest.mark.parametrize("options, needle", [
    ({"popsize": 10**9}, r"^tune\.popsize must be an integer in 1\.\.1000"),
    ({"maxiter": 10**6}, r"^tune\.maxiter must be an integer in 1\.\.10000"),
    ({"maxiter": 10000, "popsize": 1000}, r"^tune\.maxiter \(10000\) \+ 1 generations x tune\.popsize \(1000\)"),
])
def test_tune_is_budgeted_up_front(options, needle):
    from hubbeam_ctrl.core.errors import ParameterError
    from hubbeam_ctrl.study.tune import TuneOptions, tune
    with pytest.raises(ParameterError, match=needle):
        tune(_spec_with(), "lqr", options=TuneOptions.from_dict(options), workers=1)


def test_cli_popsize_names_the_option(tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text(GOOD_SPEC)
    err = _one_line(capsys, main(["tune", str(spec), "--controller", "lqr", "--out", str(tmp_path / "t"),
                                  "--popsize", "1e9"]))
    assert "--popsize" in err and "1..1000" in err


# -- CLI numbers: one helper, the option with its dashes --------------------------------------------
@pytest.mark.parametrize("argv, needle", [
    (["design", "--controller", "lqr", "--out", "c.mat", "--tau-max=--"], "--tau-max must be given a value, got '--'"),
    (["modes", "--spin="], "--spin must be given a value"),
    (["compare", "--out", "o", "--controllers", "mpc", "--horizon=1e308"], "--horizon must be an integer in 1..5000"),
    (["compare", "--out", "o", "--horizon=1e309"], "--horizon must be an integer"),
    (["design", "--controller", "lqr", "--out", "c.mat", "--tau-max=1e308"], "--tau-max must be in (0, 200]"),
    (["design", "--controller", "lqr", "--out", "c.mat", "--payload-range", "0,1e308"],
     "--payload-range m_max must be in [0, 1e+06]"),
    (["design", "--controller", "lqr", "--out", "c.mat", "--design-modes", "0"], "--design-modes must be an integer"),
    (["design", "--controller", "lqr", "--out", "c.mat", "--slew-angle", "0"], "--slew-angle must be"),
    (["design", "--controller", "lqr", "--out", "c.mat", "--wf", "2"], "--wf does not apply to --scenario slew"),
])
def test_cli_numbers_are_one_line_naming_the_option(tmp_path, capsys, monkeypatch, argv, needle):
    monkeypatch.chdir(tmp_path)
    err = _one_line(capsys, main(argv))
    assert needle in err, err
    assert not any(f" {bare}" in err.replace("--" + bare, "") for bare in
                   ("tau-max", "payload-range", "design-modes", "slew-angle")), err   # never without dashes
    assert list(tmp_path.iterdir()) == []


def test_messages_with_a_bare_option_name_get_their_dashes():
    from hubbeam_ctrl.cli.args import rename_options
    assert rename_options("payload-range must be two numbers", {"--payload-range"}) == \
        "--payload-range must be two numbers"
    assert rename_options("design_modes must be an integer", {"--design-modes"}) == "--design-modes must be an integer"
    assert rename_options("tune.popsize must be", {"--popsize"}) == "--popsize (tune.popsize) must be"
    assert rename_options("payload-range must be", {"--out"}) == "payload-range must be"     # not this command's


# -- the API: one ParameterError line -------------------------------------------------------------------
def _api_cases():
    import numpy as np

    from controllers.mpc import MPCSettings
    from controllers.reference import slew_reference
    from hubbeam_ctrl.linear.statespace import linearize
    from hubbeam_ctrl.linear.transforms import reduce
    from hubbeam_ctrl.plant.modal import campbell
    from hubbeam_ctrl.plant.params import Params, load_params, save_params
    lm = linearize("sfoam", spin=0.0, params=Params(n_axial=1, n_transverse=2))
    return {
        "MPCSettings(horizon=10**9)": (lambda: MPCSettings(horizon=10**9), r"^horizon must be an integer in 1\.\.5000"),
        "reduce(model, nan)": (lambda: reduce(lm, float("nan")), r"^n_modes must be an integer in 1\.\.2, got nan"),
        "reduce(model, inf)": (lambda: reduce(lm, np.inf), r"^n_modes must be an integer"),
        "Params(foo=1)": (lambda: Params(foo=1), r"^Params has no field 'foo'; fields: L, "),
        "Params().replace(foo=1)": (lambda: Params().replace(foo=1), r"^Params has no field 'foo'"),
        "load_params(3)": (lambda: load_params(3), r"^params file must be named by a path, got 3"),
        "save_params(dict)": (lambda: save_params({"m_t": 1.0}, "p.toml"), r"^params must be a Params"),
        "slew_reference(nan)": (lambda: slew_reference(float("nan"), 10.0, 250.0, 200.0, 0.01, 30.0),
                                r"^angle must be a finite number \[rad\], got nan"),
        "campbell(spins=[])": (lambda: campbell("foam", spins=[]), r"^spins must hold at least one value"),
        "campbell(spins=[nan])": (lambda: campbell("foam", spins=[0.0, np.nan]), r"^spins must hold finite numbers"),
    }


def test_api_bad_arguments_are_one_parameter_error(tmp_path, monkeypatch):
    from hubbeam_ctrl.core.errors import ParameterError
    monkeypatch.chdir(tmp_path)
    for name, (call, needle) in _api_cases().items():
        with pytest.raises(ParameterError, match=needle) as err:
            call()
        assert "\n" not in str(err.value), name
    assert list(tmp_path.iterdir()) == []


# -- docs/ranges.md states the code's t_end rule ---------------------------------------------------------
def test_ranges_doc_states_the_scaled_t_end_rule():
    from pathlib import Path

    from hubbeam_ctrl.core.errors import ParameterError
    from hubbeam_ctrl.study.scenarios import make_scenario
    doc = (Path(__file__).resolve().parents[1] / "docs" / "ranges.md").read_text()
    assert "t_end > tf (1 + residual_delay)" in doc and "tf + 5" not in doc
    for t_f in (1.0, 10.0):                 # the bound scales with tf: 1.5 tf at the default delay 0.5
        make_scenario("slew", t_f=t_f, t_end=1.5 * t_f * 1.001, dt=0.01)
        with pytest.raises(ParameterError, match="t_end must exceed"):
            make_scenario("slew", t_f=t_f, t_end=1.5 * t_f * 0.999, dt=0.01)


def test_spec_parameter_errors_name_the_spec_key():
    from hubbeam_ctrl.core.errors import ParameterError
    from hubbeam_ctrl.study.spec_files import load_spec
    with pytest.raises(ParameterError, match=r"^params\.m_t must be in \[0, 1e\+06\] \[kg\], got -1"):
        load_spec({"params": {"m_t": -1.0}})
    with pytest.raises(ParameterError, match=r"^params: unknown parameter\(s\) foo"):
        load_spec({"params": {"foo": 1.0}})


def test_a_refused_second_sweep_leaves_the_first_ones_new_folder_alone(tmp_path):
    """Both see no folder, the first takes the lock: the refused one must not remove it."""
    import fcntl

    from hubbeam_ctrl.core.errors import ParameterError
    from hubbeam_ctrl.study.spec_files import load_spec
    from hubbeam_ctrl.study.sweep import _StudyFolder
    spec = load_spec({"study": {"controllers": ["openloop"], "t_f": 1.0, "t_end": 6.5},
                      "params": {"n_axial": 2, "n_transverse": 2}})
    out = tmp_path / "new"
    second = _StudyFolder(out, spec, resume=True)             # looked before the first created it
    assert second.created
    out.mkdir()
    with open(out / ".hubbeam-sweep.lock", "a") as first:
        fcntl.flock(first, fcntl.LOCK_EX)
        with pytest.raises(ParameterError, match="another sweep is running"):
            with second:
                pass
        assert out.is_dir()                                       # the first sweep's folder survives
