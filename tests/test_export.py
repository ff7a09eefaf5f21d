"""Export and import of linear models, and the ``hubbeam linearize`` CLI (issue 3, items 5-6)."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
import scipy.io

from hubbeam_ctrl import Params
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.linear.export import FORMATS, load_model, save_model
from hubbeam_ctrl.linear.statespace import linearize
from hubbeam_ctrl.linear.transforms import discretize, reduce

FMT = [f.lstrip(".") for f in FORMATS]


@pytest.fixture(scope="module")
def models():
    full = linearize("foam", 1.5, Params(n_axial=3, n_transverse=4, damping_ratio=0.02),
                     outputs="theta,tip_deflection,root_moment,tip_rate")
    return {
        "sfoam": linearize(),                                     # l = None (tip at L)
        "sfoam_l": linearize("sfoam", -0.7, Params(l=5.5, m_t=0.3), outputs="theta_dot"),
        "foam": full,
        "discrete": discretize(full, 0.002),
        "modal": reduce(full, 2),
        "balanced": reduce(full, 2, method="balanced"),
        "cfoam": linearize("cfoam", 2.0, Params(n_axial=2, n_transverse=2)),
    }


def _bits(a):
    return np.ascontiguousarray(a).tobytes()


@pytest.mark.parametrize("fmt", FMT)
def test_round_trip_bit_for_bit(models, fmt, tmp_path):
    for key, lm in models.items():
        path = save_model(lm, tmp_path / f"{key}.{fmt}")
        back = load_model(path)
        assert back == lm, key
        for m in "ABCD":
            a, b = getattr(lm, m), getattr(back, m)
            assert a.shape == b.shape and a.dtype == b.dtype == np.float64
            assert _bits(a) == _bits(b), (key, m)
        assert back.params == lm.params and back.params.l == lm.params.l
        assert back.spin == lm.spin and back.dt == lm.dt and back.sys.dt == lm.sys.dt
        assert back.state_names == lm.state_names and back.output_names == lm.output_names
        assert back.name == lm.name and back.reduction == lm.reduction and back.model == lm.model
        # and a second save gives the same file content
        again = save_model(back, tmp_path / f"{key}_again.{fmt}")
        if fmt != "mat":          # .mat headers carry a time stamp
            assert again.read_bytes() == path.read_bytes()


def test_negative_zero_and_extremes_survive(models, tmp_path):
    lm = models["sfoam"]
    A = lm.A.copy()
    A[0, 0] = -0.0
    A[1, 0] = 5e-324                         # subnormal
    A[2, 0] = 1.7976931348623157e308
    A[3, 0] = 0.1 + 0.2
    odd = type(lm)(sys=__import__("control").ss(A, lm.B, lm.C, lm.D, 0, states=lm.state_names,
                                                   inputs=["tau"], outputs=lm.output_names,
                                                   name=lm.name),
                   model=lm.model, spin=lm.spin, params=lm.params)
    for fmt in FMT:
        back = load_model(save_model(odd, tmp_path / f"odd.{fmt}"))
        assert _bits(back.A) == _bits(A)
        assert np.signbit(back.A[0, 0])


def test_mat_follows_matlab_conventions(models, tmp_path):
    lm = models["discrete"]
    path = save_model(lm, tmp_path / "plant.mat")
    S = scipy.io.loadmat(path)
    for m in "ABCD":
        assert S[m].dtype == np.float64 and S[m].shape == getattr(lm, m).shape
    n = lm.n_states
    assert S["state_names"].shape == (n, 1) and S["state_names"].dtype == object
    assert [str(c[0][0]) for c in S["state_names"]] == lm.state_names
    assert [str(c[0][0]) for c in S["input_names"]] == ["tau"]
    assert [str(c[0][0]) for c in S["output_names"]] == lm.output_names
    assert [str(c[0][0]) for c in S["output_units"]] == ["rad", "m", "N m", "m/s"]
    assert float(S["dt"][0, 0]) == 0.002 and float(S["spin_rad_s"][0, 0]) == 1.5
    assert str(S["model"][0]) == "foam"
    params, units = S["params"][0, 0], S["param_units"][0, 0]
    assert set(params.dtype.names) == set(Params.units())
    assert float(params["J_h"][0, 0]) == 200.0 and float(params["l"][0, 0]) == 8.0
    assert float(params["damping_ratio"][0, 0]) == 0.02
    assert str(units["J_h"][0]) == "kg m^2" and str(units["E"][0]) == "Pa"
    # the continuous model: Ts = 0, MATLAB's convention
    S = scipy.io.loadmat(save_model(models["foam"], tmp_path / "c.mat"))
    assert float(S["dt"][0, 0]) == 0.0


def test_npz_and_json_are_plain(models, tmp_path):
    lm = models["foam"]
    with np.load(save_model(lm, tmp_path / "m.npz"), allow_pickle=False) as data:
        assert set(data.files) == {"A", "B", "C", "D", "metadata"}
        meta = json.loads(str(data["metadata"]))
    assert meta["spin_rad_s"] == 1.5 and meta["params"]["n_axial"] == 3
    assert meta["param_units"]["m_t"] == "kg" and meta["state_units"][0] == "rad"
    doc = json.loads(save_model(lm, tmp_path / "m.json").read_text())
    assert doc["format"] == "hubbeam-linear-model" and doc["version"] == 1
    assert np.array(doc["A"]).shape == lm.A.shape and doc["input_names"] == ["tau"]
    assert doc["dt"] == 0.0 and doc["model"] == "foam"


def _listing(folder):
    return sorted(os.listdir(folder))


def test_bad_extension_and_folder_leave_nothing(models, tmp_path):
    lm = models["sfoam"]
    before = _listing(tmp_path)
    for bad in ("m.txt", "m", "m.MAT.bak"):
        with pytest.raises(ParameterError, match="extension") as exc:
            save_model(lm, tmp_path / bad)
        assert "\n" not in str(exc.value)
    with pytest.raises(ParameterError, match="does not exist") as exc:
        save_model(lm, tmp_path / "missing" / "m.mat")
    assert "\n" not in str(exc.value)
    (tmp_path / "afile").write_text("x")
    with pytest.raises(ParameterError):
        save_model(lm, tmp_path / "afile" / "m.json")       # parent is a file
    (tmp_path / "d.mat").mkdir()
    with pytest.raises(ParameterError, match="folder"):
        save_model(lm, tmp_path / "d.mat")                  # target is a folder
    assert _listing(tmp_path) == sorted(before + ["afile", "d.mat"])


@pytest.mark.parametrize("fmt", FMT)
def test_failed_write_is_atomic(models, fmt, tmp_path, monkeypatch):
    lm = models["sfoam"]
    target = tmp_path / f"m.{fmt}"
    target.write_bytes(b"old content")

    def boom(*args, **kwargs):
        fh = args[0]
        if hasattr(fh, "write"):
            fh.write(b"partial" if "b" in getattr(fh, "mode", "b") else "partial")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(scipy.io, "savemat", boom)
    monkeypatch.setattr(np, "savez", boom)
    monkeypatch.setattr("pathlib.Path.write_text", lambda self, *a, **k: boom(open(self, "w")))
    from hubbeam_ctrl.core.errors import ResourceError
    with pytest.raises(ResourceError, match="No space left") as exc:      # disk full is not bad input
        save_model(lm, target)
    assert "\n" not in str(exc.value) and not isinstance(exc.value, ParameterError)
    assert target.read_bytes() == b"old content"          # old file untouched
    assert _listing(tmp_path) == [target.name]            # no temporary left behind


def test_load_errors(tmp_path):
    with pytest.raises(ParameterError, match="does not exist"):
        load_model(tmp_path / "nope.mat")
    with pytest.raises(ParameterError, match="extension"):
        load_model(tmp_path / "x.csv")
    for name, content in (("g.mat", b"garbage"), ("g.npz", b"garbage"), ("g.json", b"{}"),
                          ("h.json", b"not json")):
        (tmp_path / name).write_bytes(content)
        with pytest.raises(ParameterError) as exc:
            load_model(tmp_path / name)
        assert "\n" not in str(exc.value)


# -- CLI ---------------------------------------------------------------------------------
def _parse(argv):
    from hubbeam_ctrl.cli.main import build_parser
    return build_parser().parse_args(argv)


def test_cli_json_and_file(tmp_path, capsys):
    from hubbeam_ctrl.cli import linearize as cli_linearize
    out = tmp_path / "plant.npz"
    args = _parse(["linearize", "--model", "foam", "--spin", "1", "--n-modes", "3",
                   "--outputs", "theta,root_moment", "--damping", "0.01", "--dt", "0.001",
                   "--out", str(out), "--json"])
    assert cli_linearize.COMMAND.func(args) == 0
    doc = json.loads(capsys.readouterr().out)
    assert set(doc) == {"model", "spin_rad_s", "n_states", "poles_hz", "unstable", "out"} and doc["unstable"] is False
    assert doc["model"] == "foam" and doc["spin_rad_s"] == 1.0 and doc["n_states"] == 14
    assert doc["out"] == str(out) and doc["poles_hz"] == sorted(doc["poles_hz"])
    assert doc["poles_hz"][0] == pytest.approx(0.4692, abs=1e-3)
    lm = load_model(out)
    assert lm.dt == 0.001 and lm.output_names == ["theta", "root_moment"]
    assert lm.params.damping_ratio == 0.01 and lm.params.n_transverse == 3
    assert doc["poles_hz"] == [float(f) for f in lm.poles_hz()]


def test_cli_defaults_and_main(tmp_path, capsys):
    from hubbeam_ctrl.cli.main import main
    out = tmp_path / "p.mat"
    assert main(["linearize", "--out", str(out), "--tip-mass", "0", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["model"] == "sfoam" and doc["spin_rad_s"] == 0.0 and doc["n_states"] == 12
    assert doc["poles_hz"][0] == pytest.approx(0.50649, abs=1e-5)   # free hub, no tip mass
    lm = load_model(out)
    assert lm.params.m_t == 0.0 and lm.output_names == ["theta", "tip_deflection"]
    assert main(["linearize", "--out", str(tmp_path / "q.json")]) == 0
    assert "saved to" in capsys.readouterr().out


@pytest.mark.parametrize("argv, word", [
    (["--out", "X/m.txt"], "out must end in"),
    (["--out", "X/missing/m.mat"], "does not exist"),
    (["--out", "X/m.mat", "--outputs", "theta,bogus"], "outputs"),
    (["--out", "X/m.mat", "--damping", "1.2"], "damping_ratio"),
    (["--out", "X/m.mat", "--dt", "-1"], "dt"),
    (["--out", "X/m.mat", "--spin", "inf"], "spin"),
    (["--out", "X/m.mat", "--model", "xyz"], "model"),
    (["--out", "X/m.mat", "--n-modes", "0"], "n_axial"),
])
def test_cli_errors_one_line_no_file(argv, word, tmp_path, capsys):
    from hubbeam_ctrl.cli.main import main
    argv = ["linearize"] + [a.replace("X", str(tmp_path)) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert word in err and err.count("\n") == 1 and "Traceback" not in err
    assert _listing(tmp_path) == []
