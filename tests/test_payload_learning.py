"""Payload learning during a slew (controllers.payload_learning, issue 22's payload range)."""

import json
import math

import numpy as np
import pytest

from controllers import DesignModel, LQGSettings, make_controller
from controllers.payload_learning import (
    PayloadLearning,
    PayloadLearningSettings,
    identify_payload,
    shapeable_modes,
)
from controllers.scaling import first_mode
from hubbeam_ctrl import Params
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.study.compare import compare
from hubbeam_ctrl.study.compare_values import CompareSettings, PayloadChoice, PlantChoice, ScenarioChoice
from hubbeam_ctrl.study.tasks import Slew

TF = 1.5 * 3.0763          # 1.5 x the 0.5 kg beam's time-optimal 1 rad slew [s] (docs/limit.md)


@pytest.mark.slow
def test_the_hub_rate_identifies_the_payload_by_half_the_slew():
    """The nominal plan open loop on the 0.3 kg beam (FOAM, 10 modes): the 5-mode design models'
    hub rate identifies 0.3 kg within 1 % from the first half of the slew (measured 0.301 kg)."""
    p = Params()
    c = compare(p, Slew(1.0, TF), "openloop", CompareSettings(plant=PlantChoice(plant_params=p.replace(m_t=0.3))))
    r, dt = c.results["openloop"], c.scenario.dt
    k = int(round(0.5 * TF / dt))
    m = identify_payload(p, dt, 5, np.asarray(r.tau[:k]), np.asarray(r.theta_dot[:k + 1]), np.linspace(0, 0.5, 26))
    assert m == pytest.approx(0.3, rel=0.01)


def _meets_the_targets_learning(name: str, payload: float):
    """Table 1's beam designed for 0.1 kg, carrying ``payload``, 1 rad in TF, ``name`` learning the
    payload (``real_time=False``: the same run on any computer): settled within one first-mode
    period after the slew, residual <= 0.1 % of L, final error <= 1e-3 rad. Returns the comparison."""
    p = Params()
    heavy = p.replace(m_t=payload)
    c = compare(p, Slew(1.0, TF), name,
                CompareSettings(plant=PlantChoice(plant_params=heavy),
                                payload=PayloadChoice(payload_learning=PayloadLearningSettings(real_time=False))))
    m = c.metrics[name]
    target = TF + 2 * math.pi / first_mode(DesignModel.build(heavy, 0.0, 0.01, 1))
    assert m["verdict"] == "settled" and m["settling_time_s"] <= target, (m["settling_time_s"], target)
    assert m["residual_pct_of_L"] <= 0.1 and abs(m["final_angle_error_rad"]) <= 1e-3
    return c


@pytest.mark.slow
def test_the_lqr_that_learns_the_payload_settles_the_heavy_beam_in_time():
    """Table 1's beam designed for 0.1 kg carrying 0.5 kg, 1 rad in 4.614 s: the nominal LQR
    settles at 19.2 s leaving 2.3 % of L (docs/limit.md); learning the payload at 25 % and 50 %
    of the slew and re-planning on the nonlinear model of the modes the re-plan's torque grid can
    shape (2, then 3), it settles within one first-mode period after the slew (measured 7.19 s
    against 7.37 s), residual <= 0.1 % of L, within 200 N m. ``real_time=False``: the same run
    on any computer (with the deadline, each re-plan took 0.3-0.7 s of the 1 s allowed)."""
    c = _meets_the_targets_learning("lqr", 0.5)
    assert c.metrics["lqr"]["peak_torque_nm"] <= Params().tau_max * (1 + 1e-9)
    log = c.controllers["lqr"].log
    assert [e["t_s"] for e in log] == pytest.approx([0.25 * TF, 0.5 * TF], abs=0.01)
    assert [e["modes"] for e in log] == [2, 3]
    assert log[-1]["payload_kg"] == pytest.approx(0.5, rel=0.01)
    assert all(e["converged"] and not e["dropped"] for e in log)


def test_a_re_plan_past_its_deadline_is_dropped_and_the_run_is_the_plain_lqrs():
    """With 20 ms allowed, no re-plan converges in time: each is dropped, the controller keeps
    its plan and gain, and the run equals the plain LQR's sample for sample."""
    p = Params()
    task, heavy = Slew(1.0, TF), p.replace(m_t=0.3)
    plain = compare(p, task, "lqr", CompareSettings(plant=PlantChoice(plant_params=heavy)))
    c = compare(p, task, "lqr",
                CompareSettings(plant=PlantChoice(plant_params=heavy),
                                payload=PayloadChoice(payload_learning=PayloadLearningSettings(allowance_s=0.02))))
    log = c.controllers["lqr"].log
    assert len(log) == 2 and all(e["dropped"] and not e["converged"] and e["applied_s"] is None for e in log)
    np.testing.assert_array_equal(np.asarray(c.results["lqr"].tau), np.asarray(plain.results["lqr"].tau))


