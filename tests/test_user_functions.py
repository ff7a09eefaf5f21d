"""User functions as torques and maneuvers (issue 14, class 1): constants, NumPy scalars and
0-d arrays work; a function that raises or returns bad values stops the run, naming it."""

import casadi as ca
import numpy as np
import pytest

from hubbeam_ctrl import Params, TorquePulse, UserManeuver, simulate
from hubbeam_ctrl.core.errors import HubbeamError, UserFunctionError

SMALL = Params(n_axial=2, n_transverse=2)


@pytest.fixture(scope="module")
def constant_run():
    """Reference: a constant 100 N m written as a CasADi-compatible expression."""
    return simulate("foam", lambda t: 100.0 + 0 * t, 1.0, params=SMALL)


@pytest.mark.parametrize("func", [lambda t: 100.0, lambda t: 100, lambda t: np.float32(100.0),
                                  lambda t: np.int64(100), lambda t: np.array(100.0),
                                  lambda t: np.float64(100.0)],
                         ids=["float", "int", "float32", "int64", "0-d", "float64"])
def test_constants_give_the_constant_torque_run(func, constant_run):
    res = simulate("foam", func, 1.0, params=SMALL)
    assert not res.diverged and len(res.t) == 101
    np.testing.assert_allclose(res.theta, constant_run.theta, rtol=1e-12, atol=1e-15)
    # the torque is the rate of the angular momentum about the hub axis: H(t) = 100 N m * t
    np.testing.assert_allclose(res.angular_momentum, 100.0 * res.t, rtol=1e-5, atol=1e-9)


def test_tabulated_function_matches_symbolic():
    """A function that cannot take a CasADi symbol is tabulated and gives the same run."""
    pulse = TorquePulse(200.0, 1.0)
    exact = simulate("foam", pulse, 1.5, params=SMALL)
    table = simulate("foam", lambda t: float(pulse(np.asarray(t))) if t >= 0 else 0.0, 1.5, params=SMALL)
    assert not table.diverged
    np.testing.assert_allclose(table.theta, exact.theta, atol=2e-6 * np.abs(exact.theta).max())


@pytest.mark.parametrize("func,needle", [
    (lambda t: float("nan"), "returned nan at t = 0 s"),
    (lambda t: np.inf, "returned inf at t = 0 s"),
    (lambda t: [1.0, 2.0, 3.0], "must return a number at t = 0 s, got a list of 3"),
    (lambda t: np.ones(3), "got an array of shape (3,)"),
    (lambda t: "100", "must return a number"),
    (lambda t: 1 / 0, "raised ZeroDivisionError: division by zero at t = 0 s"),
])
def test_bad_from_the_start_raises_naming_the_function(func, needle):
    with pytest.raises(UserFunctionError) as err:
        simulate("foam", UserManeuver(func, name="my_torque"), 1.0, params=SMALL)
    assert "torque function my_torque" in str(err.value) and needle in str(err.value)


@pytest.mark.parametrize("func,needle", [
    (lambda t: 100.0 if t < 0.5 else 1 / 0, "raised ZeroDivisionError"),       # tabulated
    (lambda t: 100.0 if t < 0.5 else float("nan"), "returned nan"),            # tabulated
    (lambda t: 100.0 * ca.sqrt(0.5 - t), "returned nan"),                      # symbolic
])
def test_failing_later_stops_and_keeps_what_was_computed(func, needle):
    res = simulate("foam", UserManeuver(func, name="late"), 1.0, params=SMALL)
    assert res.diverged and "torque function late" in res.message and needle in res.message
    assert 0.45 <= res.t[-1] <= 0.5 and np.all(np.isfinite(res.q)) and np.all(np.isfinite(res.tau))
    assert f"results end at t = {res.t[-1]:.3f} s" in res.message


def test_prescribed_nan_is_flagged_not_silent():
    m = UserManeuver(lambda t: (0 * t, 0 * t, ca.sqrt(0.5 - t)), "prescribed", name="spin")
    res = simulate("foam", m, 1.0, params=SMALL)
    assert res.diverged and "maneuver function spin returned nan" in res.message
    assert res.t[-1] <= 0.5 and np.all(np.isfinite(res.q)) and np.all(np.isfinite(res.v))


def test_prescribed_constant_tuple_holds_the_hub_still():
    res = simulate("foam", UserManeuver(lambda t: (0.0, 0.0, 0.0), "prescribed"), 0.5, params=SMALL)
    assert not res.diverged and np.all(res.theta == 0) and np.abs(res.v_tip).max() == 0


def test_prescribed_wrong_arity_is_named():
    with pytest.raises(UserFunctionError, match="maneuver function two must return"):
        simulate("foam", UserManeuver(lambda t: (0.0, 0.0), "prescribed", name="two"), 0.5, params=SMALL)


def test_user_errors_are_toolbox_errors_with_the_cause():
    with pytest.raises(HubbeamError) as err:
        UserManeuver(lambda t: {}["k"], name="lookup")(0.25)
    assert isinstance(err.value.__cause__, KeyError) and err.value.t == 0.25
