"""The one result type: construction checks, summary, CSV and NPZ files, load validation."""

import dataclasses
import json
import os
import zipfile

import numpy as np
import pytest

from hubbeam_ctrl import Params, TorquePulse, save_model, simulate
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.linear.statespace import linearize
from hubbeam_ctrl.sim import simulate_closed_loop, simulate_fixed_step
from hubbeam_ctrl.sim.results import (
    CSV_COLUMNS,
    ClosedLoopResult,
    Result,
    SimulationResult,
    load_result,
)
from hubbeam_ctrl.study.metrics import closed_loop_metrics

SMALL = Params(n_axial=1, n_transverse=2)


class _Constant:
    """A controller holding a constant torque, with statistics to store."""

    name = "const"
    measurement = "state"

    def __init__(self, tau):
        self.tau, self.calls = tau, 0

    def reset(self):
        self.calls = 0

    def __call__(self, t, y):
        self.calls += 1
        return self.tau

    def stats(self):
        return {"calls": np.int64(self.calls), "gains": (1.0, 2.5)}


@pytest.fixture(scope="module")
def runs():
    """One result of each kind, on a small FOAM."""
    pulse = TorquePulse(50.0, 1.0)
    ref = (lambda t: 0.01 * t, lambda t: 0.01 + 0 * t)
    return {
        "open_loop": simulate("foam", pulse, 2.0, params=SMALL),
        "fixed_step": simulate_fixed_step("foam", pulse, 2.0, params=SMALL),
        "closed_loop": simulate_closed_loop("foam", _Constant(20.0), 2.0, params=SMALL, reference=ref),
    }


def _hand_made(**changes):
    """A result with known numbers: 5 samples 5 s apart, 2 coordinates."""
    t = np.arange(5) * 5.0
    q = np.column_stack([np.array([0.0, 0.1, 0.3, 0.6, 1.0]), np.zeros(5)])
    v = np.column_stack([np.array([0.0, 0.02, 0.05, 0.07, 0.08]), np.zeros(5)])
    args = dict(kind="fixed_step", model="foam", t=t, q=q, v=v,
                v_tip=np.array([0.0, 0.5, -2.0, 1.0, 0.1]), u_tip=np.array([0.0, -1e-3, -4e-3, 0, 0]),
                tau=np.full(5, 3.0), params=Params())
    args.update(changes)
    return Result(**args)


# -- the type ----------------------------------------------------------------------------
def test_one_type_for_every_simulator(runs):
    assert SimulationResult is Result and ClosedLoopResult is Result
    assert {k: type(r) for k, r in runs.items()} == dict.fromkeys(runs, Result)
    assert {k: r.kind for k, r in runs.items()} == {k: k for k in runs}
    ol, fs, cl = runs["open_loop"], runs["fixed_step"], runs["closed_loop"]
    assert ol.energy is not None and ol.root_moment is None and ol.controller is None
    assert cl.root_moment is not None and cl.energy is None and cl.controller == "const"
    assert cl.plant == cl.model == "foam" and cl.diverged is cl.stopped is False
    # the fixed-step run stores the applied torque: 50 N m pulse of 1 s, zero after
    np.testing.assert_allclose(fs.tau, TorquePulse(50.0, 1.0)(fs.t), atol=1e-9)
    assert fs.stats["fallbacks"] == 0 and fs.stats["ms_per_step"] > 0
    assert cl.stats["plant_fallbacks"] == 0
    # controller statistics are stored as they read back from JSON
    assert cl.controller_stats == {"calls": 201, "gains": [1.0, 2.5]}
    assert type(cl.controller_stats["calls"]) is int


def test_summary_numbers():
    res = _hand_made()
    s = res.summary(residual_window_s=6.0)               # the window holds t = 15 and 20 s
    assert s == {"kind": "fixed_step", "model": "foam", "peak_tip_m": 2.0, "residual_tip_m": 1.0,
                 "peak_axial_m": 4e-3, "final_theta_rad": 1.0, "final_theta_dot_rad_s": 0.08,
                 "diverged": False, "message": "completed", "wall_s": 0.0}
    assert res.summary(residual_window_s=4.0)["residual_tip_m"] == 0.1
    assert _hand_made(controller="pd", kind="fixed_step").summary()["controller"] == "pd"
    with pytest.raises(ParameterError, match="residual_window_s"):
        res.summary(residual_window_s=0.0)


