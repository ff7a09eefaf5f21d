"""Designs for a payload range and the report over it (issue 11, item 4)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from controllers import LQR, DesignModel, make_controller
from controllers.robust import (
    REFINE_STEPS,
    check_payload_range,
    design_for_range,
    linear_openloop_residual,
    payload_grid,
)
from hubbeam_ctrl import Params
from hubbeam_ctrl.cli.main import main
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.study import make_scenario, payload_comparison, payload_table, write_payload_outputs
from hubbeam_ctrl.study.compare_values import CompareSettings, PlantChoice


@pytest.mark.parametrize("rng, words", [
    ((0.5, 0.1), r"m_min <= m_max"),
    ((-0.1, 0.5), r"payload_range m_min must be a finite number >= 0 \[kg\]"),
    ((0.0, float("nan")), r"payload_range m_max must be a finite number >= 0"),
    ((0.2, 0.5), r"must hold the nominal tip mass m_t = 0.1 kg"),
    ((0.1,), r"must be two numbers"),
])
def test_bad_payload_ranges(rng, words):
    with pytest.raises(ParameterError, match=words) as info:
        check_payload_range(rng, 0.1)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("value, words", [
    ("0.5,0.1", "payload-range must have 0 <= m_min <= m_max"),
    ("-1,0.5", "payload-range m_min must be a finite number >= 0"),
    ("0,abc", "payload-range must be two finite numbers MIN,MAX"),
    ("0.2,0.5", "must hold the nominal tip mass"),
])
def test_cli_bad_payload_range_exit_2(tmp_path, capsys, value, words):
    rc = main(["compare", "--plant", "foam", f"--payload-range={value}", "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and words in err, err


def test_design_for_range_on_linear_models():
    """The choice is the candidate with the best worst case; every candidate was measured."""
    p = Params(n_axial=2, n_transverse=2)
    sc = make_scenario("slew", plant="foam", params=p, t_end=16.0)
    base = DesignModel.build(p, 0.0, sc.dt)
    eq44 = lambda t: np.where(t <= sc.t_f, 200.0 * np.sin(2 * np.pi * t / sc.t_f), 0.0)
    rd = design_for_range("lqr", make_controller, base, LQR(base).settings, sc.reference, (0.0, 0.5),
                          t_f=sc.t_f, t_end=sc.t_end, delay=5.0, baseline=eq44)
    assert rd.grid == payload_grid((0.0, 0.5), 0.1) == (0.0, 0.1, 0.5)
    first = {f"m={m} kg{w}" for m in ("0", "0.1", "0.25", "0.5") for w in ("", ", rates")}
    assert first <= set(rd.scores) and len(rd.scores) == len(first) + REFINE_STEPS   # + the bisection
    assert rd.score == min(rd.scores.values()) and rd.design.params.m_t == rd.design_mass
    assert 0 < rd.score < 1                      # better than the open loop on every payload
    assert linear_openloop_residual(base, eq44, sc.t_f, sc.t_end, 5.0) > 0.1


@pytest.mark.slow
def test_paper_beam_designed_for_0_to_half_a_kilo(tmp_path, fast_backend):
    """Issue target: Table 1's beam, LQR, LQG and MPC designed for 0-0.5 kg, FOAM evaluation
    plants at 0, 0.1, 0.3 and 0.5 kg: every loop <= 2 % of that plant's open-loop residual, and
    settled or, since issue 27, unstable only by its linear certificate on the undamped plant
    (0.1 % damping holds it: the range designs keep their gain on the design modes).
    Measured (% of the open loop at 0 / 0.1 / 0.3 / 0.5 kg): LQR 1.83/1.06/1.33/1.56,
    LQG 1.02/0.77/1.13/0.98, MPC 1.89/1.00/0.90/1.97 (about 3 min with a C compiler).

    The suite runs the LQR at the ends of the range (the range design's search is most of the
    time: 52 evaluations on three grid payloads per controller; all three controllers took 128 s
    of the suite's 10-minute budget); ``benchmarks/bench_payload.py`` runs all three at the four
    payloads with the same conditions.
    """
    names, masses = "openloop,lqr", (0.0, 0.5)
    pc = payload_comparison("foam", "slew", names, payload_range=(0.0, 0.5), masses=masses)
    print()
    print(payload_table(pc))
    rows = {(r["payload_kg"], r["controller"]): r for r in pc.rows()}
    for name, rd in pc.designs.items():
        assert rd.grid == (0.0, 0.1, 0.5) and rd.score == min(rd.scores.values()), name
        for m in masses:
            row = rows[(m, name)]
            mm = pc.comparisons[m].metrics[name]
            if row["verdict"] != "settled":
                # issue 27: the range designs keep their gain on the design modes (a gain on the
                # residual modes is not robust to the payload), so on the undamped plant their
                # certificate grows slowly (mode 8 folded, |z| ~ 1.0008); nothing else may grow
                assert row["verdict"] == "unstable" and mm["loop_certificate"] == "grows", (name, m)
                reason = mm["verdict_reason"]       # the torque's ripple may show the same growth
                assert reason.startswith("GROWS") and "tip envelope" not in reason and "angle envelope" not in reason
                assert mm["loop_damping_needed"] <= 1e-3, (name, m)      # measured 0.025-0.073 %
                assert abs(mm["final_angle_error_rad"]) <= pc.comparisons[m].scenario.bands["settle_angle"]
            assert row["residual_pct_of_openloop"] <= 2.0, (name, m, row["residual_pct_of_openloop"])
            assert row["design_mass_kg"] == rd.design_mass and row["peak_torque_nm"] <= 200.0 + 1e-9
    paths = write_payload_outputs(pc, tmp_path / "out")
    doc = json.loads(paths["json"].read_text())
    assert doc["payload_range_kg"] == [0.0, 0.5] and len(doc["rows"]) == len(rows)
    assert "| payload kg |" in paths["report"].read_text()


@pytest.mark.slow
def test_the_range_task_needs_the_payload_to_about_one_percent():
    """Issue 22's payload range, measured out of reach (docs/limit.md): Table 1's beam, 1 rad in
    1.5 x the 0.5 kg beam's time-optimal slew (3.0763 s, ``hubbeam optimal``). The LQR designed
    for the 0.5 kg payload settles within one first-mode period after the slew (measured
    6.18 s against 7.37 s); designed for 0.49 kg, 2 % off, it leaves the residual target met
    (0.028 % of L) but settles at 9.82 s. A design that does not know the payload to about 1 %
    misses the settling target."""
    import math

    from controllers.scaling import first_mode
    from hubbeam_ctrl.study.compare import compare
    from hubbeam_ctrl.study.tasks import Slew

    heavy = Params().replace(m_t=0.5)
    tf = 1.5 * 3.0763
    own = compare(heavy, Slew(1.0, tf), "lqr").metrics["lqr"]
    target = tf + 2 * math.pi / first_mode(DesignModel.build(heavy, 0.0, 0.01, 1))
    off = compare(heavy.replace(m_t=0.49), Slew(1.0, tf), "lqr",
                  CompareSettings(plant=PlantChoice(plant_params=heavy))).metrics["lqr"]
    assert own["verdict"] == "settled" and own["settling_time_s"] <= target, (own["settling_time_s"], target)
    assert own["residual_pct_of_L"] <= 0.1 and off["residual_pct_of_L"] <= 0.1
    assert off["settling_time_s"] is None or off["settling_time_s"] > target + 1.0, (off["settling_time_s"], target)
