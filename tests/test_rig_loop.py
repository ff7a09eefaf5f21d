"""Controllers on a rig: integral action by disturbance estimation, observers for state feedback,
voltage commands, and the comparison on a rig (issue 21)."""

import dataclasses
import json
import math

import numpy as np
import pytest

from controllers import LQG, LQR, MPC, DesignModel, KalmanNoise, LQGSettings, LQRSettings, MPCSettings
from controllers.drive import VoltageCommand
from controllers.integral import ObservedFeedback, OffsetFreeEstimator
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.plant.rig import Rig, load_rig
from hubbeam_ctrl.sim.hardware import Hardware
from hubbeam_ctrl.study.compare import compare
from hubbeam_ctrl.study.compare_values import (
    CompareSettings,
    DesignChoice,
    RunChoice,
    ScenarioChoice,
    compare_arguments,
)
from hubbeam_ctrl.study.tasks import Slew

ENCODER = 2 * math.pi / 4096


@pytest.fixture(scope="module")
def design():
    return DesignModel.build(Params(), 0.0, 0.01, 2)


def test_offset_free_estimator_finds_a_constant_disturbance(design):
    est = OffsetFreeEstimator(design, KalmanNoise(), disturbance_noise=0.05)
    x, d, u = np.zeros(design.n_x), 0.7, 0.3              # 0.7 N m the model does not know
    est.reset()
    for k in range(3000):
        est.update(design.C_sensors @ x, None if k == 0 else u)
        x = design.Ad @ x + design.Bd[:, 0] * (u + d)
    assert est.disturbance == pytest.approx(d, rel=1e-6)


def test_offset_free_estimator_refuses_bad_noise(design):
    with pytest.raises(ParameterError, match="disturbance_noise"):
        OffsetFreeEstimator(design, KalmanNoise(), disturbance_noise=0.0)


def _run_law(Ac, Bc, Cc, Dc, Y):
    x = np.zeros(Ac.shape[0])
    out = []
    for y in Y:
        out.append(float((Cc @ x + Dc @ y)[0]))
        x = Ac @ x + Bc @ y
    return np.array(out)


@pytest.mark.parametrize("kind", ["lqg", "lqr", "mpc"])
def test_integral_law_equals_the_controller(design, kind):
    """The linear law the certificate closes (feedback_matrices) is the controller's, sample by sample."""
    if kind == "lqg":
        ctrl = LQG(design, LQGSettings(integral=True, disturbance_noise_nm=0.5))
    elif kind == "lqr":
        ctrl = ObservedFeedback(LQR(design, LQRSettings()), KalmanNoise(), 0.5)
    else:
        ctrl = ObservedFeedback(MPC(design, MPCSettings(horizon=20)), KalmanNoise(), 0.5)
    Ac, Bc, Cc, Dc, states, inputs = ctrl.feedback_matrices()
    assert states[-1] == "d_est" and inputs == ["theta", "theta_dot", "root_moment"]
    rng = np.random.default_rng(1)
    Y = 1e-4 * rng.standard_normal((60, 3))
    ctrl.reset()
    got = np.array([ctrl(k * design.dt, y) for k, y in enumerate(Y)])
    want = _run_law(Ac, Bc, Cc, Dc, Y)
    assert np.max(np.abs(got - want)) <= 1e-9 * max(1.0, np.max(np.abs(want)))
    # integral action: the law has a pole at z = 1 (infinite gain at DC)
    assert np.min(np.abs(np.linalg.eigvals(Ac) - 1.0)) < 1e-9


def test_voltage_command_gives_the_torque_asked_for():
    rig = load_rig("servo_link")
    hw = Hardware.from_rig(rig)
    d = DesignModel.build(rig.plant_params, 0.0, 1e-3, 2)
    inner = LQG(d, LQGSettings())
    ctrl = VoltageCommand(inner, hw)
    ctrl.reset()
    y = np.array([0.01, 2.0, 0.0])                     # 10 mrad behind, turning at 2 rad/s
    V = ctrl(0.0, y)
    assert abs(V) < rig.drive.V_max
    assert float(hw.hub_torque(V, 2.0) + hw.friction.viscous * 2.0 + math.tanh(2.0 / hw.friction.v_eps)
                 * hw.friction.coulomb) == pytest.approx(ctrl.last_torque, rel=1e-12)
    assert ctrl.name == inner.name and ctrl.dt == inner.dt and ctrl.measurement == "sensors"
    with pytest.raises(ParameterError, match="dc_motor"):
        VoltageCommand(inner, Hardware.from_rig(Rig()))


def _strip(metrics):
    """The metrics as JSON text (NaN equals NaN there), without wall times."""
    return json.dumps({n: {k: v for k, v in m.items() if "wall" not in k and not k.startswith("step_time")}
                       for n, m in metrics.items()}, sort_keys=True, default=str)


