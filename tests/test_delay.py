"""Computation delay: in the closed loop and as an extra state of the design model (issue 21, Build 6)."""

import control
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from hubbeam_ctrl import Params
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.linear import linearize
from hubbeam_ctrl.linear.delay import delay_augmented, delay_inputs
from hubbeam_ctrl.plant.rig import Drive, Friction, Timing, load_rig
from hubbeam_ctrl.sim import ClosedLoopSettings, simulate_closed_loop
from hubbeam_ctrl.sim.hardware import Hardware

DT = 1e-3
SETTINGS = ClosedLoopSettings(dt=DT, substeps=4)


def _delayed(d: float) -> Hardware:
    return Hardware(Drive(), Friction(), timing=Timing(delay=d))


class Sequence:
    """Returns commands[k] at sample k, whatever it measures."""

    name, measurement, n_modes = "sequence", "state", 1

    def __init__(self, commands, dt=DT):
        self.commands, self.dt = np.asarray(commands, dtype=float), dt

    def reset(self):
        pass

    def __call__(self, t, y):
        k = int(round(t / self.dt))
        return float(self.commands[k]) if k < len(self.commands) else 0.0


def test_delay_zero_is_todays_loop_bit_for_bit_and_one_is_a_shifted_command():
    p = Params(n_axial=1, n_transverse=2)
    u = 40.0 * np.sin(np.arange(200) * 0.07)
    today = simulate_closed_loop("foam", Sequence(u), 0.15, params=p, settings=SETTINGS)
    zero = simulate_closed_loop("foam", Sequence(u), 0.15, params=p, settings=SETTINGS, hardware=_delayed(0.0))
    for name in ("q", "v", "tau"):
        assert np.array_equal(getattr(today, name), getattr(zero, name))
    # one whole sample: the plant sees exactly the command sequence shifted by one sample
    one = simulate_closed_loop("foam", Sequence(u), 0.15, params=p, settings=SETTINGS, hardware=_delayed(1.0))
    shifted = simulate_closed_loop("foam", Sequence(np.r_[0.0, u]), 0.15, params=p, settings=SETTINGS)
    assert np.array_equal(one.q, shifted.q) and np.array_equal(one.v, shifted.v)
    assert np.array_equal(one.tau[:-1], shifted.tau[1:])           # the record is the command, unshifted
    assert one.settings["timing"] == {"delay": 1.0, "delay_substeps": 4, "applied_delay": 1.0}


def _pulse_centre(p, d: float) -> float:
    """When a one-sample torque pulse at k = 2 acted on a rigid hub, from the hub's later motion:
    theta = omega (t - t_c) [s]."""
    u = np.zeros(10)
    u[2] = 1e-3
    res = simulate_closed_loop("foam", Sequence(u), 0.1, params=p, settings=SETTINGS, hardware=_delayed(d))
    assert np.all(res.q[:3, 0] == 0.0)            # nothing moves before the pulse acts
    after = res.t > 0.01                          # a line fitted through the ringing of the link
    slope, intercept = np.polyfit(res.t[after], res.q[after, 0], 1)
    assert slope == pytest.approx(u[2] * DT / p.total_inertia, rel=1e-5)
    return -intercept / slope


def test_a_delayed_torque_pulse_moves_the_hub_later_by_the_delay():
    """The servo's hub with a nearly massless link (rho = 1), a rigid body of inertia J, hit by one
    sample of torque at k = 2 turns at omega = u dt / J through theta = omega (t - t_c): the delay d
    moves the pulse's centre t_c by d dt (measured within 1.3e-6 dt, a line fitted through the link's
    ringing). Without delay t_c is
    (2 + 1/2) dt plus half an integration step h = dt / 4: the generalized-alpha step averages the
    acceleration over a substep, so a jump of the held torque acts as a ramp over one step."""
    p = load_rig("servo_link").plant_params.replace(n_axial=1, n_transverse=2, rho=1.0)
    t0 = _pulse_centre(p, 0.0)
    assert t0 / DT == pytest.approx(2.5 + 0.5 / 4, abs=2e-3)
    for d in (0.25, 0.5, 1.0):
        shift = (_pulse_centre(p, d) - t0) / DT
        print(f"delay {d}: pulse later by {shift:.7f} samples")
        assert shift == pytest.approx(d, abs=1e-5)


def test_augmented_model_of_an_inertia_is_the_analytic_one():
    """J theta'' = u, delay d: Gamma0 = [((1-d) dt)^2 / 2, (1-d) dt] / J, Gamma1 = e^(A (1-d) dt)
    [(d dt)^2 / 2, d dt] / J; d = 0 is python-control's zero-order hold."""
    J, dt, d = 2.0, 0.1, 0.3
    A, B = np.array([[0.0, 1.0], [0.0, 0.0]]), np.array([[0.0], [1.0 / J]])
    Phi, G0, G1 = delay_inputs(A, B, dt, d)
    late, early = (1 - d) * dt, d * dt
    assert G0[:, 0] == pytest.approx([late ** 2 / 2 / J, late / J], rel=1e-13)
    assert G1[:, 0] == pytest.approx([(early ** 2 / 2 + late * early) / J, early / J], rel=1e-13)
    Ad, Bd = delay_augmented(A, B, dt, 0.0)
    zoh = control.ss(A, B, np.eye(2), 0).sample(dt)
    assert np.allclose(Ad[:2, :2], zoh.A, atol=1e-15) and np.allclose(Bd[:2], zoh.B, atol=1e-15)
    assert np.all(Ad[:2, 2] == 0)