def test_the_re_plan_keeps_the_modes_its_torque_grid_can_shape():
    """shapeable_modes counts the free-hub modes at or below the grid's Nyquist frequency
    N / (2 T); checked against the frequencies of the design model's state matrix."""
    d = DesignModel.build(Params(m_t=0.5), 0.0, 0.01, 5)
    lam = np.linalg.eigvals(d.A)
    f = np.sort(np.abs(lam[np.abs(lam.imag) > 1e-9].imag))[::2] / (2 * math.pi)     # Hz, one per pair
    for intervals, duration in ((40, 3.46), (40, 2.3), (10, 30.0), (400, 1.0)):
        expected = max(1, int(np.sum(f <= intervals / (2 * duration))))
        assert shapeable_modes(d, intervals, duration) == expected
    assert shapeable_modes(d, 40, 3.46) == 2 and shapeable_modes(d, 40, 2.3) == 3     # 0.37, 2.33, 6.95 Hz


@pytest.mark.slow
def test_the_lqg_learns_the_payload_from_its_filters_estimate(fast_backend):
    """The LQG re-plans from its filter's estimate and hands it to the new payload's filter, which
    does not predict along the 2-3-mode re-plan: on the 0.5 kg beam it settles within its target
    (measured 6.57 s against 7.37 s; 8.57 s predicting along the re-plan; docs/limit.md)."""
    learner = _meets_the_targets_learning("lqg", 0.5).controllers["lqg"]
    assert learner.log[-1]["payload_kg"] == pytest.approx(0.5, rel=0.01)
    assert learner.inner.reference.description.startswith("re-planned") and not learner.inner.predicts_along_plan


def test_the_lqg_filter_predicts_with_the_torque_applied_and_starts_from_a_given_estimate():
    """``applied`` replaces the torque the filter predicts with; ``start_estimate`` pads a
    smaller model's estimate with zeros and predicts from it with the given torque."""
    d = DesignModel.build(Params(), 0.0, 0.01, 3)
    lqg = make_controller("lqg", d, LQGSettings())
    fm, n = lqg.filter_model, lqg.filter_model.n_x // 2
    lqg(0.0, np.array([0.01, 0.2, 3.0]))
    lqg.applied(5.0)
    np.testing.assert_allclose(lqg.x_pred, fm.Ad @ lqg.x_hat + fm.Bd.ravel() * 5.0, rtol=1e-12, atol=1e-15)
    x = np.array([0.3, 0.01, -0.02, 0.5, 0.1, 0.2])            # 2 modes: [theta, q1, q2, rates]
    lqg.start_estimate(x, -7.0)
    padded = np.zeros(fm.n_x)
    padded[:3], padded[n:n + 3] = x[:3], x[3:]
    np.testing.assert_array_equal(lqg.x_hat, padded)
    np.testing.assert_allclose(lqg.x_pred, fm.Ad @ padded - fm.Bd.ravel() * 7.0, rtol=1e-12, atol=1e-15)


def test_bad_settings_and_controllers_are_refused_in_one_line():
    with pytest.raises(ParameterError, match="switch_at must be increasing fractions"):
        PayloadLearningSettings(switch_at=(0.5, 0.25))
    with pytest.raises(ParameterError, match="switch_at"):
        PayloadLearningSettings(switch_at=(0.0,))
    with pytest.raises(ParameterError, match="payload_max_kg"):
        PayloadLearningSettings(payload_min_kg=0.3, payload_max_kg=0.1)
    d = DesignModel.build(Params(), 0.0, 0.01, 2)
    lqg = make_controller("lqg", d, LQGSettings(integral=True))
    with pytest.raises(ParameterError, match="LQG without integral action"):
        PayloadLearning(lqg, PayloadLearningSettings(), 1.0, TF, make_controller)
    with pytest.raises(ParameterError, match="state-feedback"):
        PayloadLearning(make_controller("pd", d), PayloadLearningSettings(), 1.0, TF, make_controller)
    lqr = make_controller("lqr", d)
    with pytest.raises(ParameterError, match="must hold the design's m_t = 0.1 kg"):
        PayloadLearning(lqr, PayloadLearningSettings(payload_min_kg=0.2), 1.0, TF, make_controller)
    with pytest.raises(ParameterError, match="payload_learning works on slew tasks without a rig"):
        compare(None, "spinup", "lqr",
                CompareSettings(scenario=ScenarioChoice(t_f=10.0),
                                payload=PayloadChoice(payload_learning=PayloadLearningSettings())))


