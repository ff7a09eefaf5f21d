"""Robust designs in the deploy path (issue 39 item 4): the multi-stage MPC and the H-infinity law as C.

Each generated step runs in the Python controller's place over a whole closed loop on the
nonlinear evaluation plant (Table 1's beam with a payload of the design's range) and its command
is held to the Python one at every sample; ``hubbeam codegen`` writes both from the CLI.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from controllers import (
    DesignModel,
    HInfSettings,
    KalmanNoise,
    MultiStageMPC,
    MultiStageMPCSettings,
    make_controller,
    slew_reference,
)
from controllers.hinf import have_slycot
from controllers.integral import ObservedFeedback
from hubbeam_ctrl import Params
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.deploy import NO_COMPILER, CController, compile_c, compiler, to_c
from hubbeam_ctrl.sim import ClosedLoopSettings, simulate_closed_loop

needs_cc = pytest.mark.skipif(compiler() is None, reason=NO_COMPILER)
needs_slycot = pytest.mark.skipif(not have_slycot(), reason="slycot (the robust extra) is not installed")

P = Params(n_axial=2, n_transverse=3)          # Table 1's beam (0.1 kg at the tip)
PAYLOADS = (0.0, 0.25, 0.5)                     # the scenarios of `certify msmpc --uncertainty m_t=0:0.5`
DT, T_F, T_END = 0.02, 3.0, 5.0


@pytest.fixture(scope="module")
def design():
    return DesignModel.build(P, 0.0, DT, 2)


@pytest.fixture(scope="module")
def ref():
    return slew_reference(0.5, T_F, P.total_inertia, 200.0, DT, T_END)


def _loop(ctrl, ref, m_t: float):
    """The closed loop on FOAM (3 modes) with the payload ``m_t`` [kg] at the tip."""
    return simulate_closed_loop("foam", ctrl, T_END, plant_params=P.replace(m_t=m_t),
                                settings=ClosedLoopSettings(dt=DT), reference=(ref.theta_at, ref.theta_dot_at))


@pytest.fixture(scope="module")
def msmpc(design, ref):
    return MultiStageMPC(design, MultiStageMPCSettings(horizon=15, payloads=PAYLOADS, tau_max=60.0), ref)


def test_the_tree_law_is_the_python_qp(msmpc):
    """The law's QP is the tree's: ``z`` of ``1 + S (N - 1)`` torques, the Hessian and state gradient
    of :class:`MultiStageMPC`, and the reference term of every table row equals ``Gx x - g`` of
    :meth:`MultiStageMPC.qp_at` at that sample."""
    law = to_c(msmpc).law
    n_u = 1 + 3 * (15 - 1)
    assert law.controller == "msmpc" and law.kind == "mpc" and law.n_reference == n_u == 43
    assert np.array_equal(law.arrays["H"], msmpc._Hu) and np.array_equal(law.arrays["GX"], msmpc._Gx)
    x = np.random.default_rng(0).normal(size=msmpc.design.n_x) * 0.01
    for k in (0, 37, len(law.arrays["REFT"]) + 5):        # inside the table and past its end
        g, _, _ = msmpc.qp_at(k * DT, x)
        kt = len(law.arrays["REFT"])
        r = law.arrays["REFT"][k] if k < kt else law.arrays["R0"] + (k - kt) * law.arrays["R1"]
        assert np.max(np.abs(msmpc._Gx @ x - r - g)) <= 1e-9 * np.max(np.abs(g))


@needs_cc
@pytest.mark.parametrize("m_t", [0.0, 0.5])
def test_msmpc_in_c_equals_python_over_a_slew(msmpc, ref, tmp_path, m_t):
    """The tree's C step (its observer, the generated box-QP solver on 43 torques) in the Python
    controller's place, at the range's ends: commands equal within 1e-9 of tau_max at every sample,
    with the torque bound active."""
    py_ctrl = ObservedFeedback(msmpc, KalmanNoise())          # what to_c wraps a bare tree in
    code = to_c(msmpc, tmp_path / "msmpc")
    cc = CController(compile_c(code, "-O2", tmp_path), code, msmpc)
    py, c = _loop(py_ctrl, ref, m_t), _loop(cc, ref, m_t)
    assert len(c.tau) == len(py.tau) == round(T_END / DT) + 1
    err = np.max(np.abs(c.tau - py.tau)) / msmpc.tau_max
    print(f"Table 1 msmpc (payloads {PAYLOADS} kg, plant {m_t} kg): max |C - Python| / tau_max = {err:.2e}")
    assert err <= 1e-9, err
    assert np.mean(np.abs(py.tau) >= msmpc.tau_max * (1 - 1e-12)) > 0.02     # the bound was active
    assert msmpc.n_fallbacks == 0


@pytest.fixture(scope="module")
def hinf(design, ref):
    if not have_slycot():
        pytest.skip("slycot (the robust extra) is not installed")
    return make_controller("hinf", design, HInfSettings(payloads=PAYLOADS, tau_max=200.0), ref)


@needs_slycot
def test_the_hinf_law_is_the_sampled_controller(hinf):
    """The observer template's arrays give back ``A_k, B_k, C_k, D_k`` of the sampled hinfsyn law."""
    law = to_c(hinf).law
    n = hinf.order
    nx, nh = n + 2, (n + 2) // 2
    pos = np.r_[1:nh, nh + 1:nx]
    assert law.controller == "hinf" and law.kind == "observer" and law.scalars["spin"] == 0.0
    assert np.array_equal(law.arrays["A"][np.ix_(pos, pos)], hinf._Ak)
    assert np.array_equal(law.arrays["BREF"][pos], hinf._Bk[:, 0])
    assert np.array_equal(law.arrays["K"][pos], -hinf._Ck[0]) and law.arrays["K"][0] == hinf._Dk[0, 0]
    assert law.arrays["K"][nh] == 0.0 and not np.any(law.arrays["A"][nh])


