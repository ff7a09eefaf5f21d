"""A DC drive whose back-EMF damps the hub within a sample: the design model carries it
(``DesignModel.on_rig(hub_damping=)``, :func:`hubbeam_ctrl.study.rig_loop.design_hub_damping`).

Found on random rigs (session 20): the drive's static inverse cancels the back-EMF with the hub rate
of one sample earlier. With a damping ``b = eta N^2 k_t k_e / R`` that takes a sizeable share of
the hub's own speed within a sample (``b dt / J_h``), that cancellation is a delayed positive rate
feedback. The rig below is a 1.5 m steel strip (first clamped mode 1.07 Hz) on a geared DC motor
(k_t = k_e = 0.05, R = 4 ohm, 24 V: a small industrial servo motor's numbers) at 10 ms with a full
sample of computation delay; the gear ratio sets ``b``.
"""

from __future__ import annotations

import numpy as np
import pytest

from controllers import DesignModel
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.plant.rig import Drive, Friction, Rig, Sensors, Timing, load_rig
from hubbeam_ctrl.study.rig_loop import HUB_DAMPING_SHARE, design_hub_damping


def geared_strip(ratio: float) -> Rig:
    beam = Params(L=1.5, rho=7850.0, A=1.5e-4, E=200e9, I=1.125e-10, J_h=0.05, r=0.0, m_t=0.1)
    drive = Drive(kind="dc_motor", R=4.0, L=0.0, k_t=0.05, k_e=0.05, N=float(ratio), eta_forward=0.9,
                  eta_backward=0.7, J_r=0.0, V_max=24.0, I_max=10.0)
    return Rig(beam=beam.replace(tau_max=drive.torque_limit), drive=drive, friction=Friction(viscous=0.01),
               sensors=Sensors(encoder_counts=4096, strain_gauges=(0.0,)), timing=Timing(dt=0.01, delay=1.0))


def test_the_damped_design_models_rate_settles_at_torque_over_b():
    d = DesignModel.build(Params(n_transverse=2), 0.0, 0.01, 2)
    b = 3.0
    dd = d.on_rig(None, 0.0, b)
    n = d.n_x // 2
    assert np.allclose(dd.A - d.A, -b * np.outer(d.B[:, 0], np.eye(d.n_x)[n]))
    # a held torque tau drives the hub to tau / b (the rigid body's terminal speed); the modes at rest
    # (the angle integrates the rate and drives nothing: the steady state of the rest)
    x = np.linalg.solve(np.eye(d.n_x - 1) - dd.Ad[1:, 1:], dd.Bd[1:, 0])
    assert x[n - 1] == pytest.approx(1.0 / b, rel=1e-9)
    assert np.allclose(x[n:], 0.0, atol=1e-12)
    # the rigid pole moves from 0 to about -b / J_total (the flexible modes are far above)
    rigid = min(np.linalg.eigvals(dd.A), key=lambda s: abs(s + b / d.inertia))
    assert rigid.real == pytest.approx(-b / d.inertia, rel=0.02) and abs(rigid.imag) < 1e-9
    assert dd.like(dd) is dd and d.on_rig(None, 0.0, 0.0) is d and dd.on_rig(None, 0.0, 0.0).hub_damping == 0.0
    assert np.allclose(dd.on_rig(None, 0.0, 0.0).A, d.A)
    with pytest.raises(Exception, match="hub_damping must be a finite number >= 0"):
        d.on_rig(None, 0.0, -1.0)


def test_the_reference_adds_the_dampings_torque_and_the_damped_model_follows_the_plan():
    from controllers.planning import planned_slew_reference
    p = Params(n_transverse=2)
    ref = planned_slew_reference(p, 1.0, 8.0, p.tau_max, 0.01, 10.0, 2)
    b = 2.0
    rd = ref.with_hub_damping(b)
    assert rd.with_hub_damping(b) is rd and rd.with_hub_damping(0.0).torque == pytest.approx(ref.torque)
    assert np.allclose(rd.torque[:-1] - ref.torque[:-1], b * np.diff(ref.theta) / ref.dt)
    # the plan's torques on the undamped model and the damped torques on the damped model move the hub alike
    d = DesignModel.build(p, 0.0, 0.01, 2)
    dd = d.on_rig(None, 0.0, b)
    theta = {}
    for model, r in ((d, ref), (dd, rd), (dd, ref)):
        x, th = np.zeros(d.n_x), []
        for u in r.torque[:900]:
            th.append(x[0])
            x = model.Ad @ x + model.Bd[:, 0] * u
        theta[id(model), id(r)] = np.array(th)
    plan = theta[id(d), id(ref)]
    assert np.max(np.abs(plan - ref.theta[:900])) < 1e-6
    follows = np.max(np.abs(theta[id(dd), id(rd)] - plan))
    lags = np.max(np.abs(theta[id(dd), id(ref)] - plan))
    assert follows < 0.01 * lags and follows < 1e-3, (follows, lags)


