"""The NMPC's step as generated C (issue 40, item 3): the same function the Python step calls, so a
whole slew with the C step gives the Python step's commands to within 1e-8 of the limit."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from controllers import NMPC, DesignModel, NMPCSettings
from hubbeam_ctrl import Params
from hubbeam_ctrl.core.compiled import find_compiler
from hubbeam_ctrl.core.errors import ParameterError

LAB = Params(L=1, rho=2700, A=9e-5, E=69e9, I=6.75e-11, J_h=0.02, r=0.05, m_t=0.1, tau_max=1.5)


def test_the_step_function_is_the_python_step():
    """The NMPC's sample is its CasADi step function: called by hand from the controller's own plan,
    it gives the plan and command the controller then holds."""
    design = DesignModel.build(LAB.replace(n_transverse=3), 0.0, 0.01, 3)
    ctrl = NMPC(design, NMPCSettings(horizon=8))
    ctrl.reset()
    y = np.zeros(design.n_x)
    y[ctrl.prediction_states] = 1e-3 * np.arange(1, len(ctrl.prediction_states) + 1)
    xr, ur = ctrl._reference_window(0, 8)
    X, U, _ = (np.asarray(a) for a in ctrl.symbolic_step(y[ctrl.prediction_states], ctrl._X, ctrl._U[None, :],
                                                       xr.T, ur[None, :], ctrl._W[0], ctrl._W[-1]))
    u = ctrl(0.0, y)
    np.testing.assert_array_equal(ctrl._U, U.ravel())
    np.testing.assert_array_equal(ctrl._X, X)
    assert abs(u) <= LAB.tau_max and u != 0.0


@pytest.mark.slow
@pytest.mark.skipif(not find_compiler(), reason="no C compiler: the generated step cannot be built here")
def test_a_slew_with_the_generated_c_step_is_the_python_steps(monkeypatch):
    """Software in the loop: the lab arm's slew with the step's generated C (backend "compiled")
    and with CasADi's virtual machine give commands within 1e-8 of the torque limit at every sample.
    The step is built at -O0 (10 s against 84 s at -O1 for its 1.6 MB of C; the same C)."""
    monkeypatch.setenv("HUBBEAM_CC_OPT", "-O0")
    from hubbeam_ctrl.study import Slew, compare
    from hubbeam_ctrl.study.compare_values import CompareSettings, DesignChoice
    from hubbeam_ctrl.study.scenarios import make_scenario
    task, beam = Slew(math.pi / 2, 1.3), LAB.replace(n_transverse=3)
    own = NMPCSettings.for_scenario(make_scenario(task, params=beam, t_end=None)).replace(horizon=10)
    runs = {}
    for backend in ("vm", "compiled"):
        c = compare(beam, task, ["nmpc"],
                    CompareSettings(design=DesignChoice(settings={"nmpc": own.replace(backend=backend)})))
        runs[backend] = np.asarray(c.results["nmpc"].tau, dtype=float)
        assert c.metrics["nmpc"]["verdict"] == "settled"
    assert np.max(np.abs(runs["vm"] - runs["compiled"])) <= 1e-8 * LAB.tau_max
    assert np.max(np.abs(runs["vm"])) > 0.3 * LAB.tau_max              # a slew, not a rest


def test_nmpc_to_c_writes_a_self_contained_step(tmp_path):
    """The written C holds the step with its QP solver (no CasADi headers) and the JSON its sizes (the
    same step's generated C builds and runs in the software-in-the-loop test above)."""
    from hubbeam_ctrl.deploy.nmpc_c import nmpc_to_c
    design = DesignModel.build(LAB.replace(n_transverse=3), 0.0, 0.01, 3)
    ctrl = NMPC(design, NMPCSettings(horizon=6))
    info = nmpc_to_c(ctrl, tmp_path, name="arm_nmpc")
    source = (tmp_path / "arm_nmpc.c").read_text()
    assert "int arm_nmpc(" in source and "casadi.h" not in source.split("#include \"arm_nmpc.h\"")[0]
    saved = json.loads((tmp_path / "arm_nmpc.json").read_text())
    assert saved == json.loads(json.dumps(info))
    assert saved["inputs"]["X"] == [len(ctrl.prediction_states), 7] and saved["outputs"]["U_next"] == [1, 6]
    assert saved["qp_solver"] == "daqp" and saved["outputs"]["qp_residual"] == [1, 1]
    with pytest.raises(ParameterError, match="name must be a C identifier"):
        nmpc_to_c(ctrl, tmp_path, name="1bad")


@pytest.mark.skipif(not find_compiler(), reason="no C compiler: the written step cannot be built here")
def test_the_written_c_links_daqp_and_is_the_python_step(tmp_path):
    """The files ``nmpc_to_c`` writes, built with the compiler flags and DAQP's library it names
    (from CasADi's wheel), give the Python step's plan and QP residual at a moving state."""
    import subprocess

    import casadi as ca

    from hubbeam_ctrl.core.linked_solvers import solver_link_flags
    from hubbeam_ctrl.deploy.nmpc_c import nmpc_to_c
    design = DesignModel.build(LAB.replace(n_transverse=3), 0.0, 0.01, 3)
    ctrl = NMPC(design, NMPCSettings(horizon=6))
    info = nmpc_to_c(ctrl, tmp_path, name="arm_nmpc")
    source = (tmp_path / "arm_nmpc.c").read_text()
    cflags, libs = solver_link_flags(source)
    assert "#include <daqp/api.h>" in source and len(libs) == 1 and libs[0] in info["build"]
    lib = tmp_path / "arm_nmpc.so"
    subprocess.run([*find_compiler(), "-O1", "-fPIC", "-shared", *cflags, str(tmp_path / "arm_nmpc.c"), *libs,
                    "-o", str(lib), "-lm"], check=True, capture_output=True, timeout=300)
    c_step = ca.external("arm_nmpc", str(lib))
    ctrl.reset()
    x = np.zeros(len(ctrl.prediction_states))
    x[0] = 5.0                                                  # far off the reference: bounds active
    xr, ur = ctrl._reference_window(0, 6)
    args = (x, ctrl._X, ctrl._U[None, :], xr.T, ur[None, :], ctrl._W[0], ctrl._W[-1])
    py, c = ctrl.symbolic_step(*args), c_step(*args)
    assert np.max(np.abs(np.asarray(py[1]))) == pytest.approx(LAB.tau_max)
    np.testing.assert_allclose(np.asarray(c[1]), np.asarray(py[1]), rtol=0, atol=1e-10 * LAB.tau_max)
    np.testing.assert_allclose(np.asarray(c[0]), np.asarray(py[0]), rtol=1e-9, atol=1e-12)
    assert float(c[2]) <= 1e-9 * LAB.tau_max


def test_cli_codegen_writes_the_nmpc_step(tmp_path, capsys):
    from hubbeam_ctrl.cli.main import main
    out = tmp_path / "nmpc"
    assert main(["codegen", "--controller", "nmpc", "--slew-angle", "1", "--tf", "4", "--n-modes", "3",
                 "--out", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert sorted(p.name for p in out.iterdir()) == ["nmpc_rti.c", "nmpc_rti.h", "nmpc_rti.json"]
    assert info["horizon"] == 20 and info["dt_s"] == pytest.approx(0.01)
    assert main(["codegen", "--controller", "nmpc", "--precision", "single", "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--precision single" in err and "--controller nmpc" in err
