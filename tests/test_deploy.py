"""Controllers as C (hubbeam_ctrl.deploy): the compiled C command equals the Python one.

Reference: the Python controller itself, run on the same evaluation plant with the same
sensor noise; the C code is generated from it, compiled with the strict flags and loaded
with ctypes. Small models (one design mode at 20 Hz: a 5-mode evaluation plant) keep the
module within its time budget; the compile happens once per module.
"""

import json
import re

import numpy as np
import pytest

from controllers import (
    LQG,
    LQR,
    MPC,
    PD,
    DesignModel,
    DesignSchedule,
    LQGSettings,
    LQRSettings,
    MPCSettings,
    ScheduledLQG,
    ScheduledLQR,
    ShapedSettings,
    ZVDOpenLoop,
    slew_reference,
    spinup_reference,
)
from hubbeam_ctrl import Params
from hubbeam_ctrl.core.compiled import CompileError
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.deploy import (
    NO_COMPILER,
    CController,
    ObservedLQR,
    ObservedMPC,
    compile_c,
    compiler,
    sil,
    to_c,
)
from hubbeam_ctrl.sim import simulate_closed_loop
from hubbeam_ctrl.sim.closedloop import ClosedLoopSettings
from hubbeam_ctrl.study.compare_values import CompareSettings, RunChoice
from hubbeam_ctrl.study.metrics import closed_loop_metrics

needs_cc = pytest.mark.skipif(compiler() is None, reason=NO_COMPILER)

DT = 0.05
T_F, T_END = 8.0, 16.0
#: Single precision: largest |tau_c - tau_py| / tau_max in the closed loop. Measured 8e-6
#: (LQG, 12 states) here and 1.1e-4 (LQG, 22 states, 100 Hz, Table 1 beam); docs/deploy.md.
SINGLE_BOUND = 1e-3


@pytest.fixture(scope="module")
def setup():
    p = Params(n_axial=1, n_transverse=1)
    design = DesignModel.build(p, 0.0, DT)
    ref = slew_reference(0.5, T_F, p.total_inertia, 200.0, DT, T_END)
    ctrls = {"pd": PD(design, reference=ref),
             "lqr": LQR(design, LQRSettings(residual_control=True), reference=ref),
             "lqg": LQG(design, LQGSettings(residual_control=True), reference=ref),
             "mpc": MPC(design, MPCSettings(horizon=20, residual_control=True, tau_max=8.0), reference=ref)}
    return design, ref, ctrls


@pytest.fixture(scope="module")
def built(setup, tmp_path_factory):
    """Sources of every controller, compiled at -O2 (and LQG at -O0, LQG in single precision)."""
    if compiler() is None:
        pytest.skip(NO_COMPILER)
    _, _, ctrls = setup
    root = tmp_path_factory.mktemp("c")
    out = {}
    for kind, ctrl in ctrls.items():
        code = to_c(ctrl, root / kind)
        out[kind] = (code, compile_c(code, "-O2", root))
    code = out["lqg"][0]
    out["lqg-O0"] = (code, compile_c(code, "-O0", root))
    single = to_c(ctrls["lqg"], root / "lqg32", "single", name="lqg32")
    out["lqg-single"] = (single, compile_c(single, "-O2", root))
    return out


def _run(ctrl, ref):
    return simulate_closed_loop("foam", ctrl, T_END, settings=ClosedLoopSettings(dt=DT),
                                reference=(ref.theta_at, ref.theta_dot_at))


def _python(ctrl):
    """The Python controller the C code mirrors: LQR and MPC with their observer."""
    if isinstance(ctrl, LQR):
        return ObservedLQR(ctrl)
    return ObservedMPC(ctrl) if isinstance(ctrl, MPC) else ctrl


@pytest.fixture(scope="module")
def python_runs(setup):
    _, ref, ctrls = setup
    return {kind: _run(_python(c), ref) for kind, c in ctrls.items()}


