"""Issue 38, item 5: what voltage-in records determine of a DC-motor drive (calibrate.drive).

The servo link's drive: the hub torque is ``e N k_t (V - k_e N thd) / R`` below the current
limit, so k_t and R enter only as k_t / R; the sensors' sensitivity to log k_t is minus that to
log R (a null direction of the fit's Jacobian), unless the current reaches I_max. A fit asked
for both fixes R at the given (data sheet) value, says so, and returns k_t / R.
"""

import numpy as np
import pytest

from hubbeam_ctrl.calibrate import (
    FitSettings,
    ModelSettings,
    drive_plan,
    excitation,
    fit_rig,
    peak_current,
    resolve_fields,
    set_fields,
    simulate_sensors,
    synthetic_record,
)
from hubbeam_ctrl.plant.rig import load_rig

SENSORS = ("theta", "root_moment")
TWO = ModelSettings(n_transverse=2)


def _rig():
    base = load_rig("servo_link")
    return base.replace(sensors=base.sensors.replace(strain_noise=1e-3))


def _truth(rig):
    d = rig.drive
    return rig.replace(drive=d.replace(k_t=1.05 * d.k_t, R=1.08 * d.R, k_e=0.95 * d.k_e))


@pytest.fixture(scope="module")
def chirp(fast_backend_module):
    return excitation(_rig(), "chirp", 4.0)


def _log_sensitivity(rig, ex, path, h=1e-4):
    f = resolve_fields([path], rig)
    v = f[0].get(rig)
    ys = [simulate_sensors(set_fields(rig, f, [v * np.exp(s * h)]), ex.t, ex.input, SENSORS, TWO) for s in (1, -1)]
    return np.concatenate([(ys[0][k] - ys[1][k]) / (2 * h) for k in SENSORS])


def test_kt_and_r_enter_only_as_their_ratio(chirp):
    rig = _rig()
    # the excitation's current stays below I_max: d y / d log k_t = - d y / d log R
    assert peak_current(rig, [chirp]) < 0.95 * rig.drive.I_max
    jk, jr = _log_sensitivity(rig, chirp, "motor.k_t"), _log_sensitivity(rig, chirp, "motor.R")
    assert np.linalg.norm(jk + jr) < 1e-6 * np.linalg.norm(jk)
    fields, plan = drive_plan(rig, [chirp], resolve_fields("E,motor.k_t,motor.R,motor.k_e", rig))
    assert [f.path for f in fields] == ["beam.E", "motor.k_t", "motor.k_e"]
    assert plan.fixed["motor.R"]["value"] == rig.drive.R and "k_t / R" in plan.fixed["motor.R"]["reason"]
    # a current limit the records reach separates them: R stays fitted
    peak = peak_current(rig, [chirp])         # hubbeam excite keeps the tip within 0.05 L
    low = rig.replace(drive=rig.drive.replace(I_max=0.5 * peak))
    assert peak_current(low, [chirp]) > low.drive.I_max
    jk, jr = _log_sensitivity(low, chirp, "motor.k_t"), _log_sensitivity(low, chirp, "motor.R")
    assert np.linalg.norm(jk + jr) > 0.05 * np.linalg.norm(jk)
    fields, plan = drive_plan(low, [chirp], resolve_fields("motor.k_t,motor.R", low))
    assert len(fields) == 2 and not plan.fixed


def test_ideal_gear_fixes_viscous_with_k_e(chirp):
    # without Coulomb friction the hub never sticks, and the sensitivities are smooth
    rig = _rig().replace(friction=_rig().friction.replace(coulomb=0.0))
    ideal = rig.replace(drive=rig.drive.replace(eta_forward=1.0, eta_backward=1.0))
    # with e = 1, k_e and viscous enter only as N^2 k_t k_e / R + c_v: their sensitivities are proportional
    je, jv = _log_sensitivity(ideal, chirp, "motor.k_e"), _log_sensitivity(ideal, chirp, "viscous")
    cos = abs(je @ jv) / (np.linalg.norm(je) * np.linalg.norm(jv))
    assert cos > 1 - 1e-8
    fields, plan = drive_plan(ideal, [chirp], resolve_fields("motor.k_e,viscous", ideal))
    assert [f.path for f in fields] == ["motor.k_e"] and "friction.viscous" in plan.fixed
    # the servo's gear (0.9 driving, 0.69 back-driven) separates them: both stay fitted
    je, jv = _log_sensitivity(rig, chirp, "motor.k_e"), _log_sensitivity(rig, chirp, "viscous")
    assert abs(je @ jv) / (np.linalg.norm(je) * np.linalg.norm(jv)) < 1 - 1e-5
    assert len(drive_plan(rig, [chirp], resolve_fields("motor.k_e,viscous", rig))[0]) == 2


