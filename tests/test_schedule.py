"""Gain scheduling over the spin rate: schedule, scheduled LQR/LQG/MPC, python-control systems, targets."""

import control as ct
import numpy as np
import pytest

from controllers import (
    CONTROLLERS,
    LQG,
    LQR,
    DesignModel,
    DesignSchedule,
    LQGSettings,
    MPCSettings,
    ScheduledLQG,
    ScheduledLQR,
    ScheduledMPC,
    Weights,
    dlqr_gain,
    filter_schedule,
    kalman_gain,
    make_controller,
    scheduled_lqg_iosystem,
    scheduled_lqr_iosystem,
    spinup_reference,
)
from controllers.estimator import KalmanEstimator
from controllers.residual import embedding
from hubbeam_ctrl import Params
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.study.compare import compare
from hubbeam_ctrl.study.compare_values import CompareSettings, DesignChoice
from hubbeam_ctrl.study.scenarios import make_scenario

P2 = Params(n_axial=2, n_transverse=2)


@pytest.fixture(scope="module")
def sched():
    return DesignSchedule.build(P2, [0.0, 1.0, 2.5, 3.0], 0.01)


@pytest.fixture(scope="module")
def ref():
    return spinup_reference(3.0, 10.0, P2.total_inertia, 0.01, 15.0)


def test_interpolation_is_linear_in_the_spin_and_clamped(sched):
    table = sched.spins[:, None] * np.array([1.0, -2.0])          # linear data is reproduced
    for w in (0.0, 0.3, 1.0, 1.7, 2.9, 3.0):
        assert np.allclose(sched.interpolate(table, w), [w, -2 * w], atol=1e-14)
    assert np.allclose(sched.interpolate(table, 7.0), [3.0, -6.0])
    assert np.allclose(sched.interpolate(table, float("nan")), [0.0, 0.0])
    assert sched.locate(1.75) == (1, pytest.approx(0.5))


def test_scheduled_gains_at_the_grid_are_the_designs(sched, ref):
    lqr = ScheduledLQR(sched, reference=ref)
    for w, d in zip(sched.spins, sched.designs):
        assert np.allclose(lqr.gain(w), dlqr_gain(d, Weights())[0], rtol=1e-12, atol=0)
    # at the top rate, the scheduled LQR is the fixed design's LQR there (same reference table)
    fixed = LQR(sched.designs[-1], reference=ref)
    x = np.zeros(6)
    x[3] = 3.0
    assert np.allclose(lqr.gain(3.0), fixed.K, rtol=1e-12)
    # the elastic reference uses the model at the reference rate of each sample
    k = 800                                                        # t = 8 s, rate ~ 2.5 rad/s
    w = ref.theta_dot[k]
    g = np.array([np.interp(w, sched.spins, [d.quasi_static_gain[j] for d in sched.designs]) for j in range(2)])
    assert np.allclose(lqr._reference_at(k)[0][1:3], g * ref.theta_ddot[k], rtol=1e-12)


def test_lqr_iosystem_follows_create_statefbk_iosystem(sched):
    gains = [dlqr_gain(d, Weights())[0][None, :] for d in sched.designs]
    d = sched.designs[0]
    sys = ct.ss(d.A, d.B, np.eye(6), 0, states=d.state_names, outputs=d.state_names)   # labels, sizes
    ref_sys, _ = ct.create_statefbk_iosystem(sys, (gains, list(sched.spins)), gainsched_indices=["xd[3]"])
    ours = scheduled_lqr_iosystem(sched)
    rng = np.random.default_rng(1)
    for _ in range(5):
        u = rng.normal(size=13)
        u[3] = rng.uniform(0, 3)                                   # desired rate = scheduling variable
        assert np.allclose(ours.output(0, [], u), ref_sys.output(0, [], u), rtol=1e-10, atol=1e-10)
    # scheduled on the measured rate, clipped, equal to the controller class
    meas = scheduled_lqr_iosystem(sched, tau_max=200.0, gainsched_indices="theta_dot")
    ctrl = ScheduledLQR(sched, reference=None)
    x = np.array([0.01, 0.002, -0.001, 1.3, 0.0, 0.01])
    u = np.concatenate([np.zeros(6), [0.0], x])
    assert meas.output(0, [], u)[0] == pytest.approx(ctrl(0.0, x), rel=1e-12)


