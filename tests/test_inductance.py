"""The DC motor's armature inductance: the current as a state of the plant step (issue 21, Build 2)."""

from pathlib import Path

import numpy as np
import pytest

from hubbeam_ctrl import build_model
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.rig import Drive, load_rig, rig_from_dict
from hubbeam_ctrl.sim import simulate_fixed_step
from hubbeam_ctrl.sim.hardware import Hardware, drive_power, friction_torque, motor_torque
from hubbeam_ctrl.sim.stepper import PlantStepper, StepperSettings

SERVO = load_rig("servo_link")
P = SERVO.plant_params.replace(n_axial=1, n_transverse=3, damping_ratios=())


def _volts(t):
    return 3.0 + 9.0 * np.sin(2 * np.pi * t)      # brakes, back-drives, saturates


def _drive(L: float) -> Hardware:
    return Hardware(Drive(**{**SERVO.drive.to_dict(), "L": L}), SERVO.friction)


#: Every 25th sample of [q, v, a] of the servo's 1 s voltage run with L = 0 (see the test).
NO_INDUCTANCE = Path(__file__).parent / "data" / "servo_volts_no_inductance_reference.npz"


def test_without_inductance_the_dc_motor_is_the_previous_code_bit_for_bit():
    """L = 0: the 1 s voltage run of the servo gives the arrays of the code before the current could be
    a state, the same on both backends bit for bit. Recorded at eac1bcc as SHA-256 9824a58e4cbe7da5;
    re-recorded after the stepper's patient step (PlantStepper.PATIENCE: the samples the fast step
    missed, 10 of 5000 here, are now solved by more Newton iterations instead of the rootfinder,
    to the same tolerance), which the inductance work did not change (53067d597c78fa43 on that
    machine). The arrays are stored (every 25th sample) and compared within 1e-9 of each column's
    largest value: on another CPU the same code gives other round-off (6e6560e7df7d4e35)."""
    from hubbeam_ctrl.core.compiled import find_compiler
    model = build_model("foam", P)
    runs = [simulate_fixed_step(model, _volts, 1.0, settings=StepperSettings(dt=2e-4, substeps=1),
                                hardware=_drive(0.0), backend=backend)
            for backend in (("vm", "compiled") if find_compiler() is not None else ("vm",))]
    got = [np.c_[r.q, r.v, r.a] for r in runs]
    assert all(np.array_equal(got[0], g) for g in got[1:])       # vm and compiled: bit for bit
    want = np.load(NO_INDUCTANCE)["qva"]
    assert got[0][::25].shape == want.shape
    assert np.all(np.abs(got[0][::25] - want) <= 1e-9 * np.max(np.abs(want), axis=0))


def test_current_rises_with_the_electrical_time_constant_at_stall():
    """A hub too heavy to turn (J_h x 1e6) under 1 V: i = V/R (1 - e^(-t R/L)) in the continuous circuit;
    the backward Euler step gives i_k = V/R (1 - (1 + R h / L)^-k) exactly."""
    heavy = build_model("foam", P.replace(J_h=P.J_h * 1e6))
    L, R, h = 1.8e-4, SERVO.drive.R, 1e-5
    stepper = PlantStepper(heavy, StepperSettings(dt=h, substeps=1), hardware=_drive(L))
    assert stepper.inductive and stepper.n_s == 4 * heavy.n_q + 1
    s = stepper.initial_state(tau=0.0)
    assert s[-1] == 0.0
    states = stepper.run(s, np.ones((60, 1)))                   # 1 V from t = 0+
    k = np.arange(1, 61)
    current = states[:, -1]
    assert current == pytest.approx(1.0 / R * (1 - (1 + R * h / L) ** -k), rel=1e-6)   # the hub turns a bit
    t = k * h
    assert np.max(np.abs(current - 1.0 / R * (1 - np.exp(-t * R / L)))) < 0.05 / R        # BE vs exact: 4 %


def test_power_balance_and_circuit_with_inductance():
    """The servo with L = 5 mH (tau_e = 1.9 ms) under the voltage sine: at every sample below the current
    limit the terminal voltage R i + L di/dt + k_e N thd equals the command (the circuit's equation, to
    1e-9 V); electrical power in = copper + magnetic + gear losses + mechanical out to 1e-9; and the
    plant's energy follows the work of the motor torque of that current minus friction."""
    model = build_model("foam", P)
    hw = _drive(5e-3)
    dt = 2e-4
    stepper = PlantStepper(model, StepperSettings(dt=dt, substeps=1), hardware=hw)
    t = dt * np.arange(1, 5001)
    u = _volts(t)
    s0 = stepper.initial_state(tau=_volts(0.0))
    states = np.vstack([s0, stepper.run(s0, u[:, None])])
    n = model.n_q
    i, thd = states[:, -1], states[:, n]
    di = np.diff(i) / dt
    pw = drive_power(u, thd[1:], hw.values(), current=i[1:], di_dt=di)
    free = np.abs(i[1:]) < hw.drive.I_max
    assert np.mean(free) > 0.5 and np.any(np.abs(u) > hw.drive.V_max)         # the amplifier saturates
    V = np.clip(u, -hw.drive.V_max, hw.drive.V_max)
    assert np.max(np.abs(pw["V"][free] - V[free])) < 1e-9
    balance = pw["P_in"] - (pw["P_copper"] + pw["P_inductor"] + pw["P_gear"] + pw["P_out"])
    assert np.max(np.abs(balance)) <= 1e-9 * np.max(np.abs(pw["P_in"]))
    assert np.any(pw["P_out"] < 0) and np.max(np.abs(pw["P_inductor"])) > 0.005 * np.max(np.abs(pw["P_in"]))
    E = np.array([float(model.energy_function(q, v)[2]) for q, v in zip(states[:, :n], states[:, n:2 * n])])
    torque = motor_torque(i, thd, hw.values()) - friction_torque(thd, hw.values())
    work = np.concatenate([[0.0], np.cumsum(0.5 * dt * (torque * thd)[1:] + 0.5 * dt * (torque * thd)[:-1])])
    assert np.max(np.abs(E - E[0] - work)) < 2e-3 * np.max(np.abs(E - E[0]))
    # a small inductance approaches the resistive motor
    r0 = simulate_fixed_step(model, _volts, 0.5, settings=StepperSettings(dt=dt, substeps=1), hardware=_drive(0.0))
    diffs = [np.max(np.abs(simulate_fixed_step(model, _volts, 0.5, settings=StepperSettings(dt=dt, substeps=1),
                                               hardware=_drive(L)).q[:, 0] - r0.q[:, 0])) for L in (1e-6, 1e-8)]
    assert diffs[1] < 0.03 * diffs[0] and diffs[1] < 1e-4


def test_negative_inductance_is_one_line_naming_the_key():
    with pytest.raises(ParameterError, match=r"^rig file x.toml: motor.L must be in \[0, 10\] \[H\], got -0.001"):
        rig_from_dict({"motor": {"kind": "dc_motor", "L": -1e-3}}, path="x.toml")
