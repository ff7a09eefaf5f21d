"""A torque law behind a DC drive whose voltage clips at V_max (issue 36 item 3: a default design that
bangs between its limits is a defect).

Reference: servo_payload's default LQR at 1.1 T* on the bounded planned reference (as
tests/test_servo_payload_range.py makes that run). At 12-13 rad/s the back-EMF takes about 7 of the
10 V, so the voltage the torque law asks for clips and the hub gets a fraction of the law's torque.
A filter that predicts with the law's torque winds up: the command alternated sample by sample
between +10 V and 0.2-1 V (peak step 9.8 V, 98 % of V_max). Predicting with the torque that V_max
gives (:meth:`hubbeam_ctrl.sim.hardware.Hardware.clipped_torque`, :class:`controllers.drive.VoltageCommand`)
removes the alternation; the generated C does the same.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import until_first_stick

from hubbeam_ctrl.deploy import NO_COMPILER, CController, compile_c, compiler, to_c
from hubbeam_ctrl.plant.rig import load_rig
from hubbeam_ctrl.sim import simulate_closed_loop
from hubbeam_ctrl.sim.hardware import Hardware
from hubbeam_ctrl.study import Slew, compare
from hubbeam_ctrl.study.compare_values import CompareSettings, DesignChoice

#: servo_payload's time-optimal 90 degree slew [s] (tests/test_servo_payload_range.py)
T_STAR = 0.4169
RIG = load_rig("servo_payload")


def _run():
    return compare(RIG, Slew(math.pi / 2, 1.1 * T_STAR), "lqr",
                   CompareSettings(design=DesignChoice(reference="planned")))


def _chatter(volts, v_max) -> int:
    """Samples at the limit followed by one below half of it (the wound-up filter's alternation)."""
    v = np.abs(np.asarray(volts))
    return int(np.sum((v[:-1] >= v_max) & (v[1:] < 0.5 * v_max)))


def test_clipped_torque_is_the_torque_of_v_max_through_the_same_drive_model():
    hw = Hardware.from_rig(RIG)
    v_max = RIG.drive.V_max
    for thd in (12.0, -3.0, 0.0):
        for tau in (RIG.beam.tau_max, -RIG.beam.tau_max):
            v = hw.voltage_for_torque(tau, thd)
            given = hw.clipped_torque(tau, thd)
            if abs(v) < v_max:                         # within the limit: nothing to say
                assert given is None
                continue
            assert abs(given) < abs(tau) and math.copysign(1.0, given) in (math.copysign(1.0, tau), -1.0, 1.0)
            # the torque V_max gives, back through the inverse: V_max itself (unclipped)
            assert hw.voltage_for_torque(given * (1 - 1e-9), thd) == pytest.approx(v, abs=1e-6 * v_max)
    assert hw.clipped_torque(0.1, 0.0) is None
    assert Hardware.from_rig(load_rig("accel_link")).clipped_torque(2.0, 10.0) is None     # a torque drive


@pytest.mark.slow
def test_the_lqr_behind_a_clipping_drive_does_not_alternate_between_the_limit_and_a_fraction(monkeypatch):
    v_max = RIG.drive.V_max
    c = _run()
    m, volts = c.metrics["lqr"], c.results["lqr"].tau
    with monkeypatch.context() as mp:        # the filter predicting with the law's torque, as before
        mp.setattr(Hardware, "clipped_torque", lambda self, tau, thd: None)
        old = _run()
    m0, volts0 = old.metrics["lqr"], old.results["lqr"].tau
    print(f"peak step {m0['peak_command_step']:.2f} -> {m['peak_command_step']:.2f} V, chatter "
          f"{_chatter(volts0, v_max)} -> {_chatter(volts, v_max)}, at the limit {m0['time_at_limit_s']:.3f} -> "
          f"{m['time_at_limit_s']:.3f} s, settled in {m0['settling_time_s']:.3f} -> {m['settling_time_s']:.3f} s")
    assert m0["peak_command_step"] > 0.95 * v_max and _chatter(volts0, v_max) >= 4    # measured 9.80 V, 5
    assert m["peak_command_step"] <= 0.65 * v_max                                       # measured 5.99 V
    assert _chatter(volts, v_max) <= 1                                                  # measured 1
    assert m["time_at_limit_s"] < m0["time_at_limit_s"]                                 # 0.053 s against 0.063 s
    assert m0["verdict"] == m["verdict"] == "settled"
    assert m["settling_time_s"] <= 1.05 * m0["settling_time_s"]                         # 1.709 s against 1.654 s
    assert m["residual_tip_max_m"] <= m0["residual_tip_max_m"]


@pytest.mark.slow
@pytest.mark.skipif(compiler() is None, reason=NO_COMPILER)
def test_the_generated_c_predicts_with_the_clipped_torque_too(tmp_path):
    c = _run()
    sc, py_ctrl, py = c.scenario, c.controllers["lqr"], c.results["lqr"]
    hw = Hardware.from_rig(RIG)
    code = to_c(py_ctrl, tmp_path / "lqr")
    assert "clipped_torque(inst, " in code.source
    cc = CController(compile_c(code, "-O2", tmp_path), code, py_ctrl)
    run = simulate_closed_loop(c.plant, cc, sc.t_end, settings=sc.closed_loop_settings(),
                               reference=(sc.reference.theta_at, sc.reference.theta_dot_at), hardware=hw)
    moving = until_first_stick(py, sc.t_f, RIG)
    at_limit = int(np.sum(np.abs(py.tau[moving]) >= RIG.drive.V_max))
    err = np.max(np.abs(run.tau - py.tau)[moving]) / RIG.drive.V_max
    print(f"servo_payload 1.1 T* lqr: {at_limit} samples at V_max, max |C - Python| / V_max = {err:.2e}")
    assert at_limit > 20                                   # the clipping stage was at work
    assert err <= 1e-9, err