def test_lqg_iosystem_matches_the_controller(sched, ref):
    settings = LQGSettings()
    ctrl = ScheduledLQG(sched, settings, ref, variable="measured")
    sys = scheduled_lqg_iosystem(sched, settings, gainsched_indices="y[theta_dot]")
    ctrl.reset()
    xs = ctrl.x_pred.copy()
    rng = np.random.default_rng(2)
    for k in range(40):
        xr, tff = ctrl._reference_at(k)
        y = np.array([xr[0], xr[3], 0.0]) + rng.normal(scale=[1e-3, 1e-2, 0.5])
        tau = ctrl(0.01 * k, y)
        u = np.concatenate([xr, [tff], y])
        assert sys.output(0, xs, u)[0] == pytest.approx(tau, rel=1e-12, abs=1e-12)
        xs = sys.dynamics(0, xs, u)
        assert np.allclose(xs, ctrl.x_pred, rtol=1e-12, atol=1e-15)
    # the Kalman gains of the schedule are those of its filter's models: the designs with the
    # residual modes (robust, the default), or the designs themselves
    models, E = filter_schedule(sched, settings)
    assert models.n_modes == 10 and E.shape == (22, 6) and ctrl.gains.shape == (4, 22)
    assert np.allclose(KalmanEstimator(models.designs[0], settings, 2).L, ctrl.L[0])
    plain = ScheduledLQG(sched, LQGSettings(robust=False), ref)
    assert np.allclose(kalman_gain(sched.designs[0], settings), plain.estimator.L[0])


@pytest.mark.parametrize("robust", [True, False])
def test_scheduled_lqg_at_constant_spin_equals_fixed_lqg(ref, robust):
    """Both on a schedule whose grid ends at the design spin, driven at that spin, give the same torques."""
    s = DesignSchedule.build(P2, [2.0, 3.0], 0.01)
    hold = spinup_reference(3.0, 10.0, P2.total_inertia, 0.01, 15.0)
    st = LQGSettings(robust=robust)
    fixed, sch = LQG(s.designs[-1], st, hold), ScheduledLQG(s, st, hold, variable="reference")
    E = embedding(s.n_modes, fixed.filter_model.n_modes)
    fixed.reset()
    sch.reset()
    rng = np.random.default_rng(3)
    for k in range(1200, 1260):                                     # after the spin-up: rate 3 rad/s
        t = 0.01 * k
        xr, _ = sch._reference_at(k)
        y = np.array([xr[0], 3.0, 0.0]) + rng.normal(scale=[1e-4, 1e-3, 0.02])
        if k == 1200:                                               # start both on the reference
            fixed.estimator.reset(E @ (xr - np.r_[3.0 * t, 0, 0, 3.0, 0, 0]))   # deviation coordinates
            sch.estimator.reset(E @ xr)
        assert fixed(t, y) == pytest.approx(sch(t, y), rel=1e-9, abs=1e-9)


def test_registry_builds_the_scheduled_versions(sched, ref):
    """make_controller(schedule=...) builds the registered scheduled class with the usual settings."""
    for name, cls, settings in (("lqr", ScheduledLQR, None), ("lqg", ScheduledLQG, LQGSettings(tau_max=150.0)),
                                ("mpc", ScheduledMPC, MPCSettings(horizon=5))):
        assert CONTROLLERS[name].scheduled is cls
        ctrl = make_controller(name, sched.designs[1], settings, ref, schedule=sched)
        assert type(ctrl) is cls and ctrl.name == name and ctrl.schedule is sched
        assert ctrl.stats()["schedule_points"] == 4
    assert np.allclose(ctrl.gains[2], dlqr_gain(sched.designs[2], Weights())[0], rtol=1e-12)
    assert ctrl.settings.horizon == 5


def test_schedule_for_a_scenario_spans_its_reference_rates():
    sc = make_scenario("spinup", plant="foam", params=P2, t_f=10.0, t_end=15.5, w_f=2.0)
    s = DesignSchedule.for_scenario(sc, 3)
    assert np.allclose(s.spins, [0.0, 1.0, 2.0], rtol=0, atol=1e-12)
    assert [d.spin for d in s.designs] == s.spins.tolist() and s.n_modes == 2 and s.dt == sc.dt


