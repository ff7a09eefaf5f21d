"""Units are the drive's (issue 36, Build 4): volts and newton-metres never share a metric.

Every metric of :data:`~hubbeam_ctrl.study.metrics.METRIC_UNITS` is checked on a run of the
DC-motor rig ``servo_link`` (command in volts) and on a torque-source run (command in N m):
each metric whose unit is N m equals the hub torque computed here from the recorded command
and hub rate by the drive's own equations, each metric in V the command clipped to
``V_max``, each in A the current, and each in the command's unit (``"command"``) the command.
"""

import math

import numpy as np
import pytest

from hubbeam_ctrl import Params
from hubbeam_ctrl.plant.rig import load_rig
from hubbeam_ctrl.sim import ClosedLoopSettings, simulate_closed_loop
from hubbeam_ctrl.sim.hardware import Hardware
from hubbeam_ctrl.study.drive_figures import AT_LIMIT, drive_metrics, drive_of
from hubbeam_ctrl.study.metrics import METRIC_UNITS, closed_loop_metrics

SERVO = load_rig("servo_link")
T_F = 0.5
TARGET = 0.5                       # rad


class _PD:
    """A PD on the hub angle with a gain large enough to hit the command limit at the start."""

    measurement = "state"

    def __init__(self, kp, kd, limit, name, dt):
        self.kp, self.kd, self.limit, self.name, self.dt = kp, kd, limit, name, dt

    def reset(self):
        pass

    def __call__(self, t, y):
        return float(np.clip(self.kp * (TARGET - y[0]) - self.kd * y[len(y) // 2], -self.limit, self.limit))


def _reference():
    return (lambda t: TARGET * np.ones_like(np.asarray(t, dtype=float)),
            lambda t: np.zeros_like(np.asarray(t, dtype=float)))


@pytest.fixture(scope="module")
def dc_run():
    """servo_link: a PD commanding volts (40 V/rad: 20 V at the start, clipped to 10 V)."""
    P = SERVO.plant_params.replace(n_axial=1, n_transverse=2)
    res = simulate_closed_loop("foam", _PD(40.0, 1.0, SERVO.drive.V_max, "pd_volts", 1e-3), 6.0, params=P,
                               hardware=Hardware.from_rig(SERVO), settings=ClosedLoopSettings(dt=1e-3),
                               reference=_reference())
    return res, closed_loop_metrics(res, T_F, residual_delay=1.0, tau_max=SERVO.beam.tau_max)


@pytest.fixture(scope="module")
def torque_run():
    """Table 1's beam on the ideal torque source: a PD commanding N m, clipped at 200 N m."""
    P = Params(n_axial=1, n_transverse=2)
    res = simulate_closed_loop("foam", _PD(2000.0, 400.0, 200.0, "pd_torque", 1e-2), 6.0, params=P,
                               settings=ClosedLoopSettings(dt=1e-2), reference=_reference())
    return res, closed_loop_metrics(res, T_F, residual_delay=1.0, tau_max=200.0)


def _expected(res, drive):
    """The drive's quantities at every sample, from the recorded command and hub rate."""
    u, thd = res.tau, res.v[:, 0]
    if drive.is_ideal:
        return {"N m": np.abs(u), "command": np.abs(u)}
    d = drive
    V = np.clip(u, -d.V_max, d.V_max)
    i = np.clip((V - d.k_e * d.N * thd) / d.R, -d.I_max, d.I_max)
    # the gear passes eta_forward while motoring (i thd >= 0), 1 / eta_backward back-driven, the
    # switch made continuous over -thd sign(i) / v_eps in [0, ~2] (docs/rig.md)
    x = np.clip(-thd * np.where(i >= 0, 1.0, -1.0) / SERVO.friction.v_eps, 0.0, 50.0)
    e = d.eta_forward + (1.0 / d.eta_backward - d.eta_forward) * np.tanh(x) ** 2
    return {"V": np.abs(V), "A": np.abs(i), "N m": np.abs(d.N * d.eta_motor * d.k_t * i * e), "command": np.abs(u)}


@pytest.mark.parametrize("which", ["dc", "torque"])
def test_every_metric_holds_its_own_unit(which, dc_run, torque_run):
    res, m = dc_run if which == "dc" else torque_run
    drive = drive_of(res)
    assert drive.is_ideal == (which == "torque")
    assert m["command_unit"] == ("N m" if which == "torque" else "V")
    ref = _expected(res, drive)
    u = res.tau
    checked = []
    for key, (unit, _) in METRIC_UNITS.items():
        # a unit spelled another way ("Nm", "volt", "N.m") would slip past the checks below
        assert unit.replace(" ", "").lower() not in ("nm", "n.m", "volt", "volts", "amp", "ampere") or \
            unit in ("N m",), (key, unit)
        value = m[key]
        if value is None and unit in ("V", "A"):
            assert which == "torque", key          # no voltage or current on a torque source
            continue
        if unit == "N m":
            # every N m metric needs its independent reference here: a new one fails until it has one
            assert key in ("peak_hub_torque_nm", "peak_torque_nm"), f"no reference for the N m metric {key}"
            assert value == pytest.approx(np.max(ref["N m"]), rel=1e-12), key
            if which == "dc":       # braking at the current limit: N k_t I_max / eta_backward at most
                d = drive
                assert value <= d.N * d.k_t * d.I_max / d.eta_backward * (1 + 1e-12), key
                assert value != pytest.approx(m["peak_command"], rel=1e-2), key     # not the volts
            checked.append(key)
        elif unit == "V":
            assert which == "dc", key
            assert value == pytest.approx(np.max(ref["V"]), rel=1e-12) and value <= SERVO.drive.V_max, key
            checked.append(key)
        elif unit == "A":
            assert which == "dc", key
            assert value == pytest.approx(np.max(ref["A"]), rel=1e-12) and value <= SERVO.drive.I_max, key
            checked.append(key)
        elif unit == "command":
            expect = {"peak_command": np.max(np.abs(u)), "peak_command_step": np.max(np.abs(np.diff(u)))}.get(key)
            assert expect is not None, f"no reference for the command-unit metric {key}"
            assert value == pytest.approx(expect, rel=1e-12), key
            checked.append(key)
        elif unit == "N^2 m^2 s":
            assert key == "torque_squared_integral_n2m2s", f"no reference for the N^2 m^2 s metric {key}"
            dt = float(res.t[1] - res.t[0])
            assert value == pytest.approx(np.sum(ref["N m"][:-1] ** 2) * dt, rel=1e-12), key
            checked.append(key)
    # on a torque source the voltage and current metrics are absent (None), not torques
    if which == "torque":
        assert m["peak_voltage_v"] is None and m["peak_current_a"] is None
        assert m["within_drive_limits"] is True and m["within_torque_limit"] is True
        assert "within_voltage_limit" not in m
    else:
        # volts within V_max and N m within the drive's torque: the old check (volts against
        # tau_max = 1.86 N m) said "no" for every run that commanded more than 1.86 V
        assert m["peak_command"] == pytest.approx(10.0, rel=1e-12) and m["peak_command"] > SERVO.beam.tau_max
        assert m["peak_voltage_v"] <= 10.0 and m["within_voltage_limit"] and m["within_current_limit"]
        assert m["peak_hub_torque_nm"] <= SERVO.drive.peak_hub_torque * (1 + 1e-12)
        assert m["within_drive_limits"] is True
    assert {"peak_hub_torque_nm", "peak_torque_nm", "peak_command", "peak_command_step",
            "torque_squared_integral_n2m2s"} <= set(checked)
    if which == "dc":
        assert {"peak_voltage_v", "peak_current_a"} <= set(checked)


def test_dc_motor_hub_torque_at_the_start_is_the_stall_torque(dc_run):
    """At t = 0 the hub is at rest and the command is 10 V: the hub torque is the stall torque
    0.9 * 70 * 7.68e-3 * 10 / 2.6 = 1.861 N m, in N m (not 10)."""
    res, m = dc_run
    one = drive_metrics(res.t[:1], res.tau[:1], res.v[:1, 0], T_F, drive_of(res))
    assert res.tau[0] == 10.0
    assert one["peak_hub_torque_nm"] == pytest.approx(0.9 * 70 * 7.68e-3 * 10 / 2.6, rel=1e-12)
    assert one["peak_current_a"] == pytest.approx(10 / 2.6, rel=1e-12)
    assert one["peak_voltage_v"] == 10.0


@pytest.mark.parametrize("which", ["dc", "torque"])
def test_command_rate_and_time_at_the_limit(which, dc_run, torque_run):
    res, m = dc_run if which == "dc" else torque_run
    limit = SERVO.drive.V_max if which == "dc" else 200.0
    dt = float(res.t[1] - res.t[0])
    at = np.abs(res.tau) >= (1 - AT_LIMIT) * limit
    assert at[0]                                  # the PD's first command is clipped
    assert m["time_at_limit_s"] == pytest.approx(np.count_nonzero(at) * dt, rel=1e-12)
    assert m["time_at_limit_slew_s"] == pytest.approx(np.count_nonzero(at & (res.t <= T_F + 1e-9)) * dt, rel=1e-12)
    assert m["time_at_limit_s"] >= dt and m["time_at_limit_slew_s"] <= m["time_at_limit_s"]
    assert m["peak_command_step"] == pytest.approx(np.max(np.abs(np.diff(res.tau))), rel=1e-12)
    assert m["peak_command_step"] <= 2 * limit
    assert math.isfinite(m["torque_saturated_fraction"])