@needs_cc
@needs_slycot
@pytest.mark.parametrize("m_t", [0.0, 0.5])
def test_hinf_in_c_equals_python_over_a_slew(hinf, ref, tmp_path, m_t):
    """The H-infinity C step in the Python controller's place over the slew and past the reference
    table's end (t_end beyond it): commands equal within 1e-9 of tau_max at every sample."""
    code = to_c(hinf, tmp_path / "hinf")
    cc = CController(compile_c(code, "-O2", tmp_path), code, hinf)
    py, c = _loop(hinf, ref, m_t), _loop(cc, ref, m_t)
    err = np.max(np.abs(c.tau - py.tau)) / hinf.tau_max
    print(f"Table 1 hinf (payloads {PAYLOADS} kg, plant {m_t} kg): max |C - Python| / tau_max = {err:.2e}")
    assert err <= 1e-9, err
    assert np.max(np.abs(py.tau)) > 0.05 * hinf.tau_max


@needs_cc
@needs_slycot
def test_hinf_past_the_table_and_with_an_external_reference(hinf, ref, tmp_path):
    """Step for step on random angles: past the table's end (the angle continues at the final rate) and
    with the reference given at run time, the C equals the Python call within 1e-9 of tau_max."""
    code = to_c(hinf, tmp_path / "hinf")
    lib = compile_c(code, "-O2", tmp_path)
    cc = CController(lib, code, hinf)
    rng = np.random.default_rng(1)
    K = len(ref.theta)
    hinf.reset()
    cc.reset()
    for k in range(K + 40):
        y = np.array([0.5 * k / K + 0.01 * rng.normal(), 0.0, 0.0])
        assert abs(cc(k * DT, y) - hinf(k * DT, y)) <= 1e-9 * hinf.tau_max
    hinf.reset()
    cc.reset()
    nx = len(code.law.arrays["K"])
    for k in range(30):
        y = np.array([0.02 * rng.normal(), 0.0, 0.0])
        r = np.zeros(nx + 1)
        r[0], r[-1] = ref.theta[k], ref.torque[k]
        assert abs(cc.step(y, r) - hinf(k * DT, y)) <= 1e-9 * hinf.tau_max