@pytest.mark.parametrize("changes, needle", [
    ({"kind": "open"}, "kind must be one of open_loop, fixed_step, closed_loop"),
    ({"kind": "open_loop"}, "needs a, q_theta, energy, angular_momentum"),
    ({"kind": "closed_loop"}, "needs root_moment, step_time_s"),
    ({"hub": "loose"}, "hub must be one of free, prescribed"),
    ({"t": np.array([0.0, 1, 2, np.nan, 4])}, "t must hold finite times"),
    ({"t": np.zeros(0)}, r"t must be a non-empty 1-D array of times \[s\], got shape \(0,\)"),
    ({"q": np.zeros(5)}, r"q must have shape \(5, n_q\)"),
    ({"v": np.zeros((5, 3))}, r"v must have shape \(5, 2\)"),
    ({"v_tip": np.zeros(4)}, r"v_tip must have shape \(5,\)"),
    ({"tau": np.arange(5)}, "tau must hold real floating-point numbers, got dtype int64"),
    ({"u_tip": np.zeros(5, complex)}, "u_tip must hold real floating-point"),
    ({"params": {"L": 8.0}}, "params must be a Params"),
    ({"stopped": "no"}, "stopped must be True or False"),
    ({"wall_s": -1.0}, "wall_s must be a finite number >= 0"),
    ({"settings": [1, 2]}, "settings must be a dict"),
])
def test_construction_is_checked(changes, needle):
    with pytest.raises(ParameterError, match=needle) as exc:
        _hand_made(**changes)
    assert "\n" not in str(exc.value)


def test_equality_is_bitwise():
    a, b = _hand_made(), _hand_made()
    assert a == b
    b.v_tip[2] = np.nextafter(b.v_tip[2], 0.0)           # one bit of one sample
    assert a != b
    assert a != _hand_made(message="other") and a != _hand_made(settings={"dt": 0.01})
    assert a != _hand_made(theta_ref=np.zeros(5))         # an extra series
    assert a.__eq__("a string") is NotImplemented


# -- files ---------------------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["open_loop", "fixed_step", "closed_loop"])
def test_npz_round_trip_is_bit_exact(runs, kind, tmp_path):
    res = runs[kind]
    back = load_result(res.save(tmp_path / "r.npz"))
    assert back == res
    for name, arr in res.arrays().items():
        got = getattr(back, name)
        assert got.dtype == arr.dtype and got.shape == arr.shape
        assert got.tobytes() == np.ascontiguousarray(arr).tobytes(), name
    assert back.params == res.params == SMALL
    assert (back.settings, back.stats, back.controller_stats) == (res.settings, res.stats, res.controller_stats)
    assert (back.kind, back.model, back.hub, back.controller, back.stopped, back.message, back.wall_s) == \
        (res.kind, res.model, res.hub, res.controller, res.stopped, res.message, res.wall_s)


def test_closed_loop_csv_columns_units_and_values(runs, tmp_path):
    tau = runs["closed_loop"].tau.copy()
    tau[-1] = np.nan                                       # as when a run stops early
    res = dataclasses.replace(runs["closed_loop"], tau=tau)
    path = res.save(tmp_path / "cl.csv")
    header = path.read_text().splitlines()[0]
    assert header == ("t [s],theta [rad],theta_dot [rad/s],v_tip [m],u_tip [m],tau [N m],"
                      "root_moment [N m],theta_ref [rad],theta_dot_ref [rad/s],step_time_s [s]")
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    assert data.shape == (201, 10)
    names = [h.split(" [")[0] for h in header.split(",")]
    assert all(CSV_COLUMNS[n] == h.split(" [")[1][:-1] for n, h in zip(names, header.split(",")))
    for k, name in enumerate(names):                       # 17 digits read back exactly
        np.testing.assert_array_equal(data[:, k], getattr(res, name), err_msg=name)
    assert np.isnan(data[-1, names.index("tau")])
    np.testing.assert_allclose(data[:, names.index("theta_ref")], 0.01 * res.t, rtol=0, atol=1e-15)


def test_save_errors_leave_nothing(runs, tmp_path):
    res = runs["fixed_step"]
    with pytest.raises(ParameterError, match="unknown extension '.mat'"):
        res.save(tmp_path / "r.mat")
    with pytest.raises(ParameterError, match="does not exist"):
        res.save(tmp_path / "missing" / "r.npz")
    (tmp_path / "d.npz").mkdir()
    with pytest.raises(ParameterError, match="is a folder"):
        res.save(tmp_path / "d.npz")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.npz"]


