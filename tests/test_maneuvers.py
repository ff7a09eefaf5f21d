"""Hub maneuvers (:mod:`hubbeam_ctrl.plant.maneuvers`): the corrected Eq. 43 spin-up, the Eq. 44
torque pulse (one full sine period), and user functions, numerically and on CasADi symbols."""

import math

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import cumulative_trapezoid

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.maneuvers import ConstantSpin, SpinUp, TorquePulse, UserManeuver, spinup_rate


@pytest.mark.parametrize("w_f,t_f", [(2.8, 30.0), (5.0, 30.0), (-1.5, 7.0)])
def test_spinup_closed_form_at_half_and_full_time(w_f, t_f):
    """Eq. 43 with the factor t: thd = (w_f/t_f) t - (w_f/2pi) sin(2pi t/t_f)."""
    theta, thd, thdd = SpinUp(w_f, t_f)(np.array([0.0, t_f / 2, t_f]))
    np.testing.assert_allclose(thd, [0.0, w_f / 2, w_f], rtol=1e-12, atol=1e-15)
    # theta = (w_f/t_f) [t^2/2 + (t_f/2pi)^2 (cos(2pi t/t_f) - 1)]
    np.testing.assert_allclose(theta, [0.0, w_f * t_f / 8 - w_f * t_f / (2 * math.pi ** 2), w_f * t_f / 2],
                               rtol=1e-12, atol=1e-15)
    # smooth start and end: no acceleration jump at 0 and t_f; peak 2 w_f/t_f at t_f/2
    np.testing.assert_allclose(thdd, [0.0, 2 * w_f / t_f, 0.0], atol=1e-15)


def test_spinup_profile_is_consistent_and_holds_the_rate_after():
    """theta, theta_dot and theta_ddot integrate into one another; after t_f the hub turns steadily."""
    m = SpinUp(3.0, 20.0)
    t = np.linspace(0.0, 40.0, 400001)
    theta, thd, thdd = m(t)
    np.testing.assert_allclose(cumulative_trapezoid(thdd, t, initial=0.0), thd, atol=1e-9)
    np.testing.assert_allclose(cumulative_trapezoid(thd, t, initial=0.0), theta, atol=1e-8)
    after = t > 20.0
    assert np.all(thd[after] == 3.0) and np.all(thdd[after] == 0.0)
    np.testing.assert_allclose(theta[after], 3.0 * 20.0 / 2 + 3.0 * (t[after] - 20.0), rtol=1e-12)
    np.testing.assert_array_equal(spinup_rate(t[::1000], 3.0, 20.0), thd[::1000])


@pytest.mark.parametrize("tau_m,t_f", [(200.0, 10.0), (50.0, 4.0)])
def test_torque_pulse_one_period_is_rest_to_rest(tau_m, t_f):
    """Eq. 44 over one full sine period: zero net impulse, the rigid hub ends at rest after
    turning by tau_m t_f^2 / (2 pi J), and no torque afterwards."""
    J = 250.0
    pulse = TorquePulse(tau_m, t_f)
    t = np.linspace(0.0, t_f, 200001)
    tau = pulse(t)
    rate = cumulative_trapezoid(tau, t, initial=0.0) / J
    angle = cumulative_trapezoid(rate, t, initial=0.0)
    assert abs(rate[-1]) < 1e-9 * tau_m * t_f / J                   # zero net impulse
    assert np.all(rate >= -1e-12)                                  # turns one way only
    assert angle[-1] == pytest.approx(pulse.rigid_angle(J), rel=1e-8)
    assert pulse.rigid_angle(J) == pytest.approx(tau_m * t_f ** 2 / (2 * math.pi * J), rel=1e-15)
    assert np.max(tau) == pytest.approx(tau_m, rel=1e-9)
    np.testing.assert_array_equal(pulse(np.array([t_f + 1e-6, 2 * t_f, 100.0])), 0.0)


def test_constant_spin():
    theta, thd, thdd = ConstantSpin(1.5)(np.array([0.0, 2.0]))
    np.testing.assert_array_equal(theta, [0.0, 3.0])
    np.testing.assert_array_equal(thd, [1.5, 1.5])
    np.testing.assert_array_equal(thdd, [0.0, 0.0])


@pytest.mark.parametrize("maneuver", [SpinUp(2.8, 30.0), TorquePulse(200.0, 10.0), ConstantSpin(2.0)])
def test_symbolic_evaluation_equals_numeric(maneuver):
    """The built-ins are CasADi expressions too, so integrators can compile them."""
    ts = ca.SX.sym("t")
    out = maneuver(ts)
    outs = out if isinstance(out, tuple) else (out,)
    f = ca.Function("m", [ts], list(outs))
    t = np.array([0.0, 3.3, 10.0, 17.5, 30.0, 41.0])
    expected = maneuver(t)
    expected = expected if isinstance(expected, tuple) else (expected,)
    for k, e in enumerate(expected):
        got = np.array([float(f(tk)[k]) if len(outs) > 1 else float(f(tk)) for tk in t])
        np.testing.assert_allclose(got, e, rtol=1e-14, atol=1e-12)


@pytest.mark.parametrize("symbol", [ca.SX, ca.MX])
def test_user_function_is_used_exactly_or_tabulated(symbol):
    """A CasADi-compatible function is used as it is; one that is not (``math.sin``) is
    tabulated on ``table_dt`` and interpolated linearly (error <= table_dt^2 / 8 max|f''|).
    (``float`` of an SX symbol is NaN, so ``math.sin`` does not raise on SX: it must still
    be tabulated, not turned into a NaN torque.)"""
    ts = symbol.sym("t")
    exact = UserManeuver(lambda t: 3.0 * t ** 2, "torque")
    assert float(ca.Function("f", [ts], [exact(ts)])(0.7)) == pytest.approx(1.47, rel=1e-15)
    tab = UserManeuver(lambda t: 10.0 * math.sin(t), "torque", table_dt=1e-2).bind(5.0)
    f = ca.Function("f", [ts], [tab(ts)])
    t = np.linspace(0.0, 5.0, 777)
    err = np.max(np.abs([float(f(tk)) - 10.0 * math.sin(tk) for tk in t]))
    assert 0 < err <= 10.0 * 1e-4 / 8 * (1 + 1e-6)
    assert tab(0.3) == 10.0 * math.sin(0.3)                         # numbers: the function itself
    prescribed = UserManeuver(lambda t: (math.sin(t), math.cos(t), -math.sin(t)), "prescribed").bind(2.0)
    g = ca.Function("g", [ts], list(prescribed(ts)))
    assert [float(v) for v in g(1.0)] == pytest.approx([math.sin(1), math.cos(1), -math.sin(1)], abs=1e-6)


@pytest.mark.parametrize("make,needle", [
    (lambda: SpinUp(w_f=float("nan")), "^w_f must"),
    (lambda: SpinUp(t_f=0.0), "^t_f must"),
    (lambda: TorquePulse(t_f=-1.0), "^t_f must"),
    (lambda: TorquePulse(tau_m=-1.0), "^tau_m must"),
    (lambda: ConstantSpin(float("inf")), "spin"),
    (lambda: UserManeuver(lambda t: t, kind="angle"), "kind"),
    (lambda: UserManeuver(3.0), "callable"),
])
def test_bad_maneuvers_are_named(make, needle):
    with pytest.raises(ParameterError, match=needle):
        make()