@pytest.mark.slow
def test_fit_returns_kt_over_r_and_says_r_is_fixed(chirp):
    rig = _rig()
    truth = _truth(rig)
    rec = synthetic_record(truth, chirp.t, chirp.input, seed=3, source="chirp")
    res = fit_rig(rig, [rec], "motor.k_t,motor.R,motor.k_e", settings=FitSettings(plant_modes=2, rough_intervals=False),
                  progress=False)
    assert res.names == ["motor.k_t", "motor.k_e"]
    assert res.rig.drive.R == rig.drive.R                  # the data sheet's, not fitted
    ratio = res.drive.values["motor.k_t / motor.R"]
    true_ratio = truth.drive.k_t / truth.drive.R
    assert abs(ratio["value"] / true_ratio - 1) < 2e-3     # k_t alone is 8 % off (R is): the ratio is not
    assert abs(res.estimate[0] / truth.drive.k_t - 1) > 0.05
    assert abs(res.estimate[1] / truth.drive.k_e - 1) < 2e-3
    assert any(w.startswith("motor.R is not identifiable") for w in res.warnings)
    out = res.to_dict()
    assert out["drive"]["fixed"]["motor.R"]["value"] == rig.drive.R
    assert "determined motor.k_t / motor.R" in res.summary()


def test_the_benchmarked_drive_identifiability():
    """``benchmarks/bench_calibrate.py --seeds 2 --fisher``: the null directions its Fisher information
    finds, and item 5's fits from ``hubbeam excite``'s default records against the issue's targets
    for the fields they reach (viscous friction and J_h are reported, not met: docs/calibration.md)."""
    import json

    from tests.conftest import ROOT
    latest = sorted((ROOT / "benchmarks" / "results").glob("bench_calibrate_2*.json"))[-1]
    run = json.loads(latest.read_text())
    servo, ideal = run["drive_fisher"]["servo_gear"], run["drive_fisher"]["ideal_gear"]
    for fisher in (servo, ideal):          # k_t and R only as k_t / R: one null direction d log k_t = d log R
        sv = fisher["singular_values"]
        assert sv[-1] < 1e-10 * sv[0]
        d = fisher["weakest_directions"][0]["direction"]
        assert abs(d["motor.k_t"]) == 1.0 and abs(d["motor.R"] - d["motor.k_t"]) < 1e-2
    # the servo's gear separates k_e from viscous (weakly), an ideal one does not
    assert servo["singular_values"][-2] > 1e-4 * servo["singular_values"][0]
    assert ideal["singular_values"][-2] < 1e-9 * ideal["singular_values"][0]
    rows = run["servo_from_records"]["replicates"]
    assert rows and all(r["fixed"] == {"motor.R": 2.6} for r in rows)
    for r in rows:
        err = r["error_percent"]
        assert r["status"] == "converged"
        assert abs(err["E"]) < 1.0 and abs(err["coulomb"]) < 10.0 and abs(err["damping"]) < 15.0
        assert abs(err["motor.k_t / motor.R"]) < 2.0 and abs(err["motor.k_e"]) < 2.0


@pytest.mark.slow
def test_identify_reports_the_fixed_resistance(tmp_path, chirp, capsys):
    """``hubbeam identify --fit motor.k_t,motor.R``: R fixed and said so, k_t / R in result.json and report.md."""
    import json

    from hubbeam_ctrl.calibrate import save_record
    from hubbeam_ctrl.cli.main import main
    from hubbeam_ctrl.plant.rig import save_rig
    rig = _rig()
    truth = rig.replace(drive=_truth(rig).drive.replace(k_e=rig.drive.k_e))      # k_t +5 %, R +8 %
    save_record(synthetic_record(truth, chirp.t, chirp.input, seed=1), tmp_path / "rec.csv")
    save_rig(rig, tmp_path / "rig.toml")
    out = tmp_path / "out"
    assert main(["identify", str(tmp_path / "rec.csv"), "--rig", str(tmp_path / "rig.toml"), "--fit",
                 "motor.k_t,motor.R", "--plant-modes", "2", "--out", str(out), "--json"]) == 0
    result = json.loads((out / "result.json").read_text())
    assert list(result["estimates"]) == ["motor.k_t"]
    assert result["drive"]["fixed"]["motor.R"]["value"] == rig.drive.R
    ratio = result["drive"]["combinations"]["motor.k_t / motor.R"]["value"]
    assert abs(ratio / (truth.drive.k_t / truth.drive.R) - 1) < 1e-3
    report = (out / "report.md").read_text()
    assert "## Drive constants" in report and "- fixed motor.R = 2.6 ohm" in report
    assert "determined motor.k_t / motor.R" in report
    capsys.readouterr()
