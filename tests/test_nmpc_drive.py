"""Issue 40 item 1: the rig's DC drive, viscous friction, current limit and delay in the NMPC's prediction
(controllers.nmpc_drive)."""

from __future__ import annotations

import numpy as np
import pytest

from controllers import DesignModel
from controllers.nmpc import NMPC, NMPCSettings
from hubbeam_ctrl.plant.rig import Rig, load_rig
from hubbeam_ctrl.sim.hardware import Hardware, drive_torque


@pytest.fixture(scope="module")
def servo():
    """servo_link's drive and a 2-mode design model with its half sample of delay (1 ms)."""
    rig = load_rig("servo_link")
    p = rig.plant_params
    return rig, Hardware.from_rig(rig), DesignModel.build(p, 0.0, 1e-3, 2).on_rig(None, rig.timing.delay)


def test_the_drive_in_the_prediction_is_the_plants_drive_stage(servo):
    """The prediction's hub torque (CasADi, inside the shooting map) equals the plant's drive stage
    (sim.hardware.drive_torque) less the viscous friction at random volts and hub rates, motoring,
    back-driven and in current limit, to 1e-12 N m, wherever the gear's efficiency switch is complete
    (hub rates above 20 times the prediction's switch scale, PredictionDrive.resolved); Coulomb
    friction is not in it."""
    import casadi as ca
    rig, hw, d = servo
    ctrl = NMPC(d, NMPCSettings(tau_max=rig.plant_params.tau_max, horizon=5), hardware=hw)
    u, w = ca.SX.sym("u"), ca.SX.sym("w")
    f = ca.Function("tq", [u, w], [ctrl.drive.torque(u, w)])
    rng = np.random.default_rng(7)
    V, thd = rng.uniform(-12.0, 12.0, 200), rng.uniform(-30.0, 30.0, 200)
    plant = drive_torque(V, thd, hw.values()) - rig.friction.viscous * thd
    pred = np.array([float(f(a, b)) for a, b in zip(V, thd)])
    from hubbeam_ctrl.sim.hardware import HW_LAYOUT
    scale = ctrl.drive.values[HW_LAYOUT.index("v_eps")]
    away = np.abs(thd) > 20 * scale
    assert np.sum(away) > 150 and np.max(np.abs(pred - plant)[away]) <= 1e-12
    assert np.any(np.abs((V - hw.back_emf_constant() * thd) / rig.drive.R) > rig.drive.I_max)   # current limit hit
    assert ctrl.command == "voltage" and ctrl.u_max == rig.drive.V_max and ctrl._G is not None


def test_the_delay_holds_the_command_in_flight(servo):
    """With half a sample of delay the step first predicts the state where its command acts under the
    command in flight: from rest under V_prev = 5 V for half a sample the hub gains the rate one
    sample's shooting map gives it in half the time (to RK4's accuracy), none under V_prev = 0; and the
    step function takes the command in flight as its last input."""
    rig, hw, d = servo
    ctrl = NMPC(d, NMPCSettings(tau_max=rig.plant_params.tau_max, horizon=5), hardware=hw)
    n = ctrl._n
    x0 = np.zeros(ctrl._nx)
    half = np.asarray(ctrl._G(x0, 5.0)).ravel()
    full = np.asarray(ctrl._F(x0, 5.0)[0]).ravel()
    assert np.all(np.asarray(ctrl._G(x0, 0.0)) == 0.0)
    assert half[n] / full[n] == pytest.approx(0.5, rel=0.02)
    assert ctrl.symbolic_step.name_in()[-1] == "u_prev"


def test_an_ideal_rig_gives_todays_nmpc_bit_for_bit():
    """Hardware of an ideal rig (torque drive, no friction, no delay): the same commands as without it."""
    d = DesignModel.build(load_rig("servo_link").plant_params, 0.0, 0.01, 2)
    a = NMPC(d, NMPCSettings(tau_max=1.0, horizon=8))
    b = NMPC(d, NMPCSettings(tau_max=1.0, horizon=8), hardware=Hardware.from_rig(Rig()))
    assert b.drive is None
    rng = np.random.default_rng(3)
    for k in range(5):
        x = rng.normal(scale=0.05, size=d.n_x)
        assert a(k * d.dt, x) == b(k * d.dt, x)


