"""The MPC on a DC motor as generated C (issue 36): its QP with the voltage limit through back-EMF.

Reference: the Python MPC (DAQP on the condensed QP with the rows ``|u_i + b theta_dot_i| <= g V_max``,
:attr:`controllers.MPCSettings.emf_torque_limit`) behind its filter and the drive's voltage stage, as
``compare --rig`` runs it; the C is generated from it, compiled with the strict flags and run in its
place. The QP is strictly convex, so both solvers have one minimiser: the commands agree to rounding.
"""

import json
import math

import numpy as np
import pytest
from conftest import until_first_stick

from controllers import MPC, DesignModel, MPCSettings, slew_reference
from controllers.mpc import DirectDAQP
from hubbeam_ctrl import Params
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.deploy import NO_COMPILER, CController, ObservedMPC, compile_c, compiler, to_c
from hubbeam_ctrl.deploy.laws import control_law
from hubbeam_ctrl.plant.rig import load_rig
from hubbeam_ctrl.sim import simulate_closed_loop
from hubbeam_ctrl.sim.hardware import Hardware

needs_cc = pytest.mark.skipif(compiler() is None, reason=NO_COMPILER)

#: The slew's duration in units of servo_link's time-optimal 90 degree slew T*. At 1.2 T* the plan
#: never reaches the voltage limit (measured: the command peaks at 9.05 V of 10 V, no voltage row
#: at its bound); at 1.1 T* it does (137 of 1791 plans with a voltage row at its bound;
#: benchmarks/results/bench_mpc_dc.json).
FACTOR = 1.1


def _small_mpc(limit_fraction: float = 1.0, damping: float = 20.0, tip_bound=None) -> MPC:
    """A 2-mode MPC at 20 Hz on Table 1's beam with a voltage limit ``limit_fraction`` of tau_max
    through a back-EMF torque of ``damping`` N m s/rad (tight enough that its rows bind)."""
    p = Params(n_axial=1, n_transverse=1)
    design = DesignModel.build(p, 0.0, 0.05)
    ref = slew_reference(0.5, 8.0, p.total_inertia, 200.0, 0.05, 16.0)
    s = MPCSettings(horizon=20, tau_max=8.0, emf_torque_limit=limit_fraction * 8.0, emf_damping=damping,
                    tip_bound=tip_bound)
    return MPC(design, s, reference=ref)


def _row_activity(records, limit) -> tuple:
    """``(plans with a voltage row at its bound, plans whose first step's voltage is at its bound)``
    from DAQP's recorded solves ``(A z, lo, hi)``."""
    any_row = first = 0
    for Az, lo, hi in records:
        at = (np.abs(Az - hi) <= 1e-9 * limit) | (np.abs(Az - lo) <= 1e-9 * limit)
        any_row += bool(at.any())
        first += bool(at[0])
    return any_row, first


class _Records(list):
    """The recorded solves, and the solver of each."""

    def __init__(self):
        super().__init__()
        self.solvers = []


def _own(records: _Records, solver) -> list:
    """The records of ``solver``'s solves only."""
    return [r for r, s in zip(records, records.solvers) if s is solver]


@pytest.fixture
def recorded(monkeypatch):
    """DAQP's solves, recorded: ``(A z, lba, uba)`` for each (the voltage rows and their bounds), with the
    solver of each in ``records.solvers`` (a planner's solves, e.g. the slew planned with its tip rows
    when the plan is not in the build cache yet, are not the MPC's: :func:`_own`)."""
    records = _Records()
    solve = DirectDAQP.solve

    def recording(self, g, lba=None, uba=None, warm_start=True):
        z = solve(self, g, lba, uba, warm_start)
        if lba is not None:
            records.append((self._A @ z, np.array(lba), np.array(uba)))
            records.solvers.append(self)
        return z
    monkeypatch.setattr(DirectDAQP, "solve", recording)
    return records


