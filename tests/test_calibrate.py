"""Calibration (issue 25): records, excitation, modal identification and the fit of rig fields.

The "measured" records are made by the toolbox's own FOAM plant with the servo link's
hardware (DC motor, Coulomb and viscous friction with sticking, encoder quantisation,
strain-gauge noise) from a rig whose true values differ from the starting guess as in the
issue; the targets are the issue's. Records are short (2 s at 1 kHz, a 2-mode plant) to keep
the tests fast; the issue's full-size case is benchmarks/bench_calibrate.py.
"""

import json

import numpy as np
import pytest

from hubbeam_ctrl.calibrate.excitation import excitation
from hubbeam_ctrl.calibrate.fit import FitSettings, fit_percent, fit_rig, resolve_fields, validate_record
from hubbeam_ctrl.calibrate.modal import identify_modes
from hubbeam_ctrl.calibrate.model import ModelSettings, clamped_modes, synthetic_record
from hubbeam_ctrl.calibrate.records import Record, load_record, record_from_result, save_record
from hubbeam_ctrl.cli.main import main
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.rig import load_rig

T_RECORD = 2.0
# the records are made by a 2-mode plant (the module docstring): the fit simulates the same (issue 38 made the
# default the records' band, which counts the modes of the real beam and would model the records' own truncation)
NO_RESTART = FitSettings(restarts=0, plant_modes=2)


def _rigs():
    base = load_rig("servo_link")
    guess = base.replace(beam=base.beam.replace(m_t=0.02), damping=base.damping.replace(ratios=(0.005,)),
                         friction=base.friction.replace(coulomb=0.0),
                         sensors=base.sensors.replace(strain_noise=1e-3))
    b = guess.beam
    truth = guess.replace(beam=b.replace(E=0.93 * b.E, J_h=1.10 * b.J_h, m_t=1.30 * b.m_t),
                          damping=guess.damping.replace(ratios=(0.02,)),
                          friction=guess.friction.replace(coulomb=10e-3))
    return guess, truth


