"""Closed-loop simulator: the fixed-step plant stepper against IDAS, and the sampling loop."""

import math

import numpy as np
import pytest

from hubbeam_ctrl import Params, TorquePulse, build_model, simulate
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.sensors import SensorSettings, sensor_matrix
from hubbeam_ctrl.sim import (
    ClosedLoopSettings,
    PlantStepper,
    StepperSettings,
    generalized_alpha_coefficients,
    load_result,
    simulate_closed_loop,
    simulate_fixed_step,
)


@pytest.mark.slow
def test_stepper_matches_tight_idas_on_foam():
    """The generalized-alpha stepper (2 x 5 ms per 10 ms sample) reproduces a tight IDAS
    run of the Eq. 44 slew: tip deflection within 0.5 % of the peak at every sample (the pulse
    and 5 s of free vibration after it; the 30 s run measured the same 0.035 %)."""
    ref = simulate("foam", TorquePulse(200, 10), 15, rtol=1e-10, atol=1e-10, max_order=5)
    fix = simulate_fixed_step("foam", TorquePulse(200, 10), 15)
    peak = np.max(np.abs(ref.v_tip))
    assert fix.v_tip.shape == ref.v_tip.shape
    err = np.max(np.abs(fix.v_tip - ref.v_tip)) / peak
    print(f"FOAM stepper: max tip error {100 * err:.4f} % of peak {peak:.4f} m, "
          f"{fix.stats['ms_per_step']:.3f} ms/step")
    assert err < 5e-3
    assert err < 1e-3          # measured 0.035 %
    # hub angle too
    assert np.max(np.abs(fix.q[:, 0] - ref.theta)) < 1e-3 * np.max(np.abs(ref.theta))


def test_stepper_matches_idas_on_cfoam():
    ref = simulate("cfoam", TorquePulse(200, 10), 30)
    fix = simulate_fixed_step("cfoam", TorquePulse(200, 10), 30)
    peak = np.max(np.abs(ref.v_tip))
    err = np.max(np.abs(fix.v_tip - ref.v_tip)) / peak
    print(f"CFOAM stepper: max tip error {100 * err:.4f} % of peak, {fix.stats['ms_per_step']:.3f} ms/step, "
          f"{fix.stats['jacobian_updates']} iteration-matrix updates, {fix.stats['fallbacks']} fallbacks")
    assert err < 5e-3
    assert fix.stats["fallbacks"] == 0


def test_run_is_step_after_step():
    """PlantStepper.run (the open-loop loop without per-call copies) takes every sample exactly
    as step does, iteration-matrix refreshes included."""
    model = build_model("foam", Params(n_axial=2, n_transverse=3))
    taus = 150.0 * np.sin(np.linspace(0, np.pi, 400))[:, None] * np.ones((1, 2))
    a, b = PlantStepper(model), PlantStepper(model)
    s = a.initial_state()
    stepped = []
    for row in taus:
        s = a.step(s, row)
        stepped.append(s)
    np.testing.assert_array_equal(b.run(b.initial_state(), taus), np.array(stepped))
    assert a.jacobian_updates == b.jacobian_updates > 1


def test_closed_loop_on_quasi_static_axial_plant():
    """A plant with its axial modes condensed out runs in the closed loop like any other and
    follows the dynamic plant (measured 6.6e-6 of the peak over a 20 s torque pulse)."""
    class Pulse:
        measurement = "state"

        def reset(self):
            pass

        def __call__(self, t, y):
            return 50.0 * math.sin(math.pi * t / 5.0) if t < 5.0 else 0.0

    runs = {axial: simulate_closed_loop(build_model("foam", Params(), axial), Pulse(), 20.0)
            for axial in ("dynamic", "quasi-static")}
    dyn, qs = runs["dynamic"], runs["quasi-static"]
    assert qs.q.shape[1] == 1 + Params().n_transverse and not qs.stopped
    peak = np.max(np.abs(dyn.v_tip))
    assert peak > 0.1
    assert np.max(np.abs(qs.v_tip - dyn.v_tip)) < 1e-4 * peak
    assert np.max(np.abs(qs.u_tip - dyn.u_tip)) < 1e-3 * np.max(np.abs(dyn.u_tip))


def test_generalized_alpha_coefficients():
    am, af, gamma, beta = generalized_alpha_coefficients(1.0)
    assert (am, af, gamma, beta) == pytest.approx((0.5, 0.5, 0.5, 0.25))
    am, af, gamma, beta = generalized_alpha_coefficients(0.9)
    assert gamma == pytest.approx(0.5 + af - am)
    assert beta == pytest.approx(0.25 * (gamma + 0.5) ** 2)


def test_stepper_conserves_energy_free_plant():
    """Unforced FOAM from a deflected state: energy and momentum nearly constant."""
    p = Params(n_axial=2, n_transverse=2)
    m = build_model("foam", p)
    x0 = np.zeros(2 * m.n_q)
    x0[m.n_q] = 1.0                       # spinning at 1 rad/s
    x0[m.transverse_slice.start] = 0.05    # deflected
    fix = simulate_fixed_step(m, lambda t: 0 * t, 5.0, x0=x0,
                              settings=StepperSettings(rho_inf=1.0, substeps=4))
    E = np.array([m.energy(q, v) for q, v in zip(fix.q, fix.v)])
    H = np.array([m.angular_momentum(q, v) for q, v in zip(fix.q, fix.v)])
    assert np.ptp(E) / abs(E[0]) < 1e-3
    assert np.ptp(H) / abs(H[0]) < 1e-3