@pytest.mark.parametrize("spins, match", [
    ([1.0], "at least 2 spin rates"),
    ([0.0, 2.0, 1.0], "strictly ascending"),
    ([0.0, 1.0, 1.0], "strictly ascending"),
    ([-1.0, 1.0], "must be >= 0"),
    ([0.0, float("nan")], "finite"),
    ("abc", "spins must be numbers"),
])
def test_bad_schedule_is_one_line(spins, match):
    with pytest.raises(ParameterError, match=match) as exc:
        DesignSchedule.build(P2, spins, 0.01)
    assert "\n" not in str(exc.value)


@pytest.mark.parametrize("call, match", [
    (lambda s: make_controller("pd", s.designs[0], schedule=s), "no scheduled version of 'pd'"),
    (lambda s: ScheduledLQR(s, variable="estimated"), "variable must be one of measured, reference"),
    (lambda s: ScheduledLQR(DesignModel.build(P2)), "schedule must be a DesignSchedule"),
    (lambda s: ScheduledMPC(s, MPCSettings(horizon=5, tip_bound=0.1)), "tip_bound is not available"),
    (lambda s: scheduled_lqr_iosystem(s, gainsched_indices="omega"), "unknown signal 'omega'"),
    (lambda s: DesignSchedule.build(P2, points=1), "points must be an integer >= 2"),
    (lambda s: compare(None, "spinup", "lqr",
                       CompareSettings(design=DesignChoice(schedule=0))), "schedule must be an integer >= 1"),
])
def test_bad_scheduled_input_is_one_line(sched, call, match):
    with pytest.raises(ParameterError, match=match) as exc:
        call(sched)
    assert "\n" not in str(exc.value)


# == the spin-up on FOAM (slow) =================================================================
@pytest.fixture(scope="module")
def spinup_runs(fast_backend_module):
    """Spin-up to 3 rad/s in 10 s on FOAM: fixed design at 3 rad/s, and schedules of 9 and 17 spins."""
    runs = {1: compare(None, "spinup", "openloop,lqr,mpc").metrics}
    for n in (9, 17):
        runs[n] = compare(None, "spinup", "lqr,mpc", CompareSettings(design=DesignChoice(schedule=n))).metrics
    return runs


@pytest.mark.slow
def test_target_scheduled_lqr_and_mpc_in_the_spinup(spinup_runs):
    fixed, sched = spinup_runs[1], spinup_runs[9]
    feedforward_only = fixed["openloop"]["residual_tip_max_m"]
    for name in ("lqr", "mpc"):
        m = sched[name]
        assert m["completed"] and m["within_torque_limit"] and m["schedule_points"] == 9
        assert m["residual_tip_max_m"] <= 0.01 * feedforward_only   # measured 0.89 %, 0.53 % (5 modes: 0.90, 0.54)
        assert m["residual_tip_max_m"] <= 0.5 * fixed[name]["residual_tip_max_m"]   # fixed 3.1 %, 2.6 %


@pytest.mark.slow
def test_default_grid_is_dense_enough(spinup_runs):
    """Doubling the grid (9 -> 17 spins) changes the residual by less than 5 %."""
    for name in ("lqr", "mpc"):
        a, b = spinup_runs[9][name]["residual_tip_max_m"], spinup_runs[17][name]["residual_tip_max_m"]
        assert abs(b - a) < 0.05 * b, (name, a, b)   # measured 1.3 %, 2.8 % (5 modes: 1.3, 3.0)


@pytest.mark.parametrize("argv, match", [
    (["--schedule", "0"], "schedule must be an integer > 0"),
    (["--schedule", "two"], "schedule must be an integer"),
    (["--shaping", "zvdd"], "invalid choice: 'zvdd'"),
])
def test_cli_bad_schedule_or_shaping_exits_2(capsys, tmp_path, argv, match):
    from hubbeam_ctrl.cli.main import main
    code = main(["compare", "--plant", "foam", "--scenario", "spinup", "--controllers", "lqr",
                 "--out", str(tmp_path / "out"), *argv])
    err = capsys.readouterr().err
    assert code == 2 and match in err and len(err.strip().splitlines()) == 1