def _rewrite(src, dst, drop=(), arrays=None, meta=None):
    """Copy an NPZ result with entries dropped or replaced (for the load checks)."""
    with np.load(src) as data:
        content = {k: data[k] for k in data.files if k not in drop}
    if meta is not None:
        m = json.loads(str(content["metadata"]))
        m.update(meta)
        for key in [k for k, v in meta.items() if v is None]:
            del m[key]
        content["metadata"] = np.array(json.dumps(m))
    content.update(arrays or {})
    np.savez(dst, **content)
    return dst


def test_load_result_refuses_bad_files_in_one_line(runs, tmp_path):
    good = runs["closed_loop"].save(tmp_path / "good.npz")
    (tmp_path / "garbage.npz").write_bytes(b"\x00garbage")
    (tmp_path / "truncated.npz").write_bytes(good.read_bytes()[:200])
    (tmp_path / "folder.npz").mkdir()
    with zipfile.ZipFile(tmp_path / "nometa.npz", "w") as z:
        z.writestr("t.npy", b"")
    np.savez(tmp_path / "pickled.npz", metadata=np.array("{}"), t=np.array([object()], dtype=object))
    np.save(tmp_path / "plain.npy", np.zeros(3))
    os.replace(tmp_path / "plain.npy", tmp_path / "plain.npz")
    lm = linearize("sfoam", spin=0.0, params=Params(n_axial=1, n_transverse=1))
    save_model(lm, tmp_path / "model.npz")
    cases = {
        "missing.npz": "does not exist",
        "folder.npz": "is not a regular file",
        "garbage.npz": "not an NPZ archive",
        "truncated.npz": "not a hubbeam result file",
        "nometa.npz": "no metadata entry",
        "pickled.npz": "not a hubbeam result file",
        "plain.npz": "not an NPZ archive",
        "model.npz": "format tag 'hubbeam-linear-model'",
        _rewrite(good, tmp_path / "a.npz", drop=["tau"]).name: "needs tau",
        _rewrite(good, tmp_path / "b.npz", arrays={"q": np.zeros((3, 2))}).name: r"q must have shape \(201, 2\)",
        _rewrite(good, tmp_path / "c.npz", arrays={"v_tip": np.zeros(201, complex)}).name: "v_tip must hold real",
        _rewrite(good, tmp_path / "d.npz", arrays={"t": np.full(201, np.inf)}).name: "t must hold finite times",
        _rewrite(good, tmp_path / "e.npz", arrays={"extra": np.zeros(3)}).name: "unexpected array.s. extra",
        _rewrite(good, tmp_path / "f.npz", meta={"kind": None}).name: "metadata lacks kind",
        _rewrite(good, tmp_path / "k.npz", meta={"kind": ["x"]}).name: r"kind must be one of .*got \['x'\]",
        _rewrite(good, tmp_path / "g.npz", meta={"version": 99}).name: "format version 99",
        _rewrite(good, tmp_path / "h.npz", meta={"params": {"L": -1.0}}).name: "L must be",
        _rewrite(good, tmp_path / "i.npz", meta={"params": [1, 2]}).name: "params must be a JSON object, got list",
        _rewrite(good, tmp_path / "j.npz", meta={"stopped": "yes"}).name: "stopped must be True or False",
    }
    if hasattr(os, "mkfifo"):
        os.mkfifo(tmp_path / "fifo.npz")
        cases["fifo.npz"] = "is not a regular file"
    for name, needle in cases.items():
        with pytest.raises(ParameterError, match=needle) as exc:
            load_result(tmp_path / name)
        msg = str(exc.value)
        assert "\n" not in msg and name in msg and msg.startswith("path: "), msg
    with pytest.raises(ParameterError, match=r"only \.npz results can be loaded.*\.csv holds only"):
        load_result(tmp_path / "r.csv")
    assert load_result(good) == runs["closed_loop"]        # the untouched file still loads


def test_metrics_need_a_closed_loop_result(runs):
    with pytest.raises(ParameterError, match="closed-loop run .kind 'closed_loop'., got kind 'open_loop'"):
        closed_loop_metrics(runs["open_loop"], 1.0)
    m = closed_loop_metrics(runs["closed_loop"], 0.5, residual_delay=1.0)
    assert m["peak_torque_nm"] == 20.0 and m["calls"] == 201 and "gains" not in m
