"""Controllers: design checks, bad settings, MPC against LQR and against a second QP solver."""

import math

import numpy as np
import pytest

from controllers import (
    LQG,
    LQR,
    MPC,
    PD,
    DesignModel,
    LQGSettings,
    LQRSettings,
    MPCSettings,
    OpenLoop,
    OpenLoopSettings,
    PDSettings,
    Reference,
    Weights,
    condensed_matrices,
    dlqr_gain,
    make_controller,
    pd_gains,
    slew_reference,
    spinup_reference,
)
from controllers.reference import slew_shape_constant
from hubbeam_ctrl import Params
from hubbeam_ctrl.core.errors import ParameterError

P2 = Params(n_axial=2, n_transverse=2)


@pytest.fixture(scope="module")
def design():
    return DesignModel.build(P2, 0.0, 0.01)


def test_design_model_shapes_and_rigid_mode(design):
    assert design.n_x == 6 and design.n_modes == 2
    assert design.state_names == ["theta", "q2_1", "q2_2", "theta_dot", "q2_dot_1", "q2_dot_2"]
    # the rigid-body mode: a double eigenvalue 1 of Ad; undamped flexible modes on |z| = 1
    z = np.linalg.eigvals(design.Ad)
    assert np.sum(np.abs(z - 1) < 1e-6) == 2
    assert np.allclose(np.abs(z), 1.0)
    assert design.inertia == pytest.approx(P2.total_inertia)
    # sensors: theta, theta_dot, root moment
    assert design.C_sensors[0, 0] == 1 and design.C_sensors[1, 3] == 1
    assert abs(design.C_tip[0, 1]) == pytest.approx(2.0)     # |f2_i(L)| = 2
    # a steady rotation stays a solution of the linear model at spin 3 (what the
    # controllers rely on to work in absolute coordinates)
    d3 = DesignModel.build(P2, 3.0, 0.01)
    assert np.allclose(d3.A @ np.r_[0, 0, 0, 1, 0, 0], np.r_[1, 0, 0, 0, 0, 0], atol=1e-9)


def test_lqr_stabilises_the_design_model(design):
    K, P = dlqr_gain(design, Weights())
    rho = max(abs(np.linalg.eigvals(design.Ad - design.Bd @ K[None, :])))
    assert rho < 1
    assert np.all(np.linalg.eigvalsh(P) > 0)


def test_pd_gains_helper():
    kp, kd = pd_gains(2.0, 0.5, 100.0)
    assert (kp, kd) == pytest.approx((400.0, 200.0))
    ctrl = PD(DesignModel.build(P2, 0.0, 0.01), PDSettings(kp=10.0, kd=1.0, feedforward=False))
    assert ctrl(0.0, np.array([-1.0, 0.5, 0.0])) == pytest.approx(10.0 - 0.5)
    assert ctrl(0.0, np.array([-100.0, 0.0, 0.0])) == 200.0         # saturated


def test_openloop_is_eq44(design):
    ol = OpenLoop(design, OpenLoopSettings(tau_m=150.0, t_f=8.0))
    assert ol(2.0, None) == pytest.approx(150.0)
    assert ol(6.0, None) == pytest.approx(-150.0)
    assert ol(8.5, None) == 0.0


def test_slew_reference_is_rest_to_rest_within_budget():
    J = P2.total_inertia
    ref = slew_reference(2.0, 10.0, J, 200.0, 0.01, 15.0)
    assert ref.theta[-1] == pytest.approx(2.0, abs=1e-9)
    assert ref.theta_dot[1000:] == pytest.approx(0.0, abs=1e-9)
    assert np.max(np.abs(ref.torque)) < 200.0
    # consistency: the feedforward integrates to the rate
    assert np.cumsum(ref.torque / J)[-1] * 0.01 == pytest.approx(0.0, abs=1e-3)
    assert slew_shape_constant(0.0) == pytest.approx(1 / (2 * math.pi), rel=1e-6)
    # the Eq. 44 rigid angle in 10 s needs 75 % of the budget with the default shape
    theta = 200 * 100 / (2 * math.pi * J)
    ref = slew_reference(theta, 10.0, J, 200.0, 0.01, 15.0)
    assert np.max(np.abs(ref.torque)) == pytest.approx(0.749 * 200, rel=0.01)
    with pytest.raises(ParameterError, match="tau_max"):
        slew_reference(theta, 10.0, J, 100.0, 0.01, 15.0)
    with pytest.raises(ParameterError, match="tau_max"):
        spinup_reference(3.0, 2.0, J, 0.01, 10.0, tau_max=200.0)
    sp = spinup_reference(3.0, 10.0, J, 0.01, 12.0)
    assert sp.theta_dot[-1] == pytest.approx(3.0)
    assert np.max(sp.torque) == pytest.approx(2 * J * 3.0 / 10.0, rel=1e-3)