@needs_cc
@pytest.mark.parametrize("kind", ["pd", "lqr", "lqg", "lqg-O0", "mpc"])
def test_c_command_equals_python_on_the_evaluation_plant(setup, built, python_runs, kind):
    _, ref, ctrls = setup
    base = kind.split("-")[0]
    ctrl = ctrls[base]
    code, lib = built[kind]
    py = python_runs[base]
    c = _run(CController(lib, code, ctrl), ref)
    assert c.settings["plant_modes"] == py.settings["plant_modes"] == 5   # the same evaluation plant
    assert len(c.tau) == len(py.tau) == round(T_END / DT) + 1
    err = np.max(np.abs(c.tau - py.tau)) / ctrl.tau_max
    assert err <= 1e-9, err
    assert np.max(np.abs(py.tau)) > 0.05 * ctrl.tau_max          # the loop did work
    v_py = closed_loop_metrics(py, T_F, tau_max=ctrl.tau_max)["verdict"]
    v_c = closed_loop_metrics(c, T_F, tau_max=ctrl.tau_max)["verdict"]
    assert v_c == v_py
    if base == "mpc":       # the torque bound was active: the generated QP solver's active set worked
        assert np.mean(np.abs(py.tau) >= ctrl.tau_max * (1 - 1e-12)) > 0


@needs_cc
def test_single_precision_stays_within_its_documented_bound(setup, built, python_runs):
    _, ref, ctrls = setup
    code, lib = built["lqg-single"]
    assert "typedef float lqg32_real;" in code.header
    c = _run(CController(lib, code, ctrls["lqg"]), ref)
    err = np.max(np.abs(c.tau - python_runs["lqg"].tau)) / ctrls["lqg"].tau_max
    assert 1e-12 < err <= SINGLE_BOUND, err     # really float (not 0), and within the bound


@needs_cc
@pytest.mark.parametrize("kind", ["pd", "lqr", "lqg", "mpc"])
def test_lockstep_beyond_the_reference_table_and_external_reference(setup, built, kind):
    """Random sensor values past the table's end: the extension of the reference matches."""
    _, ref, ctrls = setup
    ctrl = _python(ctrls[kind])
    code, lib = built[kind]
    cc = CController(lib, code, ctrl)
    ctrl.reset()
    cc.reset()
    rng = np.random.default_rng(3)
    n = len(ref.theta) + 40
    worst = 0.0
    for k in range(n):
        y = np.array([0.5 + 0.01 * rng.standard_normal(), 0.01 * rng.standard_normal(), rng.standard_normal()])
        worst = max(worst, abs(cc(k * DT, y) - ctrl(k * DT, y)))
    assert worst <= 1e-9 * ctrl.tau_max
    # an external reference equal to the table's row gives the table's command
    law = code.law
    cc.reset()
    if law.kind == "pd":
        r = [law.arrays["THETA"][0], law.arrays["THETA_DOT"][0], law.arrays["TFF"][0]]
    elif law.kind == "mpc":
        r = list(law.arrays["REFT"][0])
    else:
        r = [*law.arrays["XREF"][0], law.arrays["TFF"][0]]
    y = [0.01, 0.0, 1.0]
    with_ref = cc.step(y, r)
    cc.reset()
    assert cc.step(y) == with_ref


def test_shaped_open_loop_table_and_metadata(setup, tmp_path):
    design, ref, _ = setup
    ctrl = ZVDOpenLoop(design, ShapedSettings(angle=0.5, duration=T_F), ref)
    code = to_c(ctrl, tmp_path / "zvd")
    assert code.law.kind == "table" and np.array_equal(code.law.arrays["TORQUE"], ctrl.torques)
    assert sorted(p.name for p in (tmp_path / "zvd").iterdir()) == ["MANIFEST.json", "zvd.c", "zvd.h", "zvd.json"]
    meta = json.loads((tmp_path / "zvd" / "zvd.json").read_text())
    assert meta["measurements"] == [] and meta["command"]["unit"] == "N m"
    if compiler() is not None:
        cc = CController(compile_c(code, "-O0", tmp_path), code, ctrl)
        cc.reset()
        taus = [cc(k * DT, None) for k in range(len(ctrl.torques) + 5)]
        assert taus == [ctrl(k * DT, None) for k in range(len(ctrl.torques) + 5)]


