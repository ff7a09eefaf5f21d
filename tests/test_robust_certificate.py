"""Issue 39: the uncertainty set as a value, the worst-case certificate over it, and its check
by nonlinear runs at the worst plant found."""

from __future__ import annotations

import json

import numpy as np
import pytest
import tomllib

from hubbeam_ctrl import Params
from hubbeam_ctrl.cli.main import main
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.rig import Rig, load_rig, rig_from_dict, rig_to_toml
from hubbeam_ctrl.plant.uncertainty import Uncertainty
from hubbeam_ctrl.study.certificate import certify, loop_matrix
from hubbeam_ctrl.study.compare import compare
from hubbeam_ctrl.study.robust_check import run_at
from hubbeam_ctrl.study.worst_case import RADIUS_MARGIN, certify_set

PAYLOAD = Uncertainty.from_table({"m_t": (0.0, 0.5), "damping": (0.0005, 0.0005)})


# --- the set as a value ---------------------------------------------------------------

def test_uncertainty_table_round_trips_through_the_rig_file():
    rig = load_rig("servo_link")
    u = Uncertainty.from_table({"m_t": [0.0, 0.03], "E": [185e9, 200e9], "damping": [0.0005, 0.034],
                                "delay": [0.3, 0.7], "k_t": [7e-3, 8e-3]})
    r2 = rig.replace(uncertainty=u)
    back = rig_from_dict(tomllib.loads(rig_to_toml(r2)))
    assert back == r2
    assert back.uncertainty.names == ("m_t", "E", "damping", "k_t", "delay")    # the module's order
    at = u.apply(rig, u.values_at([1.0, 0.0, 0.0, 1.0, 1.0]))
    assert at.beam.m_t == 0.03 and at.beam.E == 185e9 and at.drive.k_t == 8e-3 and at.timing.delay == 0.7
    assert at.plant_params.damping_ratios[:3] == (0.0005, 0.0005, 0.0005)
    assert not at.uncertainty.is_set            # a point of the set is exact


@pytest.mark.parametrize("table, message", [
    ({"m_t": [1, 0]}, "uncertainty.m_t must have lo <= hi"),
    ({"foo": [1, 2]}, "unknown key uncertainty.foo"),
    ({"m_t": "x"}, "uncertainty.m_t must be a range [lo, hi]"),
    ({"delay": [0, 2]}, "uncertainty.delay = [0, 2] does not fit the rig"),
    ({"E": [1, float("inf")]}, "uncertainty.E must be finite"),
])
def test_bad_sets_are_refused_naming_the_key(table, message):
    with pytest.raises(ParameterError, match=message.replace("[", r"\[").replace("]", r"\]")):
        load_rig("servo_link").replace(uncertainty=Uncertainty.from_table(table))


def test_motor_constants_need_a_dc_motor():
    with pytest.raises(ParameterError, match="uncertainty.k_t needs a DC motor"):
        Rig().replace(uncertainty=Uncertainty.from_table({"k_t": (0.1, 0.2)}))


def test_calibration_intervals_become_a_set():
    u = Uncertainty.from_intervals({"E": (6.7e10, 7.0e10), "J_h": (190.0, 210.0), "friction.viscous": (0.1, 0.2),
                                    "motor.k_t": (7e-3, 8e-3), "not_a_field": (1, 2)})
    assert u.names == ("E", "J_h", "viscous", "k_t")


# --- the certificate -------------------------------------------------------------------

@pytest.fixture(scope="module")
def table1():
    """Table 1's slew, LQR and LQG designed at the nominal 0.1 kg, on a rig carrying the set."""
    rig = Rig(beam=Params(), uncertainty=PAYLOAD)
    return rig, compare(rig, "slew", ["openloop", "lqr", "lqg"])


@pytest.mark.slow
def test_a_zero_width_set_is_the_linear_certificate(table1):
    rig, cmp = table1
    ctrl = cmp.controllers["lqr"]
    point = Uncertainty.from_table({"m_t": 0.1, "damping": 0.0005})
    wc = certify_set(ctrl, rig, point, plant_modes=cmp.plant.modes, margins=False)
    ref = certify(ctrl, cmp.plant.params.replace(damping_ratio=0.0005), name="lqr")
    assert wc.worst.radius == pytest.approx(ref.worst.spectral_radius, abs=1e-12)