def test_reference_extends_beyond_its_end():
    ref = Reference.from_profile(lambda t: (2 * t, 2 + 0 * t, 0 * t, 0 * t), 0.1, 1.0)
    th, thd, tau = ref.window(9, 4)
    assert th == pytest.approx([1.8, 2.0, 2.2, 2.4])
    assert thd == pytest.approx([2.0] * 4)


@pytest.mark.parametrize("factory, match", [
    (lambda: Weights(angle=-1.0), "weights.angle"),
    (lambda: Weights(torque=0.0), "weights.torque"),
    (lambda: Weights(tip_rate=float("nan")), "weights.tip_rate"),
    (lambda: LQRSettings(tau_max=0.0), "tau_max"),
    (lambda: LQGSettings(tau_max=-5.0), "tau_max"),
    (lambda: LQGSettings(rate_noise_rad_s=0.0), "rate_noise_rad_s"),
    (lambda: MPCSettings(horizon=0), "horizon"),
    (lambda: MPCSettings(horizon=2.5), "horizon"),
    (lambda: MPCSettings(tau_max=0.0), "tau_max"),
    (lambda: MPCSettings(tip_bound=-0.1), "tip_bound"),
    (lambda: MPCSettings(solver="nope"), "solver"),
    (lambda: PDSettings(tau_max=-1.0), "tau_max"),
    (lambda: PDSettings(bandwidth=0.0), "bandwidth"),
    (lambda: OpenLoopSettings(tau_m=0.0), "tau_m"),
    (lambda: DesignModel.build(P2, 0.0, 0.0), "dt"),
    (lambda: DesignModel.build(P2, 0.0, -0.01), "dt"),
])
def test_bad_settings_name_the_setting(factory, match):
    with pytest.raises(ParameterError, match=match):
        factory()


def test_weights_not_psd_are_rejected(design):
    Q = np.eye(6)
    Q[1, 1] = -1.0
    with pytest.raises(ParameterError, match="state_matrix.*positive semidefinite"):
        LQR(design, LQRSettings(weights=Weights(state_matrix=Q)))
    with pytest.raises(ParameterError, match="state_matrix.*symmetric"):
        LQR(design, LQRSettings(weights=Weights(state_matrix=np.triu(np.ones((6, 6))))))
    with pytest.raises(ParameterError, match="state_matrix"):
        MPC(design, MPCSettings(weights=Weights(state_matrix=np.eye(3))))
    # PSD but not detectable: no weight at all leaves the rigid-body mode unstable
    Q0 = np.zeros((6, 6))
    with pytest.raises(ParameterError, match="weights"):
        LQR(design, LQRSettings(weights=Weights(state_matrix=Q0)))


def test_unconstrained_mpc_first_move_equals_lqr(design):
    """With the LQR Riccati solution as terminal weight and inactive bounds, the MPC's
    first move is the LQR's."""
    lqr = LQR(design)
    mpc = MPC(design, MPCSettings(horizon=20))
    rng = np.random.default_rng(1)
    for _ in range(3):
        y = rng.normal(size=6) * np.r_[1e-3, 1e-4, 1e-5, 1e-3, 1e-4, 1e-5]
        mpc.reset()
        u_lqr = lqr(0.0, y)
        u_mpc = mpc(0.0, y)
        assert abs(u_lqr) < 200
        assert u_mpc == pytest.approx(u_lqr, rel=1e-5, abs=1e-8)


