"""The LQG's filter predicts along a planned reference (LQGSettings.plan_prediction, issue 22).

An optimal slew is planned on the nonlinear model; the filter's linear model disagrees with
it along the way. Predicting ``x_ref[k+1] + A (x_hat - x_ref[k]) + B (u - u_ff[k])`` keeps
that disagreement out of the estimate: a plant that follows the plan exactly is estimated
exactly, and the LQG then commands exactly the plan's torque.
"""

import numpy as np
import pytest

from controllers import LQG, DesignModel, LQGSettings, Reference
from hubbeam_ctrl import Params

DT, N = 0.01, 150


@pytest.fixture(scope="module")
def plan():
    """A 1.5 s slew by 0.2 rad whose planned bending (two modes, 2 mm and 0.5 mm bumps) is not
    the linear model's response to its torque."""
    d = DesignModel.build(Params(n_transverse=2), 0.0, DT)
    t = np.arange(N + 1) * DT
    T = N * DT
    w = 2 * np.pi / T
    theta = 0.2 * (t / T - np.sin(w * t) / (2 * np.pi))
    theta_dot = 0.2 / T * (1 - np.cos(w * t))
    theta_ddot = 0.2 / T * w * np.sin(w * t)
    torque = d.inertia * theta_ddot
    s = np.sin(np.pi * t / T)
    ds = np.pi / T * np.cos(np.pi * t / T)
    q = np.column_stack([2e-3 * s ** 2, 5e-4 * s ** 3])
    qd = np.column_stack([4e-3 * s * ds, 1.5e-3 * s ** 2 * ds])
    ref = Reference(DT, theta, theta_dot, theta_ddot, torque, "planned slew", elastic=np.hstack([q, qd]))
    return d, ref


def _run(ctrl, states):
    """Feed the sensors of ``states`` (filter model) to ``ctrl``; torques and estimate errors."""
    fm = ctrl.filter_model
    taus, errs = [], []
    for k, x in enumerate(states):
        taus.append(ctrl(k * DT, fm.C_sensors @ x))
        errs.append(np.max(np.abs(ctrl.x_hat - x)))
    return np.array(taus), np.array(errs)


def test_a_plant_on_the_plan_gets_the_plans_torque(plan):
    d, ref = plan
    ctrl = LQG(d, LQGSettings(), ref)
    assert ctrl.predicts_along_plan and ctrl.filter_model.n_modes > d.n_modes
    states = ctrl.filter_model.reference_states(ref)        # the planned modes, residual ones at rest
    assert np.max(np.abs(states[:, 1:3])) > 1e-3
    taus, errs = _run(ctrl, states)
    scale = np.max(np.abs(ref.torque))
    assert np.max(np.abs(taus - ref.torque)) <= 1e-9 * scale
    assert np.max(errs) <= 1e-9 * np.max(np.abs(states))
    # predicting with the model alone, the same plant is misread and the torque leaves the plan
    plain = LQG(d, LQGSettings(plan_prediction=False), ref)
    assert not plain.predicts_along_plan
    taus0, errs0 = _run(plain, states)
    assert np.max(np.abs(taus0 - ref.torque)) > 1e-2 * scale and np.max(errs0) > 1e-5


def test_plan_prediction_needs_a_plan(plan):
    d, ref = plan
    assert not LQG(d).predicts_along_plan                                  # rest: no plan
    task = Reference(ref.dt, ref.theta, ref.theta_dot, ref.theta_ddot, ref.torque, "smooth slew")
    assert not LQG(d, reference=task).predicts_along_plan                  # quasi-static deflection
    assert not LQG(d, LQGSettings(elastic_reference=False), ref).predicts_along_plan
    assert LQG(d, LQGSettings(plan_prediction=True), task).predicts_along_plan


def test_generated_c_predicts_along_the_plan_too(plan, tmp_path):
    """The C step of the LQG and of the rig's observer-fed LQR (integral action) carries the plan's
    offsets: its command equals Python's within 1e-9 of tau_max on random sensor values, past
    the table's end too; skipped without a C compiler."""
    from controllers import LQR, KalmanNoise
    from controllers.integral import ObservedFeedback
    from hubbeam_ctrl.core.compiled import CompileError
    from hubbeam_ctrl.deploy import CController, compile_c, to_c
    d, ref = plan
    rng = np.random.default_rng(5)
    for name, ctrl in (("lqg", LQG(d, LQGSettings(), ref)),
                       ("lqr", ObservedFeedback(LQR(d, reference=ref), KalmanNoise(), 0.01))):
        assert ctrl.predicts_along_plan
        code = to_c(ctrl, tmp_path / name)
        assert "OFFSET" in code.law.arrays
        try:
            lib = compile_c(code, "-O0", tmp_path)
        except CompileError as exc:
            pytest.skip(f"no C compiler: {exc}")
        cc = CController(lib, code, ctrl)
        ctrl.reset()
        cc.reset()
        worst = 0.0
        for k in range(N + 20):
            y = np.array([0.2 * k / N + 1e-3 * rng.standard_normal(), 0.1 * rng.standard_normal(),
                          rng.standard_normal()])
            worst = max(worst, abs(cc(k * DT, y) - ctrl(k * DT, y)))
        assert worst <= 1e-9 * ctrl.tau_max, name


@pytest.mark.parametrize("integral", [False, True], ids=["plain", "integral"])
def test_observed_lqr_follows_the_plan_too(plan, integral):
    """LQR and MPC on a rig close their loop through ObservedFeedback's filter: the same."""
    from controllers import LQR, KalmanNoise
    from controllers.integral import ObservedFeedback
    d, ref = plan
    noise = 0.01 if integral else None
    ctrl = ObservedFeedback(LQR(d, reference=ref), KalmanNoise(), noise)
    assert ctrl.predicts_along_plan
    states = ctrl.filter_model.reference_states(ref)
    taus, _ = _run_observed(ctrl, states)
    scale = np.max(np.abs(ref.torque))
    assert np.max(np.abs(taus - ref.torque)) <= 1e-9 * scale
    plain = ObservedFeedback(LQR(d, reference=ref), KalmanNoise(), noise, plan_prediction=False)
    taus0, _ = _run_observed(plain, states)
    assert np.max(np.abs(taus0 - ref.torque)) > 1e-2 * scale


def _run_observed(ctrl, states):
    fm = ctrl.filter_model
    taus = [ctrl(k * DT, fm.C_sensors @ x) for k, x in enumerate(states)]
    return np.array(taus), None


def test_a_plan_of_the_design_model_itself_is_not_predicted_along_by_default(plan):
    """A reference planned on the design model (controllers.planning) is what the filter's own
    prediction follows: LQG and the observer-fed LQR do not predict along it unless asked."""
    import dataclasses

    from controllers import LQR
    from controllers.integral import ObservedFeedback
    d, ref = plan
    own = dataclasses.replace(ref, planned_on_design=True)
    assert LQG(d, reference=ref).predicts_along_plan
    assert not LQG(d, reference=own).predicts_along_plan
    assert LQG(d, LQGSettings(plan_prediction=True), own).predicts_along_plan
    assert not ObservedFeedback(LQR(d, reference=own), LQGSettings()).predicts_along_plan
    assert ObservedFeedback(LQR(d, reference=ref), LQGSettings()).predicts_along_plan