def test_the_law_carries_the_rows_the_python_mpc_bounds():
    """``control_law`` of an MPC with an emf_torque_limit: ``AV`` is the Python QP's constraint matrix,
    ``lo, hi = -+LIM - OFFX x`` its row bounds at a state, ``CM = L^-1 [I; AV]'`` rows with ``H = L L'``."""
    mpc = _small_mpc()
    law = control_law(ObservedMPC(mpc))
    N = mpc.settings.horizon
    a = law.arrays
    assert a["AV"].shape == (N, N) and a["OFFX"].shape == (N, mpc.design.n_x)
    np.testing.assert_array_equal(a["AV"], np.asarray(mpc._A.full())[:, :N])
    x = np.random.default_rng(3).normal(size=mpc.design.n_x)
    _, _, lba, uba = mpc._qp_at(0.0, x)
    np.testing.assert_allclose(-a["LIM"] - a["OFFX"] @ x, lba, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(a["LIM"] - a["OFFX"] @ x, uba, rtol=1e-14, atol=1e-14)
    H = np.asarray(mpc._H.full())
    C = np.vstack([np.eye(N), a["AV"]])
    np.testing.assert_allclose(a["GM"], C @ np.linalg.solve(H, C.T), rtol=1e-10, atol=1e-12 * np.max(a["GM"]))
    np.testing.assert_allclose(a["HL"] @ a["CM"].T, C.T, atol=1e-12)


def test_a_tip_bound_and_single_precision_are_refused():
    """A tip bound (not generated) and single precision (the rows' active set needs double): one line each."""
    with pytest.raises(ParameterError, match="tip_bound cannot be generated as C yet"):
        control_law(ObservedMPC(_small_mpc(tip_bound=0.01)))
    with pytest.raises(ParameterError, match="^precision: 'single' does not apply to an MPC with a DC motor's "
                                             "voltage limit .*; use 'double'$"):
        to_c(ObservedMPC(_small_mpc()), None, "single")


@needs_cc
def test_c_qp_equals_daqp_on_random_measurements(recorded, tmp_path):
    """The small MPC's C step against the Python one (DAQP), both given the same random sensor values
    (the filter's state jumps: the QP meets states of every kind): the commands agree, the voltage
    rows were at their bounds in many solves, and DAQP never failed (no LQR fallback to compare)."""
    mpc = _small_mpc()
    py = ObservedMPC(mpc)
    code = to_c(py, tmp_path / "mpc")
    assert "feasible_start" in code.source and "static const double H[" not in code.source
    cc = CController(compile_c(code, "-O2", tmp_path), code, py)
    rng = np.random.default_rng(36)
    py.reset()
    cc.reset()
    errs = []
    for k in range(400):
        y = np.array([rng.normal(0.0, 0.03), rng.normal(0.0, 0.05), rng.normal(0.0, 2.0)])
        errs.append(abs(cc(k * mpc.dt, y) - py(k * mpc.dt, y)))
    err = max(errs) / mpc.tau_max
    recorded = _own(recorded, mpc.solver)
    rows, first = _row_activity(recorded, mpc.settings.emf_torque_limit)
    print(f"max |C - Python| / tau_max = {err:.2e}; voltage row at a bound in {rows} of "
          f"{len(recorded)} solves (first step's in {first})")
    assert len(recorded) == 400 and mpc.n_fallbacks == 0
    assert rows >= 40 and first >= 10
    assert err <= 1e-9, err


@needs_cc
@pytest.mark.slow
def test_c_step_equals_python_over_a_slew_on_servo_link(recorded, fast_backend, tmp_path):
    """servo_link (DC motor, Coulomb friction, encoder + tachometer, half a sample of delay), 90 degrees
    in 1.1 T*: the plan meets the voltage limit in some samples, and the C, run in the Python MPC's place
    on the same plant, returns its volts to 1e-9 of V_max until the hub first sticks; same verdict."""
    from hubbeam_ctrl.study import Slew, compare
    from hubbeam_ctrl.study.judge import judge
    from tests.conftest import ROOT
    rig = load_rig("servo_link")
    # T* of `hubbeam optimal --rig servo_link --slew-angle pi/2` (benchmarks/bench_any_rig.py; 14 s to recompute)
    optimal = json.loads((ROOT / "benchmarks" / "results" / "bench_any_rig.json").read_text())["rigs"]["servo_link"]
    assert optimal["angle_rad"] == math.pi / 2
    t_star = optimal["t_opt_s"]
    c = compare(rig, Slew(math.pi / 2, FACTOR * t_star), "mpc")
    sc, py_ctrl, py = c.scenario, c.controllers["mpc"], c.results["mpc"]
    mpc = py_ctrl.inner.inner
    recorded = _own(recorded, mpc.solver)
    rows, first = _row_activity(recorded, mpc.settings.emf_torque_limit)
    assert len(recorded) == len(py.tau) and mpc.n_fallbacks == 0
    assert rows > 0 and first > 0                   # the voltage limit is active in the plan, and on the command
    code = to_c(py_ctrl, tmp_path / "mpc")
    assert code.metadata()["command"] == {"name": "V", "unit": "V", "V_max": rig.drive.V_max}
    cc = CController(compile_c(code, "-O2", tmp_path), code, py_ctrl)
    run = simulate_closed_loop(c.plant, cc, sc.t_end, settings=sc.closed_loop_settings(),
                               reference=(sc.reference.theta_at, sc.reference.theta_dot_at),
                               hardware=Hardware.from_rig(rig))
    assert len(run.tau) == len(py.tau) == round(sc.t_end / sc.dt) + 1
    moving = until_first_stick(py, sc.t_f, rig)
    err = np.max(np.abs(run.tau - py.tau)[moving]) / rig.drive.V_max
    print(f"servo_link 90 deg in {FACTOR} T* = {FACTOR * t_star:.4f} s: voltage row at its bound in {rows} of "
          f"{len(recorded)} plans (first step's in {first}); max |C - Python| / V_max = {err:.2e} over "
          f"{int(moving.sum())} samples until the first stick")
    assert err <= 1e-9, err
    assert np.max(np.abs(py.tau)) >= 0.999 * rig.drive.V_max        # the command reached the limit
    assert judge(run, py_ctrl, sc, c.plant.params, "mpc")[0]["verdict"] == c.metrics["mpc"]["verdict"]


def test_cli_codegen_mpc_on_a_dc_motor(tmp_path, capsys):
    """``hubbeam codegen --controller mpc --rig servo_link``: once refused, now written (and compiled with
    the strict flags where a compiler is); the header says the step commands volts within +-V_max."""
    from hubbeam_ctrl.cli.main import main
    rig = load_rig("servo_link")
    out = tmp_path / "mpc"
    assert main(["codegen", "--controller", "mpc", "--rig", "servo_link", "--slew-angle", "1.5", "--tf", "0.5",
                 "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["command"] == {"name": "V", "unit": "V", "V_max": rig.drive.V_max}
    assert summary["compiled"] is (compiler() is not None)
    header = (out / "mpc.h").read_text()
    assert f"#define MPC_V_MAX {rig.drive.V_max:.17g}  /* [V] */" in header
    assert f"the DC motor's voltage [V] to hold until the next sample, within +-V_max = {rig.drive.V_max:.12g} V" \
        in header
    assert "voltage limit through back-EMF" in header
    assert "feasible_start" in (out / "mpc.c").read_text()


def test_cli_still_refuses_zv_and_single_precision_on_a_dc_motor(tmp_path, capsys):
    """ZV on servo_link's DC motor (an input-shaped torque table, not generated in volts) and the MPC in
    single precision there: one line each, exit 2, nothing written."""
    from conftest import assert_refused_in_one_line
    assert_refused_in_one_line(["codegen", "--controller", "zv", "--rig", "servo_link", "--out",
                                str(tmp_path / "z")], "--controller zv does not apply with --rig servo_link",
                               tmp_path, capsys)
    assert_refused_in_one_line(["codegen", "--controller", "mpc", "--rig", "servo_link", "--precision", "single",
                                "--out", str(tmp_path / "s")],
                               "--precision single does not apply with --controller mpc --rig servo_link", tmp_path,
                               capsys)


def test_docs_quote_the_benchmark_and_the_c_follows_daqp_there():
    """docs/deploy.md's table is benchmarks/results/bench_mpc_dc.json; in those replays the C volts
    equal the Python ones to 1e-9 of V_max, never failed, stayed within the iteration limit, and at
    1.1 T* the voltage rows bound (at 1.2 T* they need not); the step's median within the sample."""
    from conftest import bench_module
    bench, root = bench_module("bench_mpc_dc")
    doc = json.loads((root / "benchmarks" / "results" / "bench_mpc_dc.json").read_text())
    text = (root / "docs" / "deploy.md").read_text()
    assert "<!-- bench_mpc_dc table: generated from benchmarks/results/bench_mpc_dc.json -->" in text
    for line in bench.table_lines(doc):
        assert line in text, line
    for f, r in doc["factors"].items():
        assert r["max_diff_over_v_max"] <= 1e-9 and r["c_failures"] == 0, f
        assert r["iterations_max"] <= 8 * r["horizon"] + 10 and r["samples"] == r["plans"], f
        assert r["c_step_us_median"] * 1e-6 < r["dt_s"], f
    assert doc["factors"][f"{FACTOR:g}"]["plans_with_a_voltage_row_at_its_bound"] > 0
    peak = doc["factors"]["1.2"]["peak_volts"]
    assert peak < doc["factors"]["1.2"]["v_max"] and f"(the command peaks at {peak:.2f} V of 10 V)" in text


@needs_cc
def test_no_feasible_plan_is_counted_where_the_python_mpc_falls_back(tmp_path):
    """Sensor values ten times wilder (the filter's hub rate beyond what the voltage can brake): some QPs
    have no feasible plan. DAQP fails there and the Python MPC falls back to its LQR torque; the C keeps
    its plan within the torque limit and counts a failure: on the same samples, and only there the
    commands differ (read through a getter compiled beside the generated source)."""
    import ctypes
    import subprocess

    from hubbeam_ctrl.deploy import STRICT_FLAGS
    mpc = _small_mpc()
    py = ObservedMPC(mpc)
    code = to_c(py, tmp_path / "mpc")
    (tmp_path / "get.c").write_text('#include "mpc/mpc.h"\nlong mpc_failures(const mpc_instance *inst);\n'
                                    'long mpc_failures(const mpc_instance *inst) { return inst->failures; }\n')
    lib = tmp_path / "libmpc.so"
    subprocess.run([compiler(), *STRICT_FLAGS, "-O2", "-fPIC", "-shared", str(tmp_path / "mpc" / "mpc.c"),
                    str(tmp_path / "get.c"), "-o", str(lib), "-lm"], check=True)
    cc = CController(lib, code, py)
    failures = cc._lib.mpc_failures
    failures.argtypes, failures.restype = [ctypes.c_void_p], ctypes.c_long
    rng = np.random.default_rng(36)
    py.reset()
    cc.reset()
    c_failed, py_failed, errs = [], [], []
    for k in range(400):
        y = np.array([rng.normal(0.0, 0.3), rng.normal(0.0, 0.5), rng.normal(0.0, 20.0)])
        before = mpc.n_fallbacks, failures(cc._inst)
        tau_c, tau_py = cc(k * mpc.dt, y), py(k * mpc.dt, y)
        assert abs(tau_c) <= mpc.tau_max
        py_failed.append(mpc.n_fallbacks > before[0])
        c_failed.append(failures(cc._inst) > before[1])
        if not py_failed[-1]:
            errs.append(abs(tau_c - tau_py))
    print(f"{sum(c_failed)} C failures, {sum(py_failed)} Python fallbacks of 400; elsewhere max |C - Python| / "
          f"tau_max = {max(errs) / mpc.tau_max:.2e}")
    assert c_failed == py_failed and sum(c_failed) > 0
    assert max(errs) <= 1e-9 * mpc.tau_max