def test_the_design_carries_the_damping_past_the_share_and_the_presets_keep_theirs():
    for name in ("paper", "servo_link", "servo_payload", "accel_link", "space_boom"):
        assert design_hub_damping(load_rig(name)) == 0.0, name
    low, high = geared_strip(30), geared_strip(60)
    share = lambda rig: (0.9 * rig.drive.N ** 2 * 0.05 ** 2 / 4.0 + 0.01) * 0.01 / 0.05
    assert share(low) < 1.1 * HUB_DAMPING_SHARE and design_hub_damping(geared_strip(20)) == 0.0
    assert design_hub_damping(high) == pytest.approx(0.9 * 60 ** 2 * 0.05 ** 2 / 4.0 + 0.01)


@pytest.mark.slow
def test_a_high_gear_drive_at_a_coarse_sample_settles_with_the_damping_in_the_design(fast_backend):
    from hubbeam_ctrl.study.compare import compare
    from hubbeam_ctrl.study.compare_values import CompareSettings, RunChoice, ScenarioChoice
    rig = geared_strip(100)                      # b dt / J_h = 1.13
    c = compare(rig, "slew", "openloop,lqr,mpc", CompareSettings(
        scenario=ScenarioChoice(t_f=2.2, slew_angle=np.pi / 2), run=RunChoice(t_end=6.0)))
    assert any("the design model carries the hub's damping b = 5.635 N m s/rad" in n and "= 1.13 >= 0.1" in n
               for n in c.notes), c.notes
    for name in ("lqr", "mpc"):
        m = c.metrics[name]
        # cancelling the back-EMF one sample late: spectral radius 1.19, banging between +-24 V, "unstable"
        assert m["loop_spectral_radius"] < 1.0 and m["verdict"] == "settled", (name, m["verdict_reason"])
        assert m["within_voltage_limit"] and m["peak_voltage_v"] < 12.0, m["peak_voltage_v"]
        assert m["residual_tip_max_m"] < 1e-3 * rig.beam.L


@pytest.mark.slow
def test_a_current_limited_drive_commands_up_to_its_voltage_with_the_damping_in_the_design(fast_backend):
    """The design's input is the torque at rest ``g V``: bounded by ``g V_max``, not by the stall torque a
    current limit sets lower. A 1 m aluminium link on a 100:1 motor whose 8 A limit gives 19.2 N m against
    57.6 N m at 24 V at rest (``b dt / J_h`` = 0.36 at 1 ms): bounded at 19.2 N m the laws commanded at most
    8 V, the hub lagged 0.51 rad at t_f and nothing settled."""
    from hubbeam_ctrl.study.compare import compare
    from hubbeam_ctrl.study.compare_values import CompareSettings
    beam = Params(L=1.0, rho=2700.0, A=3e-4, E=69e9, I=2.25e-9, J_h=0.02, r=0.0, m_t=0.2)
    drive = Drive(kind="dc_motor", R=1.0, L=0.0, k_t=0.03, k_e=0.03, N=100.0, eta_forward=0.8, eta_backward=0.6,
                  J_r=0.0, V_max=24.0, I_max=8.0)
    rig = Rig(beam=beam.replace(tau_max=drive.torque_limit), drive=drive,
              friction=Friction(viscous=0.05, coulomb=0.2 * drive.torque_limit),
              sensors=Sensors(encoder_counts=4096, strain_gauges=(0.0,)), timing=Timing(dt=0.001, delay=0.5))
    assert drive.torque_limit == pytest.approx(19.2) and design_hub_damping(rig) == pytest.approx(7.25)
    c = compare(rig, "slew", "lqr,mpc", CompareSettings())
    for name in ("lqr", "mpc"):
        m = c.metrics[name]
        assert m["verdict"] == "settled" and abs(m["angle_error_tf_rad"]) < 1e-3, (name, m["angle_error_tf_rad"])
        assert 8.5 < m["peak_voltage_v"] <= 24.0 and m["within_drive_limits"], m["peak_voltage_v"]
        assert c.controllers[name].tau_max == pytest.approx(0.8 * 100 * 0.03 * 24.0)


def test_a_rig_file_that_rounds_the_stall_torque_up_still_builds_on_the_damped_design():
    """Found in session 21's last batch: a rig file stating 677.603 N m for a drive whose constants give
    677.6028 (kept: within the rig's 1 % tolerance). The damped design's bound was g V_max = 677.6028 and the
    settings' the file's 677.603, 3e-7 above it: every controller refused "tau_max must be in (0, 677.603]"."""
    from controllers import LQR, DesignModel, LQRSettings
    from hubbeam_ctrl.study.rig_loop import rig_design, rig_settings
    rig = geared_strip(100)
    rig = rig.replace(beam=rig.beam.replace(tau_max=rig.drive.torque_limit * (1 + 3e-7)))
    assert rig.beam.tau_max > rig.drive.torque_limit and design_hub_damping(rig) > 0
    design = rig_design(DesignModel.build(rig.plant_params, 0.0, rig.timing.dt, 2), rig)
    settings = rig_settings("lqr", LQRSettings(tau_max=rig.beam.tau_max), rig)
    assert settings.tau_max == design.params.tau_max == rig.beam.tau_max
    assert LQR(design, settings).tau_max == rig.beam.tau_max