def test_ideal_rig_is_the_beam_alone_bit_for_bit():
    kw = dict(controllers="lqg", t_end=16.0)
    beam = compare(**compare_arguments("foam", "slew", **kw))
    rig = compare(**compare_arguments("foam", "slew", rig=Rig(beam=Params()), **kw))
    for name in beam.results:
        a, b = beam.results[name], rig.results[name]
        assert np.array_equal(a.q, b.q) and np.array_equal(a.tau, b.tau)
    assert _strip(beam.metrics) == _strip(rig.metrics)


@pytest.mark.slow
def test_servo_link_targets(fast_backend):
    """Issue 21's targets on the published rig: 90 degrees in 0.6 s, all defaults, the task's whole
    2.19 s. (Cut at 1.8 s, the torque envelope's growth rate over the short window that is left was
    erratic in the integration step, MPC 'unstable' at 15 and 25 substeps and 'settled' at 14, 16,
    18, 20 and 29, the one run at the old rule's count; over the whole task it decays at every count
    tried, issue 28.)"""
    rig = load_rig("servo_link")
    c = compare(rig, Slew(math.pi / 2, 0.6), "lqr,lqg,mpc")
    for name, r in c.results.items():
        m = c.metrics[name]
        assert m["verdict"] == "settled", (name, m["verdict_reason"])
        assert abs(r.q[-1, 0] - r.theta_ref[-1]) <= 2 * ENCODER, name
        assert np.max(np.abs(r.v_tip[r.t >= 0.6 + 1.0])) <= 1e-3, name
        assert np.max(np.abs(r.tau)) <= rig.drive.V_max, name          # volts
        assert r.settings["hardware"]["command"] == "voltage"


def test_friction_leaves_a_steady_error_without_integral_action():
    """50 mN m of Coulomb friction: the LQG without integral action stops inside its dead band
    F_c / K_theta (K_theta its DC gain from angle to torque) and more than 2 encoder counts off
    (with it, test_servo_link_targets: within 2 counts)."""
    rig = load_rig("servo_link")
    rig = dataclasses.replace(rig, friction=dataclasses.replace(rig.friction, coulomb=0.05))
    c = compare(rig, Slew(math.pi / 2, 0.6), "lqg",
                CompareSettings(design=DesignChoice(integral=False), run=RunChoice(t_end=2.0)))
    r = c.results["lqg"]
    error = abs(r.q[-1, 0] - r.theta_ref[-1])
    Ac, Bc, Cc, Dc, _, _ = c.controllers["lqg"].inner.feedback_matrices()     # the torque law (not the volts)
    k_theta = abs(float((Cc @ np.linalg.solve(np.eye(len(Ac)) - Ac, Bc) + Dc)[0, 0]))
    dead_band = rig.friction.coulomb / k_theta
    assert 2 * ENCODER < error <= dead_band + ENCODER
    assert c.metrics["lqg"]["verdict"] == "not settled"


@pytest.mark.slow
def test_cli_compare_on_a_rig_writes_the_rig_and_its_ladder(tmp_path, capsys):
    """hubbeam compare --rig: the API's numbers on the rig, and the ladder's last step is the rig itself."""
    from hubbeam_ctrl.cli.main import main
    from hubbeam_ctrl.plant.rig import rig_to_toml
    out = tmp_path / "cmp"
    full = load_rig("servo_link")     # its drive and friction (the ladder: ideal, + friction, + drive)
    rig = Rig(beam=full.beam, drive=full.drive, friction=full.friction, timing=full.timing.replace(delay=0.0))
    (tmp_path / "rig.toml").write_text(rig_to_toml(rig))
    argv = ["compare", "--rig", str(tmp_path / "rig.toml"), "--slew-angle", "1.5708", "--tf", "0.6",
            "--controllers", "lqg", "--t-end", "1.0", "--out", str(out), "--json"]
    assert main(argv) == 0
    cli = json.loads(capsys.readouterr().out)
    api = compare(rig, "slew", "lqg",
                  CompareSettings(run=RunChoice(t_end=1.0), scenario=ScenarioChoice(slew_angle=1.5708, t_f=0.6)))
    assert cli[0]["residual_tip_max_m"] == api.metrics["lqg"]["residual_tip_max_m"]
    report = (out / "report.md").read_text()
    assert "## The rig" in report and "DC motor R = 2.6 ohm" in report and "integral action" in report.lower()
    section = report[report.index("## The rig ladder"):]
    ladder = section[:section.index("\n## ", 5)].splitlines()
    steps = [line.split("|")[1].strip() for line in ladder if line.startswith("| ") and "lqg" in line]
    assert steps == ["ideal plant", "+ friction", "+ drive"]
    last = [line for line in ladder if line.startswith("| + drive")][0]
    assert f"{1e3 * api.metrics['lqg']['residual_tip_max_m']:.4g}" in last


def test_ladder_rigs_add_one_part_at_a_time():
    from hubbeam_ctrl.study.ladder import ladder_rigs
    rig = load_rig("servo_link")
    steps = ladder_rigs(rig)
    assert steps[0][1].is_ideal is False or steps[0][1].drive.is_ideal      # the beam alone (its dt kept)
    assert steps[0][1].timing.dt == rig.timing.dt and steps[0][1].friction.is_ideal
    assert steps[-1][1] == rig
    ideal = ladder_rigs(Rig(beam=Params()))
    assert [label for label, _ in ideal] == ["ideal plant"]