def test_the_search_finds_the_worst_payload_of_a_dense_scan(table1):
    """The search (3 grid points, local climbs) against 41 payloads evaluated directly."""
    rig, cmp = table1
    for name in ("lqr", "lqg"):
        ctrl, wc = cmp.controllers[name], cmp.robust[name]
        dense = []
        for m in np.linspace(0.0, 0.5, 41):
            p = cmp.plant.params.replace(m_t=float(m))
            dense.append(max(np.max(np.abs(np.linalg.eigvals(loop_matrix(ctrl, p, s, 0.0005)[0])))
                             for s in (0.0, wc.worst.spin)))
        assert wc.worst.radius >= max(dense) - 1e-7, name
        assert wc.evaluations < 41


def test_nominal_lqr_is_certified_and_nominal_lqg_fails_at_the_heavy_end(table1):
    """Table 1, 0-0.5 kg at a 0.05 % damping floor: the nominal LQR decays everywhere; the nominal
    LQG's filter pumps mode 6 at 0.5 kg, and the certificate names that plant."""
    _, cmp = table1
    lqr, lqg = cmp.robust["lqr"], cmp.robust["lqg"]
    assert lqr.certified and lqr.worst.radius <= 1 - RADIUS_MARGIN
    assert lqr.undamped_radius > lqr.worst.radius            # the floor matters: reported
    assert not lqg.certified
    assert lqg.worst.values["m_t"] == pytest.approx(0.5)
    assert "mode" in lqg.worst_source
    assert cmp.metrics["lqg"]["robust_verdict"] == "not certified"


def test_the_worst_plant_found_agrees_with_a_nonlinear_run(table1, fast_backend):
    rig, cmp = table1
    bare = rig.replace(uncertainty=Uncertainty())
    bad = run_at(cmp, "lqg", bare, cmp.robust["lqg"].worst.values, PAYLOAD)
    assert bad["verdict"] == "unstable"
    good = run_at(cmp, "lqr", bare, cmp.robust["lqr"].worst.values, PAYLOAD)
    assert good["verdict"] == "settled" and good["residual_pct_of_openloop"] <= 2.0
    assert good["peak_torque_nm"] <= 200.0 + 1e-9


# --- the command -----------------------------------------------------------------------

@pytest.mark.slow
def test_certify_cli_writes_the_certificate_and_exits_1_when_not_certified(tmp_path, capsys):
    code = main(["certify", "lqg", "--uncertainty", "m_t=0:0.5,damping=0.0005:0.0005", "--check", "none",
                 "--out", str(tmp_path), "--json"])
    assert code == 1
    doc = json.loads((tmp_path / "certificate.json").read_text())
    cap = capsys.readouterr()
    assert json.loads(cap.out) == doc                   # --json: the document alone on stdout
    assert doc["set"] == {"m_t": [0.0, 0.5], "damping": [0.0005, 0.0005]}
    assert doc["controllers"]["lqg"]["certificate"]["robust_verdict"] == "not certified"
    assert "not certified: lqg" in cap.err


