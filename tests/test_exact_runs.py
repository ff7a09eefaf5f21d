"""The exact-beam plant in the toolbox's runs: ``hubbeam simulate --plant ancf``, sweeps on it, and a
comparison checked against FOAM past its range. Short runs, small models (the 30 s runs are in
benchmarks/bench_exact.py)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hubbeam_ctrl import Params, SpinUp, TorquePulse, simulate
from hubbeam_ctrl.cli.main import main
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.exact import EXUDYN_INSTALL, exudyn_available
from hubbeam_ctrl.study.compare import compare
from hubbeam_ctrl.study.compare_values import CompareSettings, PlantChoice, RunChoice, ScenarioChoice
from hubbeam_ctrl.study.spec_files import load_spec
from hubbeam_ctrl.study.sweep import sweep

needs_exudyn = pytest.mark.skipif(not exudyn_available(), reason=EXUDYN_INSTALL)

P5 = Params(n_transverse=5)


@needs_exudyn
def test_simulate_exact_against_foam():
    """Eq. 44 (1 s) and a spin-up (2 s, prescribed hub) on the exact beam by simulate_exact, against FOAM
    by IDAS: tip within 1.2 % (the torque run) and 0.1 % (small deflection, the spin-up), the drive torque
    of the prescribed hub (the constraint's reaction) within 1e-3 of FOAM's required torque."""
    from hubbeam_ctrl.sim.exactbeam import simulate_exact
    ex = simulate_exact(TorquePulse(), 1.0, params=P5)
    fo = simulate("foam", TorquePulse(), 1.0, params=P5)
    assert ex.model == "ancf" and ex.hub == "free" and ex.settings["plant_elements"] == 16
    assert ex.settings["substeps"] == 7 and "substep rule" in ex.settings["step_reason"]
    assert np.max(np.abs(ex.v_tip)) == pytest.approx(np.max(np.abs(fo.v_tip)), rel=1.2e-2)
    assert ex.theta[-1] == pytest.approx(fo.theta[-1], rel=5e-4)
    spin = SpinUp(3.0, 30.0)
    ex = simulate_exact(spin, 2.0, params=P5)
    fo = simulate("foam", spin, 2.0, params=P5)
    assert ex.hub == "prescribed"
    assert np.allclose(ex.theta, fo.theta, atol=1e-12)
    assert np.max(np.abs(ex.v_tip - fo.v_tip)) < 1e-3 * np.max(np.abs(fo.v_tip))
    assert np.max(np.abs(ex.tau - fo.tau)) < 1e-3 * np.max(np.abs(fo.tau))


@needs_exudyn
def test_cli_simulate_plant_ancf(tmp_path, capsys):
    out = tmp_path / "run.npz"
    assert main(["simulate", "--plant", "ancf", "--maneuver", "torque", "--t-end", "0.5", "--n-modes", "5",
                 "--json", "--out", str(out)]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["plant"] == "ancf" and s["plant_elements"] == 16 and s["substeps"] == 7
    assert s["past_assumed_mode_range_time_s"] is None and out.exists()
    fo = simulate("foam", TorquePulse(), 0.5, params=P5)
    assert s["peak_tip_m"] == pytest.approx(np.max(np.abs(fo.v_tip)), rel=1.2e-2)
    for argv, first in (
            (["--substeps", "2"], "hubbeam: error: --substeps must be at least 3 for dt = 0.01 s (bending mode 5"),
            (["--elements", "4"], "hubbeam: error: --elements must be an integer in [10, 512]"),
            (["--model", "foam"], "hubbeam: error: --model does not apply to --plant ancf"),
            (["--axial", "quasi-static"], "hubbeam: error: --axial does not apply to --plant ancf"),
            (["--t-end", "1e5", "--allow-large"], "hubbeam: error: --t-end = 100000 s at dt = 0.01 s (10000001 "
                                                  "samples of 7 steps) would take at least")):
        assert main(["simulate", "--plant", "ancf", "--maneuver", "torque", "--t-end", "0.1", "--n-modes", "5",
                     *argv]) == 2          # (a second --t-end replaces the first)
        err = capsys.readouterr().err
        assert err.startswith(first) and err.count("\n") == 1, err
    assert main(["simulate", "--model", "foam", "--maneuver", "torque", "--t-end", "0.1", "--substeps", "3"]) == 2
    assert "--substeps does not apply to an assumed-mode model" in capsys.readouterr().err
    assert main(["simulate", "--maneuver", "torque", "--t-end", "0.1"]) == 2
    assert "--model is required" in capsys.readouterr().err


def test_without_exudyn_one_line_exit_2(monkeypatch, tmp_path, capsys):
    import hubbeam_ctrl.exact.beam as beam
    monkeypatch.setattr(beam, "exudyn_available", lambda: False)
    assert main(["simulate", "--plant", "ancf", "--maneuver", "torque", "--t-end", "0.1"]) == 2
    err = capsys.readouterr().err
    assert err == f"hubbeam: error: --plant ancf: {EXUDYN_INSTALL}\n"
    spec = tmp_path / "s.toml"
    spec.write_text('[study]\ncontrollers = ["lqr"]\nt_end = 2.0\n')
    assert main(["sweep", str(spec), "--plant", "ancf", "--out", str(tmp_path / "o")]) == 2
    assert capsys.readouterr().err == f"hubbeam: error: --plant 'ancf': {EXUDYN_INSTALL}\n"
    for option in ("--plant", "--check-plant"):
        argv = ["--plant", "ancf"] if option == "--plant" else ["--check-plant", "ancf"]
        assert main(["compare", *argv, "--controllers", "openloop", "--out", str(tmp_path / "c")]) == 2
        assert capsys.readouterr().err == f"hubbeam: error: {option} ancf: {EXUDYN_INSTALL}\n"
    with pytest.raises(ParameterError, match=r"^study.plant 'ancf': .*pip install 'hubbeam-ctrl\[exact\]'"):
        load_spec({"study": {"plant": "ancf"}})


def test_sweep_bad_plant_names_the_option(tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text('[study]\ncontrollers = ["lqr"]\nt_end = 2.0\n')
    assert main(["sweep", str(spec), "--plant", "exact", "--out", str(tmp_path / "o")]) == 2
    assert capsys.readouterr().err == "hubbeam: error: --plant must be one of foam, cfoam, ancf, got 'exact'\n"


@needs_exudyn
def test_sweep_on_the_exact_plant_equals_compare():
    """``[study] plant = "ancf"`` (here through load_spec(plant=), as ``hubbeam sweep --plant ancf``): each
    row equals compare('ancf') on that case, bit for bit (2 + 2 modes, 1 s slew, 2 s)."""
    p = Params(n_axial=2, n_transverse=2)
    spec = load_spec({"study": {"controllers": ["openloop", "lqr"], "t_f": 1.0, "t_end": 2.0, "plant_modes": 2},
                      "params": {"n_axial": 2, "n_transverse": 2}, "grid": {"m_t": [0.0, 0.3]}}, plant="ancf")
    assert spec.plant == "ancf"
    df = sweep(spec, workers=1, progress=False)
    assert list(df["plant"]) == ["ancf"] * 4
    ref = compare(p, "slew", "openloop,lqr",
                  CompareSettings(plant=PlantChoice("ancf", plant_params=p.replace(m_t=0.3), plant_modes=2),
                                  run=RunChoice(t_end=2.0), scenario=ScenarioChoice(t_f=1.0))).metrics
    for name, m in ref.items():
        row = df[(df["m_t"] == 0.3) & (df["controller"] == name)].iloc[0]
        assert row["peak_tip_m"] == m["peak_tip_m"] and row["residual_tip_max_m"] == m["residual_tip_max_m"]


@needs_exudyn
def test_compare_past_foams_range_reports_both_plants(tmp_path, capsys):
    """A fast slew of the paper's beam (0.5 rad in 2 s, open loop, 3 modes, 3.5 s): FOAM's tip passes 0.3 L
    (flagged, peak 0.416 L) and the exact plant's is recorded, not flagged (peak 0.398 L: FOAM +4.5 %);
    ``--check-plant foam`` runs both in one comparison and report.md says which left its range."""
    out = tmp_path / "cmp"
    assert main(["compare", "--plant", "ancf", "--check-plant", "foam", "--controllers", "openloop", "--n-modes", "3",
                 "--plant-modes", "3", "--tf", "2", "--slew-angle", "0.5", "--t-end", "3.5", "--out", str(out),
                 "--json"]) == 0
    captured = capsys.readouterr()
    m = json.loads(captured.out)[0]
    L = Params().L
    assert m["plant"] == "ancf" and m["check_plant"] == "foam"
    assert not m["outside_validated_range"] and m["check_outside_range_time_s"] == pytest.approx(1.83)
    assert 0.3 < m["peak_tip_m"] / L < m["check_peak_tip_m"] / L
    assert m["check_peak_tip_m"] / m["peak_tip_m"] - 1 == pytest.approx(0.045, abs=0.01)   # measured +4.5 %
    report = (out / "report.md").read_text()
    assert "## ANCF (exact beam) and FOAM on the same loop" in report
    assert "- Exact beam: 16 ANCF cable elements (3 per bending mode" in report       # issue 23 item 2
    assert (f"- openloop: FOAM left its validated range (|v_tip| > 0.3 L at t = 1.830 s; peak "
            f"{m['check_peak_tip_m'] / L:.3f} L); the exact plant did not (it has no such range): peak "
            f"{m['peak_tip_m'] / L:.3f} L") in report
    assert "on the check plant FOAM" in captured.err
    assert main(["compare", "--plant", "foam", "--check-plant", "foam", "--controllers", "openloop",
                 "--out", str(tmp_path / "x")]) == 2
    assert capsys.readouterr().err == ("hubbeam: error: --check-plant must be a plant other than --plant foam, "
                                       "got foam\n")
    with pytest.raises(ParameterError, match=r"^check_plant must be one of foam, cfoam \(a plant other than "):
        compare(Params(n_transverse=3), "slew", "openloop",
                CompareSettings(plant=PlantChoice("ancf", check_plant="ancf")))
