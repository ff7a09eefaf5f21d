"""Strain gauges along the beam and the tip accelerometer (issue 21, Build 5)."""

import numpy as np
import pytest

from hubbeam_ctrl import Params, TorquePulse, build_model
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.basis import modal_basis
from hubbeam_ctrl.plant.instruments import moment_rows, signal_names, tip_acceleration, tip_kinematics_function
from hubbeam_ctrl.plant.sensors import sensor_matrix
from hubbeam_ctrl.sim import simulate_fixed_step
from hubbeam_ctrl.sim.stepper import StepperSettings


def test_gauge_at_the_root_is_the_root_sensor_and_moves_continuously():
    p = Params(n_axial=2, n_transverse=4)
    root = sensor_matrix(p, 4, 2)[2]
    rows = moment_rows(p, [0.0, 1e-7 * p.L], 4, 2)
    assert np.array_equal(rows[0], root)                        # bit for bit
    assert np.allclose(rows[1], root, rtol=1e-5, atol=0)
    assert signal_names(2, True) == ("theta", "theta_dot", "moment_1", "moment_2", "accel_radial",
                                     "accel_tangential")


def test_gauge_reads_the_static_moment_of_a_tip_load():
    """Clamped beam under a tip force F (K2 q2 = f2(L) F): M(x) = F (L - x), within the modal
    truncation of 10 modes (measured: -0.2 % at the root, +0.25 % at mid-span, -1.2 % at 0.75 L
    where the moment is small)."""
    p = Params(n_axial=1, n_transverse=10)
    b = modal_basis(p)
    q2 = np.linalg.solve(b.K2, b.f2_tip * 1.0)
    x = np.array([0.0, 0.1, 0.5, 0.75]) * p.L
    M = moment_rows(p, x, 10, 0)[:, 1:11] @ q2
    assert M[:3] == pytest.approx(1.0 * (p.L - x[:3]), rel=5e-3)
    assert M[3] == pytest.approx(1.0 * (p.L - x[3]), rel=2e-2)


def test_gauge_beyond_the_beam_is_refused():
    with pytest.raises(ParameterError, match=r"^sensors.strain_gauges\[1\] must be in \[0, L\] = \[0, 8\] \[m\]"):
        moment_rows(Params(), [0.0, 8.5], 3)


def test_accelerometer_at_steady_spin_is_the_centripetal_acceleration():
    """Rigid-body value -omega^2 (r + L) radially, nothing tangentially; the beam's centrifugal
    stretch adds u_tip (measured 4e-6 relative on Table 1's beam at 2 rad/s)."""
    p = Params(n_axial=2, n_transverse=3, r=0.5)
    model = build_model("foam", p)
    for w in (1.0, 2.0):
        x = model.steady_state(w)
        q, v = x[:model.n_q], x[model.n_q:]
        acc = tip_acceleration(model, q, v, model.accelerations(q, v, 0.0))
        u_tip = model.tip(q)[1]
        assert acc[0] == pytest.approx(-w ** 2 * (p.r + p.L + u_tip), rel=1e-9)
        assert acc[0] == pytest.approx(-w ** 2 * (p.r + p.L), rel=1e-4)
        assert abs(acc[1]) < 1e-9 * w ** 2 * p.L
    # a hub turning up from rest at alpha (rigid at that instant): tangential alpha (r + L)
    q, v = np.zeros(model.n_q), np.zeros(model.n_q)
    a = np.zeros(model.n_q)
    a[0] = 0.3
    assert tip_acceleration(model, q, v, a) == pytest.approx([0.0, 0.3 * (p.r + p.L)], abs=1e-12)


def test_accelerometer_against_finite_differences_of_the_simulated_tip_velocity():
    """FOAM under Eq. 44's torque for 3 s (spinning up, bending): the AD acceleration at each sample
    against the central difference of the inertial tip velocity, both in hub axes (measured: 1.7e-5
    m/s^2 of a 22 m/s^2 signal, the difference's own O(dt^2) error)."""
    model = build_model("foam", Params(n_axial=2, n_transverse=3))
    dt = 1e-3
    r = simulate_fixed_step(model, TorquePulse(200, 10), 3.0, settings=StepperSettings(dt=dt, substeps=2))
    f = tip_kinematics_function(model).map(len(r.t))
    _, vel, acc = (np.array(z).T for z in f(r.q.T, r.v.T, r.a.T))
    c, s = np.cos(r.q[:, 0]), np.sin(r.q[:, 0])
    v_in = np.stack([c * vel[:, 0] - s * vel[:, 1], s * vel[:, 0] + c * vel[:, 1]], 1)
    a_in = (v_in[2:] - v_in[:-2]) / (2 * dt)
    c, s = c[1:-1], s[1:-1]
    fd = np.stack([c * a_in[:, 0] + s * a_in[:, 1], -s * a_in[:, 0] + c * a_in[:, 1]], 1)
    scale = np.max(np.abs(acc), axis=0)
    assert scale[0] > 10 and scale[1] > 5                         # both axes exercised
    assert np.max(np.abs(fd - acc[1:-1])) < 1e-5 * np.max(scale)
    with pytest.raises(ParameterError, match="dynamic axial coordinates"):
        tip_kinematics_function(build_model("foam", Params(n_axial=2, n_transverse=3), axial="quasi-static"))