class _Recorder:
    name = "recorder"
    measurement = "state"

    def __init__(self, tau=10.0, n_modes=None, kind="state"):
        self.tau, self.n_modes, self.measurement = tau, n_modes, kind
        self.seen = []

    def reset(self):
        self.seen = []

    def __call__(self, t, y):
        self.seen.append((t, np.array(y)))
        return self.tau


def test_state_measurement_is_sfoam_ordered():
    p = Params(n_axial=2, n_transverse=3)
    ctrl = _Recorder(50.0, n_modes=2)
    res = simulate_closed_loop("foam", ctrl, 1.0, params=p)
    assert not res.stopped and len(res.t) == 101
    t, y = ctrl.seen[60]
    k = 60
    assert t == pytest.approx(0.6)
    m = build_model("foam", p)
    q, v = res.q[k], res.v[k]
    expect = np.r_[q[0], q[m.transverse_slice][:2], v[0], v[m.transverse_slice][:2]]
    assert np.allclose(y, expect)
    assert np.all(res.tau == 50.0)
    # 50 N m for 1 s turns the hub by about tau t^2 / (2 J), a little more at first
    # (the flexible beam lags behind the hub)
    assert res.theta[-1] == pytest.approx(50 / (2 * p.total_inertia), rel=0.15)


def test_sensor_measurement_has_stated_noise():
    p = Params(n_axial=2, n_transverse=2)
    ctrl = _Recorder(0.0, kind="sensors")
    sens = SensorSettings(angle_noise_rad=1e-3, rate_noise_rad_s=2e-3, moment_noise_nm=0.5, seed=3)
    simulate_closed_loop("foam", ctrl, 20.0, params=p, settings=ClosedLoopSettings(sensors=sens))
    Y = np.array([y for _, y in ctrl.seen])
    assert Y.shape == (2001, 3)
    assert np.std(Y, axis=0) == pytest.approx([1e-3, 2e-3, 0.5], rel=0.1)   # plant at rest
    C = sensor_matrix(p, 2, 2)
    assert C.shape == (3, 10)
    assert np.allclose(C[2, 3:5], p.EI * build_model("foam", p).basis.f2pp_root)


def test_nan_controller_stops_the_run_naming_it():
    class Bad(_Recorder):
        name = "broken-ctrl"

        def __call__(self, t, y):
            return float("nan") if t >= 0.5 else 1.0

    res = simulate_closed_loop("foam", Bad(), 2.0, params=Params(n_axial=1, n_transverse=1))
    assert res.stopped
    assert "broken-ctrl" in res.message and "non-finite" in res.message
    assert res.t[-1] == pytest.approx(0.5)
    assert len(res.t) == len(res.tau) == len(res.v_tip)


def test_bad_closed_loop_inputs():
    p = Params(n_axial=1, n_transverse=1)
    with pytest.raises(ParameterError, match="dt"):
        ClosedLoopSettings(dt=0.0)
    with pytest.raises(ParameterError, match="dt"):
        StepperSettings(dt=-0.01)
    with pytest.raises(ParameterError, match="substeps"):
        ClosedLoopSettings(substeps=0)
    with pytest.raises(ParameterError, match="rho_inf"):
        StepperSettings(rho_inf=1.5)
    with pytest.raises(ParameterError, match="angle_noise_rad"):
        SensorSettings(angle_noise_rad=-1)
    with pytest.raises(ParameterError, match="t_end"):
        simulate_closed_loop("foam", _Recorder(), 0.0, params=p)
    ctrl = _Recorder()
    ctrl.dt = 0.02
    with pytest.raises(ParameterError, match="dt"):
        simulate_closed_loop("foam", ctrl, 1.0, params=p)
    with pytest.raises(ParameterError, match="modes"):
        simulate_closed_loop("foam", _Recorder(n_modes=3), 1.0, params=p)
    with pytest.raises(ParameterError, match="callable"):
        simulate_closed_loop("foam", object(), 1.0, params=p)


def test_stepper_speed_is_reported():
    """Per-sample cost of the compiled stepper (printed; loose bound for a loaded machine)."""
    import time
    for name in ("foam", "cfoam"):
        st = PlantStepper(build_model(name))
        s = st.initial_state()
        st.step(s, 100.0)
        t0 = time.perf_counter()
        for _ in range(300):
            s = st.step(s, 100.0)
        ms = (time.perf_counter() - t0) / 300 * 1e3
        print(f"{name}: {ms:.3f} ms per 10 ms sample")
        assert ms < 5.0
        assert math.isfinite(s[0])


def test_stopped_run_metrics_and_save(tmp_path):
    from hubbeam_ctrl.study.metrics import closed_loop_metrics

    class Bad(_Recorder):
        name = "nan-at-3s"

        def __call__(self, t, y):
            return float("nan") if t >= 3.0 else 5.0

    p = Params(n_axial=1, n_transverse=1)
    ref = (lambda t: 0 * t, lambda t: 0 * t)
    res = simulate_closed_loop("foam", Bad(), 20.0, params=p, reference=ref)
    m = closed_loop_metrics(res, 10.0, tau_max=10.0)
    assert not m["completed"] and "nan-at-3s" in m["message"]
    assert math.isnan(m["residual_tip_max_m"])          # the run never reached 15 s
    assert m["peak_torque_nm"] == 5.0 and m["within_torque_limit"]
    path = res.save(tmp_path / "run.npz")
    with np.load(path) as data:
        assert np.array_equal(data["t"], res.t)
        assert "nan-at-3s" in str(data["metadata"])
    back = load_result(path)
    assert back == res and back.stopped and back.controller == "nan-at-3s"
    assert np.isnan(back.tau[-1]) and back.tau[-2] == 5.0
    with pytest.raises(ParameterError, match="t_end"):
        closed_loop_metrics(res, 16.0)