@pytest.mark.slow
def test_payload_comparison_and_the_cli_learn_the_payload(tmp_path, capsys, fast_backend):
    """``PayloadChoice(payload_learning=...)`` of ``payload_comparison`` and ``hubbeam compare --learn-payload``: no
    range design, the nominal LQR learns 0.5 kg and settles in time; the rows and the report say
    what it learned (the table's design column is the payload it ended with)."""
    from hubbeam_ctrl.cli.main import main
    from hubbeam_ctrl.study import payload_comparison, write_payload_outputs
    pc = payload_comparison(None, Slew(1.0, TF), "lqr",
                            CompareSettings(payload=PayloadChoice(payload_range=(0.1, 0.5),
                                                                  payload_learning=PayloadLearningSettings(
                                                                      real_time=False))),
                            masses=(0.5,))
    assert pc.designs == {}
    (row,) = pc.rows()
    heavy = Params(m_t=0.5)
    target = TF + 2 * math.pi / first_mode(DesignModel.build(heavy, 0.0, 0.01, 1))
    assert row["verdict"] == "settled" and row["settling_time_s"] <= target
    assert row["design"].startswith("learns the payload: ") and row["design_mass_kg"] == pytest.approx(0.5, rel=0.01)
    assert pc.comparisons[0.5].scenario.t_end == pytest.approx(19.97, abs=0.01)       # the task's, as compare's
    report = write_payload_outputs(pc, tmp_path / "pc")["report"].read_text()
    assert "the nominal design learns the payload during the slew" in report
    rc = main(["compare", "--scenario", "slew", "--tf", str(TF), "--slew-angle", "1", "--controllers", "lqr",
               "--payload-range", "0.1,0.5", "--learn-payload", "--json", "--out", str(tmp_path / "cli")])
    assert rc == 0
    doc = json.loads((tmp_path / "cli" / "payload.json").read_text())
    assert [r["payload_kg"] for r in doc["rows"]] == [0.1, 0.5]
    # the CLI learns in real time (PayloadLearningSettings.real_time): on a loaded machine a re-plan past its
    # allowance is dropped, said in the row's design, and the run keeps its plan (it failed a fresh-clone
    # suite so once, session 25); every re-plan that was kept settles the run
    assert all(r["design"].startswith("learns the payload") for r in doc["rows"])
    assert all(r["verdict"] == "settled" or "(dropped)" in r["design"] for r in doc["rows"]), doc["rows"]


@pytest.mark.parametrize("argv", [["--learn-payload"], ["--learn-payload", "--payload-range", "0,0.5",
                                                        "--scenario", "spinup"]])
def test_the_cli_refuses_learning_without_a_range_or_a_slew(tmp_path, capsys, argv):
    from hubbeam_ctrl.cli.main import main
    rc = main(["compare", *argv, "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1
    assert "--learn-payload needs --payload-range MIN,MAX and --scenario slew" in err


@pytest.mark.slow
def test_a_fast_slew_caps_the_allowance_at_the_next_switch_and_half_the_time_left():
    """The lab arm (1 m aluminium, 0.05 kg nominal, 0-0.2 kg range), 90 degrees in 1.79 s: the 1 s allowance
    would outlast the slew's second half (it stopped the run before); it is capped at the next
    switch (0.45 s away) and at half the time left, and the run completes. The grid's default step
    (a fiftieth of the range, 4 g) identifies the nominal 0.05 kg within 0.5 %."""
    lab = Params(L=1, rho=2700, A=9e-5, E=69e9, I=6.75e-11, J_h=0.02, r=0.05, m_t=0.05, tau_max=1.5)
    c = compare(lab, Slew(math.pi / 2, 1.7930), "lqr",
                CompareSettings(payload=PayloadChoice(
                    payload_learning=PayloadLearningSettings(payload_max_kg=0.2, real_time=False))))
    assert c.metrics["lqr"]["verdict"] == "settled"
    log = c.controllers["lqr"].log
    assert [e["allowance_s"] for e in log] == pytest.approx([0.45, 0.45], abs=0.011)
    assert all(e["applied_s"] <= e["t_s"] + e["allowance_s"] + 0.06 for e in log)
    assert log[0]["payload_kg"] == pytest.approx(0.05, rel=0.005)


def test_the_held_feedforward_stays_within_the_drive_at_full_torque():
    """A feedforward at full torque exceeds tau_max by round-off (it is differenced from the plan's
    torque integral); the held prefix is what the drive plays, within tau_max. Before, the
    re-plan refused it ("hold must be ... within +-200 N m") and the paper's Eq. 44 slew with
    0.5 kg stopped the learning LQG's run."""
    from controllers import Reference
    from controllers.payload_learning import _held_prefix
    n = 100
    torque = np.full(n, 200.0 * (1 + 1e-11))
    torque[60:] = -200.0 * (1 + 1e-11)
    ref = Reference(0.01, np.zeros(n), np.zeros(n), np.zeros(n), torque, "full torque")
    edges, hold = _held_prefix(ref, 40, 0.05, 0.3, 200.0)
    assert list(edges) == [40, 45, 50, 55, 60, 65, 70]
    assert hold == [200.0, 200.0, 200.0, 200.0, -200.0, -200.0]