def test_unsupported_tree_settings_are_refused_in_one_line(design, ref):
    with pytest.raises(ParameterError, match=r"^controller: a multi-stage MPC with a tip_bound cannot"):
        to_c(MultiStageMPC(design, MultiStageMPCSettings(horizon=5, payloads=PAYLOADS, tip_bound=0.1), ref))
    with pytest.raises(ParameterError, match=r"^controller: a multi-stage MPC with the DC motor's voltage rows "
                                             r"\(emf_torque_limit\)"):
        to_c(MultiStageMPC(design, MultiStageMPCSettings(horizon=5, payloads=PAYLOADS, emf_torque_limit=150.0,
                                                         emf_damping=300.0), ref))


@needs_cc
@pytest.mark.slow
def test_msmpc_on_a_torque_source_rig_in_c_equals_python(tmp_path, fast_backend):
    """accel_link (encoder + tip accelerometer, 1 kHz, a torque source), the tree over its payloads
    0.05 / 0.1 / 0.2 kg built as ``hubbeam codegen --rig accel_link --controller msmpc`` builds it (the
    rig's sensors in the design and its observer): the C step in the Python
    controller's place on the rig's plant, commands equal within 1e-9 of tau_max over the slew."""
    import math

    from controllers.integral import ObservedFeedback as Observed
    from hubbeam_ctrl.plant.rig import load_rig
    from hubbeam_ctrl.sim.hardware import Hardware
    from hubbeam_ctrl.study.design_task import task_and_design
    from hubbeam_ctrl.study.rig_loop import on_rig, rig_closed_loop, rig_design, rig_settings, task_noise
    rig = load_rig("accel_link")
    sc, design = task_and_design(rig.plant_params, "slew", rig=rig, slew_angle=math.pi / 2, t_f=1.5)
    design = rig_design(design, rig)
    settings = rig_settings("msmpc", MultiStageMPCSettings.for_scenario(sc).replace(payloads=(0.05, 0.1, 0.2)), rig)
    loop_settings, hardware = rig_closed_loop(rig, sc.closed_loop_settings())
    ms = MultiStageMPC(design, settings, sc.reference)
    py_ctrl = on_rig(ms, rig, task_noise(sc, rig), hardware)
    assert isinstance(py_ctrl, Observed) and len(ms.payloads) == 3
    code = to_c(py_ctrl, tmp_path / "msmpc")
    assert code.law.sensors == ("theta", "accel_tangential")
    cc = CController(compile_c(code, "-O2", tmp_path), code, py_ctrl)
    t_end = 2.5
    runs = [simulate_closed_loop("foam", x, t_end, plant_params=rig.plant_params, settings=loop_settings,
                                 reference=(sc.reference.theta_at, sc.reference.theta_dot_at),
                                 hardware=Hardware.from_rig(rig)) for x in (py_ctrl, cc)]
    py, c = runs
    assert len(c.tau) == len(py.tau) == round(t_end / sc.dt) + 1
    err = np.max(np.abs(c.tau - py.tau)) / ms.tau_max
    print(f"accel_link msmpc (3 scenarios, {code.law.n_reference} torques): max |C - Python| / tau_max = {err:.2e}")
    assert err <= 1e-9, err
    assert np.max(np.abs(py.tau)) > 0.05 * ms.tau_max