@pytest.mark.slow
def test_sweep_on_a_rig_gives_the_rows_of_compare(tmp_path):
    """[study] rig = "servo_link": the sweep's case at the base beam equals compare(rig=...) bit for bit
    (the rig's dt, its hardware and the controllers on the rig, the same code path), and a spec whose
    rig file sits beside it is read relative to it."""
    from hubbeam_ctrl.study.spec_files import load_spec
    from hubbeam_ctrl.study.sweep import sweep
    study = {"controllers": ["lqg"], "rig": "servo_link", "t_f": 0.6, "slew_angle": 1.5708, "t_end": 1.0}
    spec = load_spec({"study": study, "grid": {"m_t": [0.0, 0.005]}})
    assert spec.dt == 1e-3 and spec.rig == load_rig("servo_link")
    df = sweep(spec, workers=1, progress=False)
    ref = compare(load_rig("servo_link"), "slew", "lqg",
                  CompareSettings(run=RunChoice(t_end=1.0), scenario=ScenarioChoice(t_f=0.6, slew_angle=1.5708)))
    row = df[df["m_t"] == 0.0].iloc[0]
    for key in ("peak_tip_m", "residual_tip_max_m", "final_angle_error_rad", "torque_squared_integral_n2m2s"):
        assert row[key] == ref.metrics["lqg"][key], key
    assert row["error"] == "" and row["verdict"] == ref.metrics["lqg"]["verdict"]
    # the rig travels in the spec's identity (study.json, --resume): from_dict(to_dict) is the same study
    assert load_spec(spec.to_dict()).hash() == spec.hash()
    from hubbeam_ctrl.plant.rig import rig_to_toml
    (tmp_path / "my_rig.toml").write_text(rig_to_toml(load_rig("servo_link")))
    (tmp_path / "spec.toml").write_text('[study]\ncontrollers = ["lqg"]\nrig = "my_rig.toml"\nt_f = 0.6\n')
    assert load_spec(tmp_path / "spec.toml").rig == load_rig("servo_link")


def test_sweep_rig_option_replaces_the_specs_rig(tmp_path, capsys):
    """hubbeam sweep SPEC --rig RIG: the rig replaces [study] rig; a bad one is one line naming --rig,
    exit 2, nothing written."""
    from hubbeam_ctrl.cli.main import main
    from hubbeam_ctrl.study.spec_files import load_spec
    spec = tmp_path / "spec.toml"
    spec.write_text('[study]\ncontrollers = ["lqg"]\nt_f = 4.0\nslew_angle = 0.3\n')
    assert load_spec(spec).rig is None
    assert load_spec(spec, rig="servo_link").rig == load_rig("servo_link")
    assert load_spec(spec, rig="servo_link").dt == 1e-3
    out = tmp_path / "out"
    assert main(["sweep", str(spec), "--rig", "nope", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("hubbeam: error: --rig") and "nope" in err[0], err
    assert not out.exists()


def test_design_and_tune_take_the_rig(tmp_path, capsys, monkeypatch):
    """Issue 22 item 4: hubbeam design --rig designs on the rig's beam (reflected inertia), its drive's
    torque limit and its sample time; hubbeam tune --rig runs the spec on the rig; a bad rig is one line
    naming --rig, exit 2."""
    import json

    from hubbeam_ctrl.cli.main import main
    rig = load_rig("servo_link")
    out = tmp_path / "c.npz"
    assert main(["design", "--rig", "servo_link", "--controller", "lqr", "--tf", "0.6",
                 "--slew-angle", "1.5708", "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["dt"] == rig.timing.dt == 1e-3 and summary["tau_max_nm"] == rig.beam.tau_max
    assert main(["design", "--rig", "servo_link", "--controller", "lqr", "--tau-max", "5",
                 "--out", str(tmp_path / "d.npz")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--tau-max" in err[0] and "the rig's drive" in err[0], err
    spec = tmp_path / "spec.toml"
    spec.write_text('[study]\ncontrollers = ["lqr"]\nt_f = 0.6\nslew_angle = 1.5708\n[grid]\nm_t = [0.0]\n')
    assert main(["tune", str(spec), "--controller", "lqr", "--rig", "nope", "--out", str(tmp_path / "t")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("hubbeam: error: --rig"), err
    seen = {}

    def fake_tune(spec, controller, **kw):
        seen["rig"], seen["dt"] = spec.rig, spec.dt
        raise KeyboardInterrupt
    monkeypatch.setattr("hubbeam_ctrl.study.tune.tune", fake_tune)
    assert main(["tune", str(spec), "--controller", "lqr", "--rig", "servo_link", "--out", str(tmp_path / "t")]) == 130
    assert seen == {"rig": rig, "dt": rig.timing.dt}