@pytest.mark.parametrize("limit", ["path", "first"])
def test_the_command_keeps_the_current_limit(servo, limit):
    """Far behind its target at 15 rad/s the NMPC brakes with no more than I_max: the volts stay within
    k_e N thd +- R I_max and the box at the hub rate where they act (the current limit at every stage,
    or on the first move)."""
    rig, hw, d = servo
    ctrl = NMPC(d, NMPCSettings(tau_max=rig.plant_params.tau_max, horizon=5, current_limit=limit), hardware=hw)
    x = np.zeros(d.n_x)
    x[0], x[d.n_x // 2] = 0.5, 15.0
    rate = ctrl._acting_error(0, x)[1]          # where the command acts, after half a sample at 0 V
    assert 14.0 < rate < 15.0
    v = ctrl(0.0, x)
    emf, rmax = hw.back_emf_constant() * rate, rig.drive.R * rig.drive.I_max
    assert emf - rmax - 1e-9 <= v <= min(rig.drive.V_max, emf + rmax) + 1e-9
    assert v == pytest.approx(emf - rmax, abs=1e-6)          # braking as hard as the current allows


def test_cli_codegen_writes_the_nmpc_step_with_the_drive(tmp_path, capsys):
    """``hubbeam codegen --controller nmpc --rig servo_link``: the step commands volts, its header says so
    with the limits, and its state ends with the command in flight (half a sample of delay)."""
    import json

    from hubbeam_ctrl.cli.main import main
    out = tmp_path / "nmpc"
    assert main(["codegen", "--controller", "nmpc", "--rig", "servo_link", "--design-modes", "2",
                 "--out", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    rig = load_rig("servo_link")
    assert info["command"] == {"name": "voltage", "unit": "V", "limit": rig.drive.V_max}
    assert "u_prev" in info["inputs"] and info["drive"]["I_max_a"] == rig.drive.I_max
    assert info["inputs"]["x"] == [len(info["states"]), 1] and info["dt_s"] == pytest.approx(1e-3)
    header = (out / "nmpc_rti.h").read_text()
    assert "[V], |u| <= 10 V" in header and "|i| <= 4 A" in header


def test_on_the_rig_the_nmpc_commands_volts_and_its_loop_is_certified(servo):
    """compare's on_rig gives the NMPC the drive (ObservedNMPC: the rig's filter, volts out); its linear
    form at the end point, closed through the rig's drive, delay and sensors, is stable on a 4-mode
    plant (the certificate every verdict carries; 0.994 in the benchmark's runs)."""
    from controllers.lqg import LQGSettings
    from controllers.nmpc_drive import ObservedNMPC
    from hubbeam_ctrl.study.certificate import certify
    from hubbeam_ctrl.study.rig_loop import on_rig, rig_design, rig_noise
    rig, hw, _ = servo
    p = rig.plant_params
    d = rig_design(DesignModel.build(p, 0.0, 1e-3, 2), rig)
    nmpc = NMPC(d, NMPCSettings(tau_max=p.tau_max, horizon=5))
    ctrl = on_rig(nmpc, rig, rig_noise(LQGSettings(), rig), hw)
    assert isinstance(ctrl, ObservedNMPC) and ctrl.inner.drive is not None and ctrl.command == "voltage"
    v = ctrl(0.0, np.zeros(len(ctrl.filter_model.sensor_labels)))
    assert abs(v) <= rig.drive.V_max
    c = certify(ctrl, p.replace(n_transverse=4))
    assert not c.grows and c.worst.spectral_radius < 1.0


@pytest.mark.slow
def test_the_efficiency_switch_is_spread_for_the_shooting_and_servo_payload_settles():
    """The gear's switch between eta_forward and 1 / eta_backward, over the friction's v_eps (1 mrad/s)
    in the plant, is spread in the prediction to what the shooting's RK4 step resolves (0.77 jump N k_t
    I_max h / (J_h RK4_REACH): about 0.29 rad/s on servo_link and servo_payload), and not at all with an
    ideal gear. On servo_payload (full-sample delay, 30 mN m Coulomb friction) the NMPC with the plant's
    1 mrad/s switch was "not settled" (tip 148 um against a 48 um band; growing at 5.6 /s with a fine
    encoder); with the spread switch it settles."""
    from controllers.nmpc_rti import RK4_REACH
    from hubbeam_ctrl.sim.hardware import HW_LAYOUT
    from hubbeam_ctrl.study import compare
    k = HW_LAYOUT.index("v_eps")
    for name in ("servo_link", "servo_payload"):
        rig = load_rig(name)
        d, p = rig.drive, rig.plant_params
        ctrl = NMPC(DesignModel.build(p, 0.0, 1e-3, 2).on_rig(None, rig.timing.delay),
                    NMPCSettings(tau_max=p.tau_max, horizon=5), hardware=Hardware.from_rig(rig))
        want = 0.77 * (1 / d.eta_backward - d.eta_forward) * d.N * d.k_torque * d.I_max * 1e-3 / (
            ctrl.substeps * p.J_h * RK4_REACH)
        assert ctrl.drive.values[k] == pytest.approx(want) and 0.1 < want < 1.0
        ideal = rig.replace(drive=d.replace(eta_forward=1.0, eta_backward=1.0))
        same = NMPC(DesignModel.build(p, 0.0, 1e-3, 2).on_rig(None, rig.timing.delay),
                    NMPCSettings(tau_max=p.tau_max, horizon=5), hardware=Hardware.from_rig(ideal))
        assert same.drive.values[k] == rig.friction.v_eps
    c = compare(load_rig("servo_payload"), "slew", ["nmpc"])
    m = c.metrics["nmpc"]
    assert m["verdict"] == "settled" and m["within_drive_limits"], m["verdict_reason"]