def _inputs(t):
    f0, f1 = 0.5, 20.0
    chirp = 0.6 * np.sin(2 * np.pi * (f0 * t + (f1 - f0) * t ** 2 / (2 * t[-1])))
    rng = np.random.default_rng(1)
    prbs = np.repeat(rng.choice([-0.8, 0.8], size=len(t) // 50 + 1), 50)[:len(t)]
    prbs[t > 0.7 * t[-1]] = 0.0
    prbs[0] = 0.0
    multi = 0.5 * sum(np.sin(2 * np.pi * f * t + k) for k, f in enumerate((1.0, 2.5, 6.0, 13.0))) / 2
    return chirp, prbs, multi


@pytest.fixture(scope="module")
def case(fast_backend_module):
    guess, truth = _rigs()
    t = np.arange(int(T_RECORD * 1000) + 1) * 1e-3
    chirp, prbs, multi = _inputs(t)
    recs = [synthetic_record(truth, t, u, seed=k, source=name)
            for k, (u, name) in enumerate(((chirp, "chirp"), (prbs, "prbs"), (multi, "multisine")))]
    return guess, truth, recs


TRUE_NAMES = ("E", "J_h", "m_t", "damping", "friction")


def _truth_values(truth):
    return np.array([truth.beam.E, truth.beam.J_h, truth.beam.m_t, truth.damping.ratios[0], truth.friction.coulomb])


@pytest.mark.slow
def test_fit_meets_the_issue_targets(case):
    guess, truth, (chirp, prbs, multi) = case
    # no restart (it costs 40 % more simulations; the CLI test runs the default with it, the benchmark
    # measures what it gains on long records)
    res = fit_rig(guess, [chirp, prbs], ",".join(TRUE_NAMES), settings=NO_RESTART, progress=False)
    assert res.converged, res.message
    err = res.estimate / _truth_values(truth) - 1
    # issue 25: E 0.5 %, J_h 2 %, m_t 5 %, first-mode damping 10 %, Coulomb 10 %
    assert abs(err[0]) < 0.005 and abs(err[1]) < 0.02 and abs(err[2]) < 0.05, err
    assert abs(err[3]) < 0.10 and abs(err[4]) < 0.10, err
    # the start was off by the issue's amounts: the fit moved every field
    assert np.all(np.abs(res.start / _truth_values(truth) - 1) > 0.06)
    # intervals from the Jacobian contain the truth within a few of their widths, correlations are bounded
    assert np.all(np.isfinite(res.std)) and np.all(res.std > 0)
    assert np.all(np.abs(np.diag(res.correlation) - 1) < 1e-9)
    fits, _ = validate_record(res.rig, multi, settings=ModelSettings())
    assert min(fits.values()) >= 95.0, fits
    d = res.to_dict()
    assert set(d["estimates"]) == set(TRUE_NAMES) and d["estimates"]["E"]["field"] == "beam.E"


@pytest.mark.slow
def test_bad_start_converges_or_says_so(case):
    guess, truth, (chirp, prbs, _) = case
    tv = _truth_values(truth)
    factors = np.array([2.0, 0.5, 2.0, 0.5, 2.0])          # every fitted value off by a factor 2
    from hubbeam_ctrl.calibrate.fit import set_fields
    fields = resolve_fields(",".join(TRUE_NAMES), guess)
    start = set_fields(guess, fields, tv * factors)
    res = fit_rig(start, [prbs], list(TRUE_NAMES), settings=NO_RESTART, progress=False)
    if res.converged:
        err = res.estimate / tv - 1
        assert abs(err[0]) < 0.005 and abs(err[1]) < 0.02 and abs(err[2]) < 0.05, err
    else:
        assert "did not converge" in res.message and res.warnings
    # with too few evaluations the fit keeps its last estimate and says it did not converge
    short = fit_rig(start, [chirp], list(TRUE_NAMES),
                    settings=FitSettings(max_evaluations=2, restarts=0, plant_modes=2), progress=False)
    assert not short.converged and "did not converge" in short.message
    assert "not converge" in short.warnings[0]
    assert np.all(np.isfinite(short.estimate))


def test_free_decay_modes_of_the_held_hub(fast_backend_module):
    """A free-oscillation test: the beam plucked (released from a deflection) with the hub held."""
    _, truth = _rigs()
    held = truth.replace(friction=truth.friction.replace(breakaway=1.0))
    t = np.arange(3001) * 1e-3
    u = np.zeros_like(t)
    u[0] = 1e-3
    rec = synthetic_record(held, t, u, seed=3, source="pluck", q2_0=[0.01, 0.002],
                           settings=ModelSettings(n_transverse=4, frequency_tolerance=5e-3),
                           sensors=("theta", "root_moment", "v_tip"))
    assert np.ptp(rec.columns["theta"]) == 0.0           # the hub did not move
    est = identify_modes(rec, band_hz=(0.5, 40.0))
    f, z = clamped_modes(truth, 2)                        # modal analysis of the true rig, hub clamped
    assert np.all(np.abs(est.frequency_hz / f - 1) < 0.002), est.frequency_hz / f - 1
    assert np.all(np.abs(est.damping / z - 1) < 0.10), est.damping / z - 1
    assert np.all(est.frequency_std_hz < 0.002 * f) and np.all(est.damping_std > 0)
    # mode-shape signs with two sensors: a cantilever's root curvature and tip deflection have the
    # same sign in mode 1 and opposite signs in mode 2 (phi(L) = 2 (-1)^(i+1) for phi''(0) = 2 beta^2 > 0)
    two = identify_modes(rec, ("root_moment", "v_tip"), band_hz=(0.5, 40.0))
    assert list(two.shape_signs["v_tip"]) == [1, -1] and list(two.shape_signs["root_moment"]) == [1, 1]
    assert np.all(np.abs(two.frequency_hz / f - 1) < 0.002)


def test_forced_response_modes_by_okid(fast_backend_module):
    """A PRBS on the servo with a linear drive (gear efficiency 1, no Coulomb friction): OKID + ERA
    against the linearised rig with the hub free and damped by the back-EMF and viscous friction."""
    from hubbeam_ctrl.calibrate.model import sliding_hub_modes
    from hubbeam_ctrl.plant.rig import Friction
    _, truth = _rigs()
    linear = truth.replace(drive=truth.drive.replace(eta_forward=1.0, eta_backward=1.0),
                           friction=Friction(viscous=4e-3))
    t = np.arange(4001) * 1e-3
    u = 0.5 * np.repeat(np.random.default_rng(0).choice([-1.0, 1.0], size=401), 10)[:len(t)]
    rec = synthetic_record(linear, t, u, seed=1, settings=ModelSettings(n_transverse=4, frequency_tolerance=5e-3))
    est = identify_modes(rec, kind="forced", band_hz=(0.5, 20.0))
    f, z = sliding_hub_modes(linear, 2)           # 2.01 Hz at 0.36 (the drive damps it), 15.0 Hz at 0.031
    # mode 2 within the issue's 0.2 %; mode 1, damped to 0.36 by the drive, within 0.5 % (measured 0.22 %)
    err = est.frequency_hz / f - 1
    assert abs(err[0]) < 0.005 and abs(err[1]) < 0.002, err
    assert np.all(np.abs(est.damping / z - 1) < 0.10), est.damping / z - 1
    with pytest.raises(ParameterError, match="is constant"):
        identify_modes(Record(t=t, columns={"V": np.ones_like(t), "root_moment": rec.columns["root_moment"]}),
                       kind="forced")


def test_records_round_trip_and_simulated_run_is_a_record(tmp_path, case):
    _, _, (chirp, _, _) = case
    for ext in ("csv", "npz"):
        save_record(chirp, tmp_path / f"r.{ext}")
        back = load_record(tmp_path / f"r.{ext}")
        assert back.input_name == "V" and back.sensors == chirp.sensors
        assert np.array_equal(back.t, chirp.t) and np.array_equal(back.columns["theta"], chirp.columns["theta"])
    from hubbeam_ctrl import Params
    from hubbeam_ctrl.sim.stepper import simulate_fixed_step
    res = simulate_fixed_step("foam", lambda t: 10.0 * np.sin(t), 0.2, params=Params(n_axial=1, n_transverse=1))
    res.save(tmp_path / "run.csv")
    rec = load_record(tmp_path / "run.csv")
    assert rec.input_name == "tau" and {"theta", "theta_dot", "v_tip"} <= set(rec.sensors)
    assert np.allclose(rec.columns["theta"], record_from_result(res).columns["theta"], rtol=0, atol=0)
    assert fit_percent(rec.columns["theta"], rec.columns["theta"]) == 100.0


@pytest.mark.parametrize("text, message", [
    ("t [s],V [V],theta [rad]\n0,1,0\n", "at least 8 samples"),
    ("t [s],V [V],theta [rad]\n" + "".join(f"{k * 1e-3},{k % 2},nan\n" for k in range(10)), "theta has NaN at row 1"),
    ("t [s],V [V]\n" + "".join(f"{(k if k != 5 else 3) * 1e-3},{k}\n" for k in range(10)), "time must increase"),
    ("t [s],V [V],foo [m]\n0,1,2\n", "unknown column 'foo'"),
    ("t [s],V [mV]\n0,1\n", "column V must be in [V], got [mV]"),
    ("t [s],theta [rad]\n" + "".join(f"{k * 1e-3},0\n" for k in range(10)), "exactly one input column"),
    ("t,V\n0,1\n", "not 'name [unit]'"),
])
def test_bad_records_are_one_line(tmp_path, text, message):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(ParameterError, match=None) as exc:
        load_record(path)
    assert message in str(exc.value) and "\n" not in str(exc.value)


def test_bad_fit_input_is_one_line(case):
    guess, _, (chirp, _, _) = case
    t = chirp.t
    cases = [
        (lambda: fit_rig(guess, [chirp.window(0, 0.2)], "E"), "shorter than one period of the first mode"),
        (lambda: fit_rig(guess, [Record(t=t, columns={"V": np.ones_like(t), "theta": chirp.columns["theta"]})], "E"),
         "is constant"),
        (lambda: fit_rig(guess, [chirp], "E", sensors=["tip_accel"]), "the rig does not have it"),
        (lambda: fit_rig(guess, [chirp], "Young"), "'Young' is not a rig field"),
        (lambda: fit_rig(guess, [chirp], "E", bounds={"E": (3e11, 1e11)}), "lo = 3e+11 > hi = 1e+11"),
        (lambda: fit_rig(guess, [Record(t=t, columns={"tau": chirp.input, "theta": chirp.columns["theta"]})], "E"),
         "give its voltage as V [V]"),
        (lambda: FitSettings(plant_modes=0), "plant_modes must be an integer in 1..20 or None"),
        (lambda: FitSettings(max_wall=-1.0), "max_wall must be in (0, 1e6] [s] or None, got -1.0"),
        (lambda: FitSettings(floor_margin=-1.0), "floor_margin must be in [0, 100], got -1.0"),
    ]
    for call, message in cases:
        with pytest.raises(ParameterError) as exc:
            call()
        assert message in str(exc.value) and "\n" not in str(exc.value), str(exc.value)


def test_excitation_respects_the_limits(fast_backend_module):
    rig = load_rig("servo_link")
    rec = excitation(rig, "multisine", 4.0, max_tip_deflection=0.01, max_hub_travel=0.5)
    assert rec.input_name == "V" and np.max(np.abs(rec.input)) <= rig.drive.V_max
    assert np.max(np.abs(rec.columns["v_tip"])) <= 0.01 and np.max(np.abs(rec.columns["theta"])) <= 0.5
    assert rec.input[0] == 0.0 and abs(rec.input[-1]) < 1e-12
    with pytest.raises(ParameterError, match="amplitude must be in"):
        excitation(rig, "step", 1.0, amplitude=20.0)


@pytest.mark.slow
def test_cli_excite_and_identify(tmp_path, case, capsys):
    from hubbeam_ctrl.calibrate.excitation import EXCITATION_KINDS
    from hubbeam_ctrl.cli.excite import KINDS
    assert KINDS == EXCITATION_KINDS
    guess, truth, (chirp, _, multi) = case
    from hubbeam_ctrl.plant.rig import save_rig
    save_rig(guess, tmp_path / "guess.toml")
    save_record(chirp, tmp_path / "chirp.csv")
    save_record(multi, tmp_path / "multi.csv")
    assert main(["excite", "--rig", str(tmp_path / "guess.toml"), "--kind", "step", "--duration", "1",
                 "--out", str(tmp_path / "step.csv"), "--json"]) == 0
    step = load_record(tmp_path / "step.csv")
    assert step.input_name == "V" and step.sensors == ()
    capsys.readouterr()
    # E and J_h alone from the guess, whose damping (0.005) and Coulomb friction (0) are wrong: the model
    # misses the root moment by tens of points, so no rig (issue 38: it used to be written), exit 2
    argv = ["identify", str(tmp_path / "chirp.csv"), "--fit", "E,J_h", "--validate", str(tmp_path / "multi.csv"),
            "--json", "--plant-modes", "2"]
    code = main(argv + ["--rig", str(tmp_path / "guess.toml"), "--out", str(tmp_path / "wrong")])
    cap = capsys.readouterr()
    assert code == 2 and json.loads(cap.out)["status"] == "below the noise ceiling" and "--force" in cap.err
    assert not (tmp_path / "wrong" / "rig.toml").exists()
    # with only E and J_h wrong (the guess's), their fit reaches the noise floor: the rig is written
    save_rig(truth.replace(beam=truth.beam.replace(E=guess.beam.E, J_h=guess.beam.J_h)), tmp_path / "guess.toml")
    code = main(argv + ["--rig", str(tmp_path / "guess.toml"), "--out", str(tmp_path / "calib")])
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out["estimates"]) == {"E", "J_h"} and len(out["estimates"]["E"]["ci95"]) == 2
    assert out["rig_written"] and (tmp_path / "calib" / "rig.toml").exists() and out["status"] == "converged"
    assert out["plant_modes"] == 2 and next(iter(out["fit_ceiling_percent"].values()))["theta"] > 95
    assert "## Estimates" in (tmp_path / "calib" / "report.md").read_text()
    calibrated = load_rig(tmp_path / "calib" / "rig.toml")
    assert calibrated.beam.E == pytest.approx(out["estimates"]["E"]["estimate"])
    # the calibrated rig carries its intervals as [uncertainty] (issue 39)
    assert calibrated.uncertainty["E"].lo == pytest.approx(out["estimates"]["E"]["ci95"][0])
    assert calibrated.uncertainty["J_h"].hi == pytest.approx(out["estimates"]["J_h"]["ci95"][1])
    # bad input: exit 2, one line
    for argv, message in [
        (["--fit", "E,nope"], "'nope' is not a rig field"),
        (["--fit", "E", "--bounds", "E=2e11:1e11"], "lo = 2e+11 > hi = 1e+11"),
        (["--fit", "E", "--sensors", "tip_accel"], "the rig does not have it"),
    ]:
        code = main(["identify", str(tmp_path / "chirp.csv"), "--rig", str(tmp_path / "guess.toml"),
                     "--out", str(tmp_path / "x"), *argv])
        err = capsys.readouterr().err.strip()
        assert code == 2 and message in err and "\n" not in err, err
    assert not (tmp_path / "x").exists()
    # a column of NaN: exit 2, one line naming the file and column
    nan = tmp_path / "nan.csv"
    nan.write_text("t [s],V [V],theta [rad]\n" + "".join(f"{k * 1e-3},{k % 3},nan\n" for k in range(20)))
    code = main(["identify", str(nan), "--rig", str(tmp_path / "guess.toml"), "--fit", "E",
                 "--out", str(tmp_path / "y")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "column theta has NaN at row 1" in err and "\n" not in err, err
    # a fit that does not converge: the report with its last estimate, no calibrated rig, exit 2 naming --force
    # (issue 38: a refusal to write is status 2; it was 1)
    code = main(["identify", str(tmp_path / "chirp.csv"), "--rig", str(tmp_path / "guess.toml"), "--fit", "E,J_h",
                 "--max-evaluations", "1", "--out", str(tmp_path / "nc")])
    err = capsys.readouterr().err
    assert code == 2 and "did not converge" in err and "--force" in err
    assert (tmp_path / "nc" / "report.md").exists() and not (tmp_path / "nc" / "rig.toml").exists()
    assert "did not converge" in (tmp_path / "nc" / "report.md").read_text()


def test_modal_table_fit_and_non_identifiable_warning(tmp_path):
    guess, truth = _rigs()
    from hubbeam_ctrl.plant.modal import modal_analysis
    rows = []
    for spin in (0.0, 6.0):
        p = truth.plant_params.replace(n_transverse=5, n_axial=2)
        r = modal_analysis("foam", spin, "prescribed", p)
        rows += [(spin, k + 1, r.bending_hz[k], r.damping_ratios[k]) for k in range(2)]
    path = tmp_path / "modes.csv"
    path.write_text("spin [rad/s],mode [-],frequency [Hz],damping [-]\n"
                    + "".join(f"{w},{k},{float(f)!r},{float(z)!r}\n" for w, k, f, z in rows))
    from hubbeam_ctrl.calibrate.table import fit_modal_table, load_modal_table
    table = load_modal_table(path)
    res = fit_modal_table(guess, table, "E,m_t,damping", progress=False)
    assert res.converged
    err = res.estimate / np.array([truth.beam.E, truth.beam.m_t, 0.02]) - 1
    assert np.all(np.abs(err) < 1e-3), err
    # the same through the command line: a checked rig is written
    from hubbeam_ctrl.plant.rig import save_rig
    save_rig(guess, tmp_path / "guess.toml")
    assert main(["identify", "--modal-table", str(path), "--rig", str(tmp_path / "guess.toml"), "--fit",
                 "E,m_t,damping", "--out", str(tmp_path / "mt"), "--json"]) == 0
    assert load_rig(tmp_path / "mt" / "rig.toml").beam.E == pytest.approx(truth.beam.E, rel=1e-3)
    assert main(["identify", "--rig", str(tmp_path / "guess.toml"), "--fit", "E", "--out", str(tmp_path / "n")]) == 2
    # the damping left at its guess against measured ratios: the fit says the model misses the table
    wrong = fit_modal_table(guess, table, "E,m_t", progress=False)
    assert any("misses a measured" in w for w in wrong.warnings), wrong.warnings
    # E and I enter only as E I: the fit must say that they are not separately identifiable
    both = fit_modal_table(guess, table, "E,I", progress=False)
    assert any("not separately identifiable" in w and "E" in w and "I" in w for w in both.warnings), both.warnings


def test_noise_ceiling_counts_the_encoder(case):
    # issue 38: the ceiling a perfect model reaches, from the record alone; the encoder's rounding is not
    # white where the angle moves slowly, so its level is at least q / sqrt(12)
    from hubbeam_ctrl.calibrate.design import quantum, record_design
    from hubbeam_ctrl.calibrate.fit import predict
    guess, truth, (chirp, prbs, _) = case
    sensors = ("theta", "root_moment")
    design = record_design(guess, [chirp, prbs], [sensors] * 2)
    q = 2 * np.pi / truth.sensors.encoder_counts
    for rec in (chirp, prbs):
        assert quantum(rec.columns["theta"]) == pytest.approx(q, rel=1e-6)
        assert quantum(rec.columns["root_moment"]) == 0.0
        assert design.noise[rec.source]["theta"] >= q / np.sqrt(12) * (1 - 1e-9)
        assert design.noise[rec.source]["root_moment"] == pytest.approx(truth.sensors.strain_noise, rel=0.05)
        y = predict(truth, rec, sensors, ModelSettings())
        for s in sensors:
            assert abs(fit_percent(rec.columns[s], y[s]) - design.ceiling[rec.source][s]) < 0.5, (rec.source, s)