def test_lqg_metadata_names_sensors_and_units(setup):
    code = to_c(setup[2]["lqg"])
    assert code.folder is None
    meta = code.metadata()
    assert [(m["name"], m["unit"]) for m in meta["measurements"]] == [
        ("theta", "rad"), ("theta_dot", "rad/s"), ("root_moment", "N m")]
    assert meta["data_bytes"] == 8 * sum(np.asarray(a).size for a in code.law.arrays.values())
    assert "%.17g" % code.law.arrays["K"][1] in code.source        # full precision
    assert "malloc" not in code.source and "stdio" not in code.source


def test_bad_input_one_line(setup, tmp_path):
    design, ref, ctrls = setup
    with pytest.raises(ParameterError, match=r"^controller: '.*' \(ScheduledLQR\) cannot be generated as C; kinds: pd"):
        to_c(ScheduledLQR(DesignSchedule.build(design.params, [0.0, 1.0], DT), reference=ref), tmp_path / "x")
    with pytest.raises(ParameterError, match=r"^controller: an MPC with a tip_bound cannot be generated"):
        to_c(MPC(design, MPCSettings(horizon=5, tip_bound=0.1), ref), tmp_path / "x")
    with pytest.raises(ParameterError, match="^precision must be one of double, single"):
        to_c(ctrls["pd"], tmp_path / "x", "half")
    with pytest.raises(ParameterError, match="^name must be a C identifier"):
        to_c(ctrls["pd"], tmp_path / "x", name="1pd")
    bad = PD(design, reference=ref)
    bad.kp = float("nan")
    with pytest.raises(ParameterError, match="^controller: kp has a non-finite entry"):
        to_c(bad, tmp_path / "x")
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "keep.txt").write_text("x")
    with pytest.raises(ParameterError, match="^out: folder .* exists and is not empty"):
        to_c(ctrls["pd"], tmp_path / "full")
    to_c(ctrls["pd"], tmp_path / "full", force=True)
    assert (tmp_path / "full" / "pd.c").is_file() and (tmp_path / "full" / "keep.txt").is_file()

    def failing(folder, name):
        raise CompileError("C compiler failed on pd.c -O2: boom")
    with pytest.raises(CompileError):
        to_c(ctrls["pd"], tmp_path / "failed", check=failing)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["full"]          # nothing half-written


def test_without_a_compiler_sources_are_written_and_sil_says_why(setup, tmp_path, monkeypatch):
    monkeypatch.setattr(sil, "compiler", lambda: None)
    code = to_c(setup[2]["lqg"], tmp_path / "lqg")
    assert code.source_path.is_file() and code.header_path.is_file()
    with pytest.raises(CompileError, match=f"^{re.escape(NO_COMPILER)}$"):
        compile_c(code)


