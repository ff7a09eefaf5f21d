"""Controllers as python-control systems, their loop margins and their export (issue 11, items 5-6)."""

from __future__ import annotations

import math

import control
import numpy as np
import pytest
import scipy.io

from controllers import LQG, LQR, MPC, PD, DesignModel, LQGSettings, MPCSettings
from controllers.analysis import closed_loop_poles, design_plant, loop_margins, loop_matrices
from controllers.export import FORMATS, load_controller, save_controller
from hubbeam_ctrl import Params
from hubbeam_ctrl.core.errors import HubbeamError, ParameterError
from hubbeam_ctrl.linear.export import load_model, save_model

#: The issue's lab arm (a 1 m x 30 mm x 3 mm aluminium strip on a small hub, 1.5 N m motor).
LAB = Params(L=1, rho=2700, A=9e-5, E=69e9, I=6.75e-11, J_h=0.02, r=0.05, m_t=0.05, tau_max=1.5)


@pytest.fixture(scope="module")
def design():
    return DesignModel.build(Params(n_axial=2, n_transverse=3), 0.0, 0.01)


@pytest.fixture(scope="module")
def controllers(design):
    return {"pd": PD(design), "lqr": LQR(design), "lqg": LQG(design)}


def _sorted(z):
    z = np.asarray(z, dtype=complex)
    return z[np.lexsort((np.round(z.imag, 9), np.round(z.real, 9)))]


def test_statespace_has_named_signals(controllers, design):
    pd, lqr, lqg = (controllers[k].to_statespace() for k in ("pd", "lqr", "lqg"))
    assert pd.input_labels == ["theta", "theta_dot"] and pd.nstates == 0
    assert lqr.input_labels == design.state_names and lqr.nstates == 0
    assert lqg.input_labels == ["theta", "theta_dot", "root_moment"]
    # the filter runs on the design modes plus the residual modes (controllers.residual)
    assert lqg.state_labels == [f"{s}_est" for s in controllers["lqg"].filter_model.state_names]
    assert lqg.nstates > design.n_x
    for sys in (pd, lqr, lqg):
        assert sys.output_labels == ["tau"] and sys.dt == design.dt


@pytest.mark.parametrize("name", ["pd", "lqr", "lqg"])
def test_statespace_reproduces_the_controller(controllers, design, name):
    """The system and the controller's own call give the same torques (small errors, no saturation)."""
    ctrl = controllers[name]
    sys = ctrl.to_statespace()
    rng = np.random.default_rng(1)
    n_in = sys.ninputs
    scale = np.array([1e-4, 1e-3, 1e-2])[:n_in] if name != "lqr" else 1e-5 * np.ones(n_in)
    e = rng.standard_normal((200, n_in)) * scale
    if name == "lqr":
        y_full = e
    else:                                            # the controller reads [theta, theta_dot, M_root]
        y_full = np.zeros((200, 3))
        y_full[:, :n_in] = e
    # feedforward off: the reference is rest at 0 (the call then is the pure feedback law)
    ctrl_ff = type(ctrl)(design, ctrl.settings.__class__(feedforward=False))
    ctrl_ff.reset()
    taus = np.array([ctrl_ff(k * design.dt, y_full[k]) for k in range(200)])
    assert np.max(np.abs(taus)) < ctrl_ff.tau_max                      # never saturated
    resp = control.forced_response(sys, T=design.dt * np.arange(200), U=e.T)
    np.testing.assert_allclose(np.ravel(resp.outputs), taus, rtol=1e-9, atol=1e-9 * np.max(np.abs(taus)))


def test_lqg_closed_loop_poles_are_regulator_and_filter_poles(design):
    lqg = LQG(design, LQGSettings(robust=False))          # filter on the design model: separation
    K, L = lqg.K[None, :], lqg.L
    expected = np.concatenate([np.linalg.eigvals(design.Ad - design.Bd @ K),
                               np.linalg.eigvals(design.Ad - design.Ad @ L @ design.C_sensors)])
    np.testing.assert_allclose(_sorted(closed_loop_poles(lqg)), _sorted(expected), atol=1e-9)
    closed = control.feedback(design_plant(lqg), lqg.to_statespace(), sign=1)
    np.testing.assert_allclose(_sorted(closed.poles()), _sorted(expected), atol=1e-9)