def test_delayed_loop_poles_match_the_exact_sampled_loop_and_a_pade_model():
    """An LQR gain designed without the delay, closed on the 2-mode SFOAM with 0.6 samples of delay:
    the poles of the augmented model equal those of the loop integrated exactly over one sample
    (to 1e-12) and the n largest poles of a 6th-order Pade model of the delay sampled with the plain
    zero-order hold (to 1e-4, the Pade model's own error; the delay moves them by > 0.05); the
    delay's own pole within 5 % of the Pade model's next one."""
    lm = linearize("sfoam", 0.0, Params(n_transverse=2), outputs=("theta",))
    A, B = np.asarray(lm.sys.A), np.asarray(lm.sys.B)
    n, dt, d = A.shape[0], 0.01, 0.6
    plain = control.ss(A, B, np.eye(n), 0).sample(dt)
    K, _, _ = control.dlqr(plain.A, plain.B, np.diag([100.0] + [1.0] * (n - 1)), 1e-6, method="scipy")
    Ad, Bd = delay_augmented(A, B, dt, d)
    lam = np.sort_complex(np.linalg.eigvals(Ad - Bd @ np.hstack([K, np.zeros((1, 1))])))
    exact = np.zeros((n + 1, n + 1))
    for j, z in enumerate(np.eye(n + 1)):
        x0, u_prev, u = z[:n], z[n], float((-K @ z[:n])[0])
        ivp = dict(rtol=1e-12, atol=1e-14, method="DOP853")
        x1 = solve_ivp(lambda t, x: A @ x + B[:, 0] * u_prev, (0, d * dt), x0, **ivp).y[:, -1]
        exact[:n, j] = solve_ivp(lambda t, x: A @ x + B[:, 0] * u, (d * dt, dt), x1, **ivp).y[:, -1]
        exact[n, j] = u
    assert np.max(np.abs(lam - np.sort_complex(np.linalg.eigvals(exact)))) < 1e-12
    pade = control.series(control.tf2ss(control.tf(*control.pade(d * dt, 6))), control.ss(A, B, np.eye(n), 0))
    pd_ = pade.sample(dt)
    lam_p = np.linalg.eigvals(np.asarray(pd_.A) - np.asarray(pd_.B) @ K @ np.asarray(pd_.C))
    by_size = lambda z: z[np.argsort(-np.abs(z))]             # noqa: E731
    lam, lam_p = by_size(lam), by_size(lam_p)
    err = np.max(np.abs(np.sort_complex(lam[:n]) - np.sort_complex(lam_p[:n])))
    print(f"augmented vs Pade: plant poles within {err:.1e}, delay pole {lam[n]:.5f} vs {lam_p[n]:.5f}")
    assert err < 1e-4                                         # measured 1.3e-5
    assert abs(lam[n] - lam_p[n]) < 0.05 * abs(lam[n])
    no_delay = by_size(np.linalg.eigvals(plain.A - plain.B @ K))
    assert np.max(np.abs(np.sort_complex(no_delay) - np.sort_complex(lam[:n]))) > 0.05   # the delay matters


def test_rig_sample_time_must_be_the_loop_s():
    with pytest.raises(ParameterError, match=r"^timing.dt = 0.002 s of the rig but the closed loop samples at dt = "
                                             r"0.001 s"):
        simulate_closed_loop("foam", Sequence([0.0]), 0.01, params=Params(n_axial=1, n_transverse=1),
                             settings=SETTINGS, hardware=Hardware(Drive(), Friction(), timing=Timing(dt=2e-3)))


def test_bad_delay_is_one_line_naming_the_key():
    for bad in (1.5, -0.1):
        with pytest.raises(ParameterError, match=r"^timing.delay must be in \[0, 1\]"):
            Timing(delay=bad)
        with pytest.raises(ParameterError, match=r"^timing.delay must be in \[0, 1\]"):
            delay_inputs(np.zeros((1, 1)), np.ones((1, 1)), 0.1, bad)


def test_design_model_carries_the_delay_as_an_extra_state():
    """DesignModel.with_delay: delay 0 is its own sampled model with the previous command unused;
    with half a sample the previous command's column is the exact Gamma1."""
    from controllers import DesignModel
    design = DesignModel.build(Params(n_transverse=2), 0.0, 0.01)
    n = design.n_x
    Ad, Bd = design.with_delay(0.0)
    assert np.allclose(Ad[:n, :n], design.Ad, rtol=0, atol=1e-12) and np.allclose(Bd[:n], design.Bd, atol=1e-12)
    assert np.all(Ad[:, n] == 0) and Bd[n, 0] == 1.0
    Ad, Bd = design.with_delay(0.5)
    Phi, G0, G1 = delay_inputs(design.A, design.B, 0.01, 0.5)
    assert np.array_equal(Ad[:n, n:], G1) and np.array_equal(Bd[:n], G0)
    assert np.allclose(G0 + G1, design.Bd, rtol=0, atol=1e-12)       # the whole sample's input, split