def test_cli_codegen_writes_compiles_and_refuses_bad_input(tmp_path, capsys):
    from hubbeam_ctrl.cli.main import main
    out = tmp_path / "pd_c"
    args = ["codegen", "--controller", "pd", "--n-modes", "1", "--dt", "0.05", "--tf", "4", "--out", str(out)]
    assert main([*args, "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["compiled"] is (compiler() is not None)
    assert [m["name"] for m in summary["measurements"]] == ["theta", "theta_dot"]
    assert (out / "pd.c").is_file() and (out / "pd.h").is_file()
    rig = tmp_path / "rig.toml"
    rig.write_text("[sensors]\nstrain_gauges = [0.5]\n")        # no gauge at the root
    # issue 36 item 1: the C reads the rig's own sensors (this rig was refused before)
    assert main(["codegen", "--controller", "lqg", "--rig", str(rig), "--tf", "4", "--design-modes", "1",
                 "--out", str(tmp_path / "r"), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert [m["name"] for m in summary["measurements"]] == ["theta", "theta_dot", "moment_1"]
    assert "2: moment_1 [N m] (strain gauge at 0.5 m from the root)" in (tmp_path / "r" / "lqg.h").read_text()
    for bad, message in [(args, "--out: folder .* exists and is not empty"),
                         (["codegen", "--controller", "pid", "--out", str(tmp_path / "m")],
                          "--controller must be one of pd, lqr, lqg"),
                         (["codegen", "--controller", "zv", "--rig", "servo_link", "--out", str(tmp_path / "s")],
                          "--controller zv does not apply with --rig servo_link .*DC motor")]:
        assert main(bad) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and re.search(message, err), err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pd_c", "r", "rig.toml"]
    assert main([*args, "--force"]) == 0


def test_mat_export_states_sensors_and_units(setup, tmp_path):
    from scipy.io import loadmat

    from controllers.export import save_controller
    _, _, ctrls = setup
    for kind, expected in [("lqg", "theta [rad], theta_dot [rad/s], root_moment [N m]"),
                           ("pd", "theta [rad], theta_dot [rad/s]")]:
        m = loadmat(save_controller(ctrls[kind], tmp_path / f"{kind}.mat"))
        assert str(m["sensors"][0]) == expected and str(m["measurement"][0]) == "sensors"
        assert int(np.ravel(m["reads_sensors_only"])[0]) == 1
    m = loadmat(save_controller(ctrls["lqr"], tmp_path / "lqr.mat"))          # full state: says why not
    assert int(np.ravel(m["reads_sensors_only"])[0]) == 0
    assert str(m["sensors"][0]).startswith("none: the inputs are the design model's states")
    assert "hubbeam codegen --controller lqr" in str(m["sensors"][0])


@needs_cc
def test_gain_scheduled_lqg_in_c_equals_python_in_a_spin_up(tmp_path):
    """The schedule's interpolation on the measured hub rate, sample by sample, on FOAM."""
    p = Params(n_axial=1, n_transverse=1)
    schedule = DesignSchedule.build(p, [0.0, 1.5, 3.0], DT)
    ref = spinup_reference(3.0, 8.0, p.total_inertia, DT, 12.0, 200.0)
    ctrl = ScheduledLQG(schedule, LQGSettings(), reference=ref, variable="measured")
    code = to_c(ctrl, tmp_path / "slqg")
    assert code.law.kind == "scheduled_lqg"
    cc = CController(compile_c(code, "-O2", tmp_path), code, ctrl)
    settings = ClosedLoopSettings(dt=DT)
    py, c = (simulate_closed_loop("foam", x, 12.0, settings=settings) for x in (ctrl, cc))
    assert abs(py.v[-1, 0] - 3.0) < 0.05                  # the spin-up crossed the grid's points
    assert np.max(np.abs(c.tau - py.tau)) <= 1e-9 * ctrl.tau_max


@pytest.mark.slow
@needs_cc
def test_rig_controllers_with_integral_action_and_voltage_in_c_equal_python(tmp_path):
    """servo_link: the LQG with integral action and the observer-fed LQR with integral action, both
    commanding the DC motor in volts (controllers.integral, controllers.drive), generated as C and
    run on the rig's plant (drive, friction, encoder, half a sample of delay): the C voltage equals
    the Python one at every sample within 1e-9 of V_max, and the verdicts are equal."""
    import math

    from hubbeam_ctrl.plant.rig import load_rig
    from hubbeam_ctrl.study import Slew, compare
    from hubbeam_ctrl.study.judge import judge
    rig = load_rig("servo_link")
    c = compare(rig, Slew(math.pi / 2, 0.6), "lqr,lqg", CompareSettings(run=RunChoice(t_end=1.0)))
    hw = c.results["lqg"].settings["hardware"]
    assert hw["command"] == "voltage"
    from hubbeam_ctrl.sim.hardware import Hardware
    sc = c.scenario
    for name in ("lqr", "lqg"):
        py_ctrl = c.controllers[name]
        code = to_c(py_ctrl, tmp_path / name)
        assert code.metadata()["command"]["unit"] == "V"
        cc = CController(compile_c(code, "-O2", tmp_path), code, py_ctrl)
        run = simulate_closed_loop(c.plant, cc, sc.t_end, settings=sc.closed_loop_settings(),
                                   reference=(sc.reference.theta_at, sc.reference.theta_dot_at),
                                   hardware=Hardware.from_rig(rig))
        py = c.results[name]
        err = np.max(np.abs(run.tau - py.tau)) / rig.drive.V_max
        assert err <= 1e-9, (name, err)
        assert judge(run, py_ctrl, sc, c.plant.params, name)[0]["verdict"] == c.metrics[name]["verdict"]