def test_mpc_linear_form_is_the_lqr_gain_and_openloop_has_none(design):
    """Unconstrained, the MPC's first move is -(H^-1 Gx)[0] x; with the Riccati solution as
    terminal weight that is the LQR gain at any horizon (issue 27: the MPC gets a certificate)."""
    from controllers import OpenLoop
    lqr = LQR(design)
    for horizon in (5, 50):
        D = MPC(design, MPCSettings(horizon=horizon)).to_statespace().D
        np.testing.assert_allclose(np.ravel(D), -lqr.K, rtol=1e-7, atol=1e-9 * np.max(np.abs(lqr.K)))
    with pytest.raises(HubbeamError, match="not a linear time-invariant"):
        OpenLoop(design).to_statespace()


def _spectral_radius(ctrl, gain: float) -> float:
    A, B, C, _ = loop_matrices(ctrl)
    return float(np.max(np.abs(np.linalg.eigvals(A - gain * B @ C))))


@pytest.mark.parametrize("params", [Params(n_axial=2, n_transverse=3), LAB], ids=["paper", "lab"])
@pytest.mark.parametrize("name", ["lqr", "lqg"])
def test_margins_are_where_the_loop_goes_unstable(params, name):
    design = DesignModel.build(params, 0.0, 0.01)
    ctrl = (LQR if name == "lqr" else LQG)(design)
    m = loop_margins(ctrl, check=True)
    assert m.stable and m.spectral_radius < 1
    # python-control's disk margin on the same grid agrees with the direct sensitivity peak,
    # and refining the peak only finds a higher one
    assert m.disk_margin_control == pytest.approx(m.disk_margin_grid, rel=1e-8)
    assert m.disk_margin <= m.disk_margin_grid * (1 + 1e-12)
    assert m.disk_margin == pytest.approx(m.disk_margin_grid, rel=2e-3)
    lo, hi = m.disk_gain_margin
    # gains inside the disk keep the loop stable; the classical margins lie outside it
    for g in (lo * 1.001, hi * 0.999):
        assert _spectral_radius(ctrl, g) < 1
    assert m.gain_margin_upper >= hi and m.gain_margin_lower <= lo
    assert abs(m.phase_margin_deg) >= m.disk_phase_margin_deg - 1e-6
    # the upper gain margin is where a pole crosses the unit circle
    if math.isfinite(m.gain_margin_upper):
        assert _spectral_radius(ctrl, m.gain_margin_upper * (1 - 1e-5)) < 1
        assert _spectral_radius(ctrl, m.gain_margin_upper * (1 + 1e-5)) > 1
    if m.gain_margin_lower > 0:
        assert _spectral_radius(ctrl, m.gain_margin_lower * (1 + 1e-5)) < 1
        assert _spectral_radius(ctrl, m.gain_margin_lower * (1 - 1e-5)) > 1
    assert 0 < m.delay_margin_s < math.inf
    assert m.delay_margin_samples == pytest.approx(m.delay_margin_s / 0.01)


def test_delay_margin_matches_a_delayed_loop(controllers):
    """A whole-sample delay below the delay margin keeps the loop stable, above it does not."""
    lqg = controllers["lqg"]
    m = loop_margins(lqg)
    A, B, C, _ = loop_matrices(lqg)
    n = A.shape[0]

    def radius(d):                               # d samples of delay at the plant input
        Ad = np.zeros((n + d, n + d))
        Ad[:n, :n] = A
        Ad[:n, n:n + 1] = B if d else 0
        if d:
            Ad[n + d - 1, :n] = -C[0]
            Ad[n:n + d - 1, n + 1:n + d] = np.eye(d - 1)
        else:
            Ad[:n, :n] = A - B @ C
        return np.max(np.abs(np.linalg.eigvals(Ad)))

    below, above = math.floor(m.delay_margin_samples), math.ceil(m.delay_margin_samples)
    assert radius(below) < 1 < radius(above + 0)


# -- export ---------------------------------------------------------------------------------------
FMT = [f.lstrip(".") for f in FORMATS]