def test_mpc_saturates_and_agrees_with_second_solver(design):
    y = np.r_[-0.5, 0, 0, 0, 0, 0]          # far behind: the plan saturates
    plans = {}
    for solver in ("daqp", "qpoases"):
        mpc = MPC(design, MPCSettings(horizon=30, solver=solver, tau_max=50.0))
        plans[solver] = mpc.plan(0.0, y)
        assert mpc(0.0, y) == pytest.approx(50.0)
    assert np.max(np.abs(plans["daqp"] - plans["qpoases"])) < 1e-5 * 50
    assert np.all(np.abs(plans["daqp"]) <= 50.0 + 1e-9)


def test_mpc_soft_tip_bound_limits_predicted_deflection(design):
    y = np.r_[-0.5, 0, 0, 0, 0, 0]
    free = MPC(design, MPCSettings(horizon=40))
    soft = MPC(design, MPCSettings(horizon=40, tip_bound=1e-3, tip_bound_weight=1e12))
    Phi, Gamma = condensed_matrices(design.Ad, design.Bd, 40)
    Ct = np.kron(np.eye(40), design.C_tip[:1])

    def peak_tip(u):
        return np.max(np.abs(Ct @ (Phi @ y + Gamma @ u)))

    assert peak_tip(soft.plan(0.0, y)) < 0.5 * peak_tip(free.plan(0.0, y))
    assert peak_tip(soft.plan(0.0, y)) < 2e-3


def test_mpc_falls_back_to_saturated_lqr_when_the_qp_fails(design):
    mpc = MPC(design, MPCSettings(horizon=10, tau_max=30.0))
    lqr = LQR(design, LQRSettings(tau_max=30.0))

    def failing(**kwargs):
        raise RuntimeError("solver broke")

    mpc.plan = lambda t, y: failing()
    y = np.r_[-0.01, 0, 0, 0, 0, 0]
    assert mpc(0.0, y) == pytest.approx(lqr(0.0, y))
    y = np.r_[-10.0, 0, 0, 0, 0, 0]
    assert mpc(0.01, y) == 30.0
    st = mpc.stats()
    assert st["qp_fallbacks"] == 2 and st["qp_solves"] == 2 and st["fallback_fraction"] == 1.0


def test_kalman_filter_converges_on_the_design_model(design):
    """LQG's estimate converges to the true state of the linear model (no noise); the
    filter on the design model alone (``robust=False``)."""
    ctrl = LQG(design, LQGSettings(robust=False))
    ctrl.reset()
    x = np.r_[0.01, 0.02, -0.003, 0.0, 0.01, 0.0]
    err0 = np.max(np.abs(ctrl.x_pred - x))
    for k in range(2500):
        y = design.C_sensors @ x
        tau = ctrl(k * design.dt, y)
        x = design.Ad @ x + design.Bd[:, 0] * tau
    assert np.max(np.abs(ctrl.x_pred - x)) < 1e-8 * err0
    assert np.max(np.abs(x)) < 1e-4         # and the loop regulated it


def test_controllers_share_one_interface(design):
    ref = slew_reference(0.5, 5.0, P2.total_inertia, 200.0, 0.01, 8.0)
    for name in ("openloop", "pd", "lqr", "lqg", "mpc"):
        c = make_controller(name, design, None, ref)
        assert c.dt == 0.01 and c.measurement in ("state", "sensors")
        c.reset()
        y = np.zeros(3 if c.measurement == "sensors" else 6)
        tau = c(0.0, y)
        assert isinstance(tau, float) and math.isfinite(tau) and abs(tau) <= 200.0
        assert isinstance(c.stats(), dict)
    with pytest.raises(ParameterError, match="unknown controller"):
        make_controller("pid", design)
    with pytest.raises(ParameterError, match="reference.dt"):
        LQR(design, reference=slew_reference(0.5, 5.0, P2.total_inertia, 200.0, 0.02, 8.0))
