"""The Kalman estimator component and the python-control designs behind LQR and LQG, against
independent SciPy references; LQG = LQR gain + estimator."""

import control
import numpy as np
import pytest
import scipy.linalg

from controllers import LQG, DesignModel, KalmanEstimator, KalmanNoise, LQGSettings, Weights, dlqr_gain, kalman_gain
from controllers.residual import embedding, estimator_modes
from hubbeam_ctrl import Params
from hubbeam_ctrl.core.errors import ParameterError

P2 = Params(n_axial=2, n_transverse=2)


@pytest.fixture(scope="module", params=[0.0, 3.0], ids=["rest", "spin3"])
def design(request):
    return DesignModel.build(P2, request.param, 0.01)


def test_dlqr_gain_is_the_riccati_optimum(design):
    Q, R = Weights().matrices(design)
    A, B = design.Ad, design.Bd
    P_ref = scipy.linalg.solve_discrete_are(A, B, Q, R)
    K_ref = np.linalg.solve(R + B.T @ P_ref @ B, B.T @ P_ref @ A).ravel()
    K, P = dlqr_gain(design, Weights())
    assert np.allclose(K, K_ref, rtol=1e-10, atol=0) and np.allclose(P, P_ref, rtol=1e-10, atol=0)


def test_kalman_gain_is_the_measurement_update_of_dlqe(design):
    """control.dlqe gives the predictor gain A P C' S^-1; the filter corrects the current
    estimate with P C' S^-1, its A^-1 multiple (why that one line is written here). The plain
    filter (error_decay=0); the default's prescribed decay is checked in test_filter_decay.py."""
    noise = KalmanNoise(error_decay=0.0)
    A, C = design.Ad, design.C_sensors
    Qn, Rn = noise.covariances(design)
    P_ref = scipy.linalg.solve_discrete_are(A.T, C.T, Qn, Rn)
    L_ref = P_ref @ C.T @ np.linalg.inv(C @ P_ref @ C.T + Rn)
    est = KalmanEstimator(design, noise)
    assert np.allclose(est.L, L_ref, rtol=1e-9, atol=1e-12 * np.abs(L_ref).max())
    assert np.allclose(est.P, P_ref, rtol=1e-9, atol=1e-12 * np.abs(P_ref).max())
    L_pred, _, _ = control.dlqe(A, np.eye(design.n_x), C, Qn, Rn, method="scipy")
    assert np.allclose(L_pred, A @ est.L, rtol=1e-9, atol=1e-12 * np.abs(L_pred).max())
    assert np.array_equal(kalman_gain(design, noise), est.L)
    # the error dynamics x_pred -> (I - L C) A x_pred are stable
    assert np.max(np.abs(np.linalg.eigvals((np.eye(design.n_x) - est.L @ C) @ A))) < 1


def test_covariances_follow_the_noise_settings(design):
    noise = KalmanNoise(angle_noise_rad=2e-4, rate_noise_rad_s=3e-3, moment_noise_nm=0.5,
                        torque_noise_nm=2.0, modal_noise=1e-3)
    Qn, Rn = noise.covariances(design)
    assert np.allclose(np.diag(Rn), [4e-8, 9e-6, 0.25]) and np.count_nonzero(Rn - np.diag(np.diag(Rn))) == 0
    b = design.Bd[:, 0]
    expect = 4.0 * np.outer(b, b) + 1e-6 * np.diag([0, 1, 1, 0, 1, 1])
    assert np.allclose(Qn, expect, rtol=1e-12, atol=0)


def test_estimator_update_is_predict_then_correct(design):
    est = KalmanEstimator(design, KalmanNoise())
    x0 = np.r_[0.1, 0.0, 0.0, 0.2, 0.0, 0.0]
    est.reset(x0)
    y = np.r_[0.11, 0.19, 0.3]
    first = est.update(y, None)           # no prediction on the first sample
    assert np.allclose(first, x0 + est.L @ (y - design.C_sensors @ x0), rtol=1e-14, atol=1e-15)
    pred = design.Ad @ first + design.Bd[:, 0] * 7.0
    assert np.allclose(est.predict(7.0), pred, rtol=1e-14, atol=1e-15)
    second = est.update(y, 7.0)
    assert np.allclose(est.x_pred, pred, rtol=1e-14, atol=1e-15)
    assert np.allclose(second, pred + est.L @ (y - design.C_sensors @ pred), rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("robust", [True, False])
def test_lqg_is_the_lqr_gain_on_the_estimator(design, robust):
    """LQG's torque is sat(tau_ff - K (x_hat - x_ref)) with x_hat from a standalone estimator fed
    the same measurements (in deviation coordinates) and the torques LQG applied; with ``robust``
    the estimator runs on the design model with residual modes and K is zero on them."""
    ctrl = LQG(design, LQGSettings(tau_max=50.0, robust=robust))
    K, _ = dlqr_gain(design, Weights())
    assert np.array_equal(ctrl.K, K) and ctrl.L is ctrl.estimator.L
    model = ctrl.filter_model
    assert (model.n_modes == estimator_modes(design)) if robust else (model is design)
    est = KalmanEstimator(model, LQGSettings(), design.n_modes)   # residual modes' noise scaled
    Ke = K @ embedding(design.n_modes, model.n_modes).T
    ctrl.reset()
    est.reset(ctrl.x_hat)
    rng = np.random.default_rng(4)
    w, n, tau = design.spin, model.n_x // 2, None
    for k in range(50):
        t = k * design.dt
        y = np.r_[w * t, w, 0.0] + rng.normal(size=3) * [1e-3, 1e-2, 1.0]
        x_hat = est.update(y - np.r_[w * t, w, 0.0], tau)
        x_abs = x_hat.copy()
        x_abs[0] += w * t
        x_abs[n] += w
        expect = float(np.clip(-Ke @ x_abs, -50.0, 50.0))      # rest reference, no feedforward
        tau = ctrl(t, y)
        assert tau == pytest.approx(expect, rel=1e-10, abs=1e-9)
        assert np.allclose(ctrl.x_hat, x_hat, rtol=0, atol=1e-14)
    assert np.allclose(ctrl.x_pred, est.predict(tau), rtol=0, atol=1e-14)


def test_bad_noise_model_is_refused(design):
    with pytest.raises(ParameterError, match="noise must be a KalmanNoise"):
        KalmanEstimator(design, Weights())
    with pytest.raises(ParameterError, match="torque_noise_nm must be > 0"):
        KalmanNoise(torque_noise_nm=0.0)


def test_model_error_adds_to_the_process_noise(design):
    """``model_error`` is added to Qn as given; a wrong shape or an indefinite matrix is refused."""
    extra = np.diag(np.arange(1.0, design.n_x + 1)) * 1e-6
    Qn0, Rn0 = KalmanNoise().covariances(design)
    Qn, Rn = KalmanNoise(model_error=extra).covariances(design)
    assert np.array_equal(Qn - Qn0, extra) and np.array_equal(Rn, Rn0)
    with pytest.raises(ParameterError, match=f"model_error must be a finite {design.n_x} x {design.n_x} matrix"):
        KalmanNoise(model_error=np.eye(design.n_x + 2)).covariances(design)
    with pytest.raises(ParameterError, match="model_error must be positive semidefinite"):
        KalmanNoise(model_error=-np.eye(design.n_x)).covariances(design)