def test_cli_codegen_msmpc_and_hinf_over_a_payload_range(tmp_path, capsys):
    """``hubbeam codegen --controller msmpc|hinf --payload-range 0,0.5`` on Table 1's beam: the tree's
    scenarios are the range's ends and the tip mass (0, 0.1, 0.5 kg), compiled with the strict flags
    where a compiler is; --payload-range with another kind, or not holding the tip mass, exits 2."""
    from hubbeam_ctrl.cli import main
    base = ["codegen", "--slew-angle", "0.5", "--tf", "3", "--design-modes", "2", "--payload-range", "0,0.5",
            "--json"]
    kinds = ["msmpc"] + (["hinf"] if have_slycot() else [])
    for kind in kinds:
        assert main([*base, "--controller", kind, "--out", str(tmp_path / kind)]) == 0
        summary = json.loads(capsys.readouterr().out)
        assert summary["controller"] == kind and summary["compiled"] is (compiler() is not None)
        assert (tmp_path / kind / f"{kind}.h").is_file()
    meta = json.loads((tmp_path / "msmpc" / "msmpc.json").read_text())
    assert meta["n_reference"] == 1 + 3 * (50 - 1)      # 3 scenarios (0, 0.1, 0.5 kg) of the 50-step horizon
    assert main(["codegen", "--controller", "lqr", "--payload-range", "0,0.5", "--out", str(tmp_path / "x")]) == 2
    assert "--payload-range does not apply with --controller lqr" in capsys.readouterr().err
    assert main(["codegen", "--controller", "msmpc", "--payload-range", "0.2,0.5", "--out", str(tmp_path / "y")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "payload-range" in err and "Traceback" not in err



@pytest.mark.slow
@needs_slycot
def test_certify_writes_the_certified_hinf_with_its_verdict_in_the_header(tmp_path, capsys):
    """``hubbeam certify hinf --uncertainty m_t=0:0.5,damping=0.0005:0.02 --c-out DIR`` on Table 1's
    beam: certified, written as C whose header opens with the verdict, the set and the worst radius
    found (the certificate.json's), and whose NAME.json carries the certificate."""
    from hubbeam_ctrl.cli import main
    status = main(["certify", "hinf", "--uncertainty", "m_t=0:0.5,damping=0.0005:0.02", "--check", "none",
                   "--c-out", str(tmp_path / "c"), "--out", str(tmp_path / "cert")])
    capsys.readouterr()
    doc = json.loads((tmp_path / "cert" / "certificate.json").read_text())
    cert = doc["controllers"]["hinf"]["certificate"]
    assert status == 0 and cert["robust_verdict"] == "certified" and cert["robust_radius"] <= 1 - 1e-6
    assert doc["controllers"]["hinf"]["c_code"]["written"] is True
    header = (tmp_path / "c" / "hinf" / "hinf.h").read_text()
    assert header.startswith("/* Robust certificate: CERTIFIED over m_t [0, 0.5], damping [0.0005, 0.02].")
    assert f"found {cert['robust_radius']:.8f} at m_t = " in header.splitlines()[1]
    meta = json.loads((tmp_path / "c" / "hinf" / "hinf.json").read_text())
    assert meta["controller"] == "hinf" and meta["robust_certificate"]["robust_radius"] == cert["robust_radius"]


def robust_bench_rows(doc: dict) -> list:
    """docs/deploy.md's robust table from ``benchmarks/results/bench_codegen_robust.json``."""
    kg = " / ".join(f"{m:g}" for m in doc["payloads_kg"])
    names = {"msmpc": lambda e: f"msmpc, scenarios {kg} kg, horizon {e['horizon']} ({e['qp_torques']} torques)",
             "hinf": lambda e: f"hinf, payloads {kg} kg ({e['order']} states)"}
    us = lambda v: f"{v:.3g}" if v < 1000 else f"{v:.0f}"      # noqa: E731
    rows = []
    for kind, e in doc["controllers"].items():
        rows.append(f"| {names[kind](e)} | {us(e['c_step_us_median'])} / {us(e['c_step_us_p99'])} / "
                    f"{us(e['c_step_us_max'])} | {us(e['python_step_us_median'])} | {e['code_text_bytes']} | "
                    f"{e['rodata_bytes']} | {e['max_diff_over_tau_max']:.2g} |")
    return rows


def test_docs_quote_the_robust_codegen_benchmark():
    """docs/deploy.md's robust table is bench_codegen_robust.json's; the replayed C followed Python there."""
    from pathlib import Path
    root = Path(__file__).resolve().parents[1]
    doc = json.loads((root / "benchmarks" / "results" / "bench_codegen_robust.json").read_text())
    text = (root / "docs" / "deploy.md").read_text()
    for row in robust_bench_rows(doc):
        assert row in text, row
    assert all(e["max_diff_over_tau_max"] <= 1e-9 for e in doc["controllers"].values())