@pytest.mark.parametrize("fmt", FMT)
@pytest.mark.parametrize("name", ["pd", "lqr", "lqg"])
def test_controller_round_trip_bit_for_bit(controllers, name, fmt, tmp_path):
    ctrl = controllers[name]
    path = save_controller(ctrl, tmp_path / f"{name}.{fmt}")
    back = load_controller(path)
    sys = ctrl.to_statespace()
    for key, mat in zip(("Ac", "Bc", "Cc", "Dc"), (sys.A, sys.B, sys.C, sys.D)):
        a = getattr(back, key)
        assert a.shape == np.shape(mat) and a.tobytes() == np.asarray(mat, dtype=float).tobytes(), key
    assert back.dt == ctrl.dt and back.input_names == list(sys.input_labels)
    assert back.state_names == list(sys.state_labels) and back.output_names == ["tau"]
    assert back.metadata["tau_max_nm"] == ctrl.tau_max and back.metadata["controller"] == name
    assert back.params == ctrl.design.params
    assert load_controller(save_controller(back, tmp_path / f"again.{fmt}")) == back
    units = dict(zip(back.input_names, back.metadata["input_units"]))
    assert units.get("theta") == "rad" and units.get("theta_dot") == "rad/s"


def test_mat_controller_for_matlab(controllers, tmp_path):
    path = save_controller(controllers["lqg"], tmp_path / "lqg.mat")
    S = scipy.io.loadmat(path)
    n = controllers["lqg"].filter_model.n_x
    assert S["Ac"].shape == (n, n) and S["Dc"].shape == (1, 3)
    assert [str(c[0]) for c in S["input_names"].ravel()] == ["theta", "theta_dot", "root_moment"]
    assert S["dt"].item() == 0.01 and str(S["controller"][0]) == "lqg"


def _closed_by_name(plant, ctrl):
    """Closed by signal name: the controller reads theta, theta_dot, root_moment and drives tau;
    an input disturbance d enters at tau."""
    return control.interconnect([plant, ctrl], inplist=["tau"], inputs=["d"], outlist=["tip_deflection"],
                                outputs=["tip_deflection"], check_unused=False)


@pytest.mark.parametrize("robust", [False, True])
def test_exported_lqg_closed_with_exported_plant_has_the_design_poles(design, tmp_path, robust):
    lqg = LQG(design, LQGSettings(robust=robust))
    plant = load_model(save_model(design.linear_model, tmp_path / "plant.mat")).sys
    ctrl = load_controller(save_controller(lqg, tmp_path / "lqg.mat")).sys
    closed = _closed_by_name(plant, ctrl)
    np.testing.assert_allclose(_sorted(closed.poles()), _sorted(closed_loop_poles(lqg)), atol=1e-9)
    assert np.max(np.abs(closed.poles())) < 1
    if not robust:          # the filter's model is the plant: regulator and filter poles
        expected = np.concatenate([
            np.linalg.eigvals(design.Ad - design.Bd @ lqg.K[None, :]),
            np.linalg.eigvals(design.Ad - design.Ad @ lqg.L @ design.C_sensors)])
        np.testing.assert_allclose(_sorted(closed.poles()), _sorted(expected), atol=1e-9)
    else:                   # closed with its filter's own model: the separation holds there
        fm = lqg.filter_model
        plant_f = load_model(save_model(fm.linear_model, tmp_path / "filter_plant.npz")).sys
        expected = np.concatenate([np.linalg.eigvals(fm.Ad - fm.Bd @ lqg._Ke[None, :]),
                                   np.linalg.eigvals(fm.Ad - fm.Ad @ lqg.L @ fm.C_sensors)])
        np.testing.assert_allclose(_sorted(_closed_by_name(plant_f, ctrl).poles()), _sorted(expected), atol=1e-9)


def test_export_bad_input(controllers, design, tmp_path):
    with pytest.raises(ParameterError, match="unknown extension"):
        save_controller(controllers["lqr"], tmp_path / "k.txt")
    with pytest.raises(HubbeamError, match="not a linear"):
        save_controller(MPC(design, MPCSettings(horizon=5)), tmp_path / "k.npz")
    plant = save_model(design.linear_model, tmp_path / "plant.json")
    with pytest.raises(ParameterError, match="not a hubbeam controller file"):
        load_controller(plant)
    with pytest.raises(ParameterError, match="does not exist"):
        load_controller(tmp_path / "none.mat")
