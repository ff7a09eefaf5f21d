"""The closed loop's substep rule is set by the accuracy the verdict needs (issue 28, item 4).

``ClosedLoopSettings.frequency_tolerance`` (1 %) picks the integration step of the closed loop
from the evaluation plant's highest bending mode: 21 substeps per 10 ms sample on Table 1's
beam (10 modes) and 67 on the lab arm (8 modes), where 0.5 % asked 30 and 96. What the rule
must keep is the verdict's input, the residual vibration: here it stays within 2 % of the
30-substep run on both beams, for the two settled feedback laws whose small residuals move
most with the step (LQR, MPC), on short horizons; and on the servo_link rig (drive, friction,
encoder, half a sample of delay, 12 modes up to 1 kHz) the verdict equals a converged run's.
2 % was tried and kept the beams' residuals within 2 %, but on the rig it moved the LQR's
settling time from 0.63 s to 0.86 s and drove the command into the 10 V limit (15 substeps
per 1 ms sample; 21, 29, 46 and 65 give 0.63 s and 4.2 V).

The evaluation plants carry 0.5 % structural damping: undamped, the modes above the Nyquist
frequency ring through the residual window for ever and the largest ``|v_tip|`` there depends
on their phases, which any step changes (the lab arm's MPC moves 4 % from 30 to 31 substeps
while its rms moves 0.2 %); damped, the residuals converge smoothly with the step. The full
default comparisons, undamped and damped, every count from 8 to 47:
``benchmarks/bench_substeps.py`` (results in ``benchmarks/results/bench_substeps_*``).
"""

from __future__ import annotations

import pytest

from hubbeam_ctrl.plant.modal import modal_analysis
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.sim.closedloop import ClosedLoopSettings
from hubbeam_ctrl.sim.evaluation import evaluation_plant
from hubbeam_ctrl.sim.stepper import substep_rule
from hubbeam_ctrl.study.compare import compare
from hubbeam_ctrl.study.compare_values import CompareSettings, RunChoice, compare_arguments
from hubbeam_ctrl.study.tasks import Slew

LAB_ARM = Params(L=1, rho=2700, A=9e-5, E=69e9, I=6.75e-11, J_h=0.02, r=0.05, m_t=0.05, tau_max=1.5)
#: beam -> (parameters, task, t_end [s]): the default slews, ended 1 s (paper) or 2.2 s (lab arm) into
#: their residual windows rather than at 30 s
BEAMS = {"paper": (Params(), {}, 16.0), "lab": (LAB_ARM, {"scenario": Slew(1.5708, 1.2)}, 4.0)}


@pytest.mark.parametrize("beam, rule, before", [("paper", 21, 30), ("lab", 67, 96)])
def test_rule_on_the_default_evaluation_plants(beam, rule, before):
    params = BEAMS[beam][0]
    ev = evaluation_plant("foam", params, 0.01, 5)
    f = modal_analysis("foam", 0.0, "free", ev.params).bending_hz
    tolerance = ClosedLoopSettings().frequency_tolerance
    assert tolerance == 0.01
    r = substep_rule(f, 0.01, tolerance=tolerance)
    assert r.substeps == rule and abs(r.frequency_error) <= tolerance
    assert substep_rule(f, 0.01, tolerance=0.005).substeps == before


def _residuals(beam: str, substeps: int | None, controllers: str = "lqr,mpc") -> dict:
    params, task, t_end = BEAMS[beam]
    # the rigid reference on the lab arm: its planned slew (the default since issue 22) leaves
    # 3e-6 m, 30 times less, where a 4 % change is 1.4e-7 m and says nothing about the verdict
    c = compare(**compare_arguments(params=params, plant_params=params.replace(damping_ratio=0.005),
                                    controllers=controllers, t_end=t_end,
                                    sim_settings={"substeps": substeps} if substeps else None, reference="rigid",
                                    **task))
    return {n: (m["residual_tip_max_m"], c.results[n].settings["substeps"]) for n, m in c.metrics.items()}


@pytest.mark.parametrize("beam, rule", [("paper", 21), ("lab", 67)])
def test_residuals_at_the_rule_stay_within_two_percent_of_thirty_substeps(beam, rule, fast_backend):
    ref = _residuals(beam, 30)
    got = _residuals(beam, None)                    # the rule's count
    for name, (value, substeps) in got.items():
        assert substeps == rule
        assert value == pytest.approx(ref[name][0], rel=0.02), name
    if beam == "lab":                               # the check has teeth: 12 substeps move LQR by 4.1 %
        coarse = _residuals(beam, 12, "lqr")
        assert abs(coarse["lqr"][0] / ref["lqr"][0] - 1) > 0.02


@pytest.mark.slow
def test_the_rigs_verdict_at_the_rule_equals_a_converged_runs(fast_backend):
    """servo_link, 90 degrees at 1.5 x its time-optimal slew (0.4531 s), LQR with all defaults:
    at the rule's step the settling time and residual equal a run at a 0.2 % tolerance (46
    substeps). (At 2 %, 15 substeps, it settled at 0.86 s with the command at the 10 V limit.)"""
    import math

    from hubbeam_ctrl.plant.rig import load_rig
    rig = load_rig("servo_link")

    def run(tolerance):
        sim = ClosedLoopSettings() if tolerance is None else ClosedLoopSettings(frequency_tolerance=tolerance)
        c = compare(rig, Slew(math.pi / 2, 0.4531), "lqr", CompareSettings(run=RunChoice(t_end=1.0, sim_settings=sim)))
        m = c.metrics["lqr"]
        return m["settling_time_s"], m["residual_tip_max_m"], max(abs(float(v)) for v in c.results["lqr"].tau)

    ref, rule = run(0.002), run(None)
    assert rule[0] == pytest.approx(ref[0], abs=2 * rig.timing.dt)
    assert rule[1] == pytest.approx(ref[1], rel=0.05)
    assert rule[2] < 0.6 * rig.drive.V_max                    # about 4.2 V
