"""Issue 28: a user torque written with NumPy runs exactly and prints no warning."""

import warnings

import casadi as ca
import numpy as np

from hubbeam_ctrl import Params, UserManeuver, simulate

SMALL = Params(n_axial=2, n_transverse=2)


def test_numpy_torque_gives_no_warning_and_the_exact_run():
    with warnings.catch_warnings():
        warnings.simplefilter("error")                   # any warning fails the test
        res = simulate("foam", lambda t: 50 * np.sin(t), 1.0, params=SMALL)
    exact = simulate("foam", lambda t: 50 * ca.sin(t), 1.0, params=SMALL)
    assert not res.diverged and len(res.t) == 101
    np.testing.assert_array_equal(res.theta, exact.theta)     # traced exactly, not tabulated
    # the hub torque is the rate of the angular momentum: H(t) = 50 (1 - cos t)
    H = 50 * (1 - np.cos(res.t))
    np.testing.assert_allclose(res.angular_momentum, H, rtol=0, atol=1e-5 * H.max())


def test_a_trace_that_warns_is_not_trusted():
    """A function that warns when given a symbol is evaluated on numbers only (tabulated)."""
    def torque(t):
        if isinstance(t, ca.SX):
            warnings.warn("symbolic input", RuntimeWarning)
        return 50 * np.sin(t)
    m = UserManeuver(torque).bind(1.0)
    t = ca.SX.sym("t")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        expr = m(t)
    f = ca.Function("f", [t], [expr])
    err = abs(float(f(0.5005)) - 50 * np.sin(0.5005))       # mid-way between table points (1 ms)
    assert 1e-7 < err < 50 * np.sin(0.5005) * 1e-3 ** 2 / 8 * 1.01   # linear interpolation's error