@pytest.mark.parametrize("argv, message", [
    (["--uncertainty", "m_t=0.5:0"], "--uncertainty: m_t must have lo <= hi"),
    (["--uncertainty", "mass=0:1"], "unknown key uncertainty.mass"),
    (["--uncertainty", "m_t"], "--uncertainty must be NAME=LO:HI"),
    ([], "certify needs an uncertainty set"),
    (["--uncertainty", "m_t=0:0.5", "--payload-range", "0,0.5"], "--payload-range does not apply to certify"),
    (["--uncertainty", "m_t=0:0.5", "--grid", "1"], "--grid must be an integer in [2, 9]"),
    (["--uncertainty", "m_t=0:0.5", "--check-plant", "cfoam"], "--check-plant does not apply to certify"),
    (["--uncertainty", "m_t=0:0.5", "--design", "robust", "--shaping", "zvd"],
     "--shaping does not apply with --design robust"),
    (["--uncertainty", "delay=0:2", "--rig", "servo_link", "--slew-angle", "1.5708", "--tf", "0.5"],
     "--uncertainty: uncertainty.delay = [0, 2] does not fit the rig"),
])
def test_certify_refuses_bad_input_in_one_line(tmp_path, capsys, argv, message):
    code = main(["certify", "lqr", *argv, "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and message in err and "Traceback" not in err


# --- designs that pass it ----------------------------------------------------------------

@pytest.mark.slow
def test_a_robust_lqg_is_certified_where_the_nominal_one_is_not(table1):
    """Table 1's LQG over 0-0.5 kg at a 0.05 % floor: the nominal design grows at 0.5 kg; the design
    search finds one the certificate accepts, and the nonlinear run at its worst plant settles."""
    from hubbeam_ctrl.study.robust_design import design_for_set
    rig, cmp = table1
    bare = rig.replace(uncertainty=Uncertainty())
    sd = design_for_set(cmp, "lqg", bare, PAYLOAD)
    assert sd.nominal_radius > 1.0
    assert sd.certificate.certified and sd.certificate.worst.radius <= 1 - RADIUS_MARGIN
    assert sd.label() != "nominal design" and len(sd.tried) > 5
    assert sd.certificate.worst.radius < sd.nominal_radius
    check = run_at(cmp, sd.controller, bare, sd.certificate.worst.values, PAYLOAD)
    assert check["verdict"] == "settled"


def test_the_certificate_opens_the_generated_header(tmp_path):
    from controllers import LQG, DesignModel
    from hubbeam_ctrl.deploy import to_c
    wc = certify_set(LQG(DesignModel.build(Params(), 0.0, 0.01, 2)), Rig(beam=Params()),
                     Uncertainty.from_table({"m_t": (0.05, 0.15)}), plant_modes=2, margins=False)
    code = to_c(LQG(DesignModel.build(Params(), 0.0, 0.01, 2)), tmp_path / "c", certificate=wc.metrics())
    head = code.header.splitlines()[0]
    assert head.startswith(f"/* Robust certificate: {wc.verdict().upper()} over m_t [0.05, 0.15]")
    meta = json.loads((tmp_path / "c" / "lqg.json").read_text())
    assert meta["robust_certificate"]["robust_radius"] == pytest.approx(wc.worst.radius)


def test_pd_roll_off_state_space_is_the_step_it_runs():
    """The roll-off PD's linear form (one state) gives the torques its step gives, sample by sample."""
    from controllers import PD, DesignModel, PDSettings
    d = DesignModel.build(Params(), 0.0, 0.01, 2)
    pd = PD(d, PDSettings(roll_off_hz=2.0, feedforward=False))
    Ak, Bk, Ck, Dk, states, inputs = pd.feedback_matrices()
    assert states == ["roll_off"] and inputs == ["theta", "theta_dot"]
    rng = np.random.default_rng(3)
    x = np.zeros(1)
    pd.reset()
    for k in range(50):
        y = rng.normal(size=2) * (0.01, 0.1)
        (th,), (thd,), _ = pd.reference.window(k, 1)
        dev = np.array([y[0] - th, y[1] - thd])     # the law acts on the error
        u_lin = float((Ck @ x + Dk @ dev)[0])
        x = Ak @ x + Bk @ dev
        assert pd(k * d.dt, y) == pytest.approx(u_lin, rel=1e-12, abs=1e-12)


def test_a_pd_roll_off_is_what_the_certificate_accepts_on_the_lab_arm():
    """The 1 m lab arm, 90 deg in 1.5 s, payload 0-0.2 kg at a 0.05 % floor: the static PD grows
    (a zero-order hold pumps the modes); a roll-off at twice the first bending frequency decays."""
    import math

    from controllers import make_controller
    from controllers.scaling import first_mode
    from hubbeam_ctrl.study import Slew
    lab = Params(L=1, rho=2700, A=9e-5, E=69e9, I=6.75e-11, J_h=0.02, r=0.05, m_t=0.05, tau_max=1.5)
    u = Uncertainty.from_table({"m_t": (0.0, 0.2), "damping": (0.0005, 0.0005)})
    rig = Rig(beam=lab, uncertainty=u)
    cmp = compare(rig, Slew(math.pi / 2, 1.5), ["pd"])
    assert not cmp.robust["pd"].certified
    pd = cmp.controllers["pd"]
    f1 = first_mode(pd.design) / (2 * math.pi)
    rolled = make_controller("pd", pd.design, pd.settings.replace(roll_off_hz=2 * f1), cmp.scenario.reference)
    assert certify_set(rolled, rig, plant_modes=cmp.plant.modes, margins=False).certified


def test_docs_quote_the_robust_benchmark_and_it_meets_the_targets():
    """docs/robust.md's table is benchmarks/results/bench_robust.json's; that run meets issue 39's
    Table 1 targets (certified, settled everywhere, <= 2 % of each plant's open loop, <= 200 N m), the
    servo_link ones (certified, settled, within the drive's limits) and the 30 s certificate budget."""
    from conftest import bench_module
    bench, root = bench_module("bench_robust")
    doc = json.loads((root / "benchmarks" / "results" / "bench_robust.json").read_text())
    text = (root / "docs" / "robust.md").read_text()
    for line in bench.table_lines(doc):
        assert line in text, line
    for name, r in doc["cases"]["table1"]["controllers"].items():
        assert r["verdict"] == "certified" and r["radius"] <= 1 - RADIUS_MARGIN, name
        assert r["all_settled"] and r["worst_residual_pct_of_openloop"] <= 2.0, name
        assert r["peak_torque_nm"] <= 200.0 + 1e-9, name
    for case in ("servo_link", "servo_identified"):
        for name, r in doc["cases"][case]["controllers"].items():
            assert r["verdict"] == "certified" and r["all_settled"] and r["all_within_drive_limits"], (case, name)
    assert all(doc["cases"]["servo_identified"]["identify"]["truth_inside"].values())
    assert doc["timing"]["search"]["wall_s"] <= 30.0
    assert doc["timing"]["search"]["radius"] >= doc["timing"]["grid6_alone"]["radius"] - 1e-9


def test_a_bounded_score_stops_at_the_best_so_far_and_runs_the_hardest_point_first(monkeypatch):
    """ResidualScore is a largest value over the set's points: a run past ``bound`` ends the
    candidate (it cannot win), and the point that gave the largest value runs first next."""
    import types

    import hubbeam_ctrl.study.robust_check as rc
    u = Uncertainty.from_table({"m_t": (0.0, 0.5), "damping": (0.0005, 0.0005)})
    comparison = types.SimpleNamespace(scenario=types.SimpleNamespace(bands={"settle_angle": 1e-3}))
    residual = {0.0: 1.0, 0.5: 3.0, 0.25: 0.5}          # % of the open loop at m_t
    calls = []

    def fake_run_at(comparison, ctrl, rig, values, uncertainty, openloop):
        calls.append(values["m_t"])
        return {"verdict": "settled", "residual_pct_of_openloop": residual[values["m_t"]],
                "final_angle_error_rad": 0.0}
    monkeypatch.setattr(rc, "run_at", fake_run_at)
    score = rc.residual_score(comparison, None, u)
    assert [v["m_t"] for v in score.points] == [0.0, 0.5, 0.25]       # corners, then the centre
    assert score("c") == pytest.approx(1.5) and calls == [0.0, 0.5, 0.25]
    calls.clear()
    # the heavy end gave the largest value: it runs first, and a bound of 1.2 stops there
    assert score("c", bound=1.2) == pytest.approx(1.5) and calls == [0.5]
    calls.clear()
    assert score("c", bound=2.0) == pytest.approx(1.5) and calls == [0.5, 0.0, 0.25]
    residual[0.5] = float("nan")                           # a run that failed: inf, and it stops
    calls.clear()
    assert score("c") == float("inf") and calls == [0.5]
