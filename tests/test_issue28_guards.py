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

    from hubbeam_ctrl.core import fileio
    from hubbeam_ctrl.core.errors import ParameterError
    from hubbeam_ctrl.sim.results import load_result
    bomb = tmp_path / "bomb.npz"
    with np.load(saved / "result.npz") as data:
        content = {k: data[k] for k in data.files}
    content["extra"] = np.zeros(4_000_000)                       # 32 MB unpacked, ~30 kB on disk
    np.savez_compressed(bomb, **content)
    assert bomb.stat().st_size < 200_000
    monkeypatch.setattr(fileio, "MAX_NPZ_BYTES", 16_000_000)
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
