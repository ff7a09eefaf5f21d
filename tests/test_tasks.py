"""The motor's torque limit in Params, tasks in physical terms, and their bad input (issue 11, items 1-2)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers import LQG, LQR, MPC, PD, DesignModel, LQRSettings, MPCSettings, OpenLoop, OpenLoopSettings
from hubbeam_ctrl import Params, load_params, save_params
from hubbeam_ctrl.cli.main import main
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.study import Slew, SpinUp, make_scenario

#: The issue's lab arm (a 1 m x 30 mm x 3 mm aluminium strip on a small hub, 1.5 N m motor).
LAB = Params(L=1, rho=2700, A=9e-5, E=69e9, I=6.75e-11, J_h=0.02, r=0.05, m_t=0.05, tau_max=1.5)


# -- item 1: the actuator is part of the plant -----------------------------------------------------
def test_tau_max_is_a_param_read_from_toml(tmp_path):
    assert Params().tau_max == 200.0
    path = tmp_path / "arm.toml"
    save_params(LAB, path)
    assert "tau_max = 1.5  # [N m]" in path.read_text()
    assert load_params(path) == LAB
    path.write_text("tau_max = -1\n")
    with pytest.raises(ParameterError, match=r"(^|: )tau_max must be in \(0, 1e\+09\] \[N m\], got -1"):
        load_params(path)


@pytest.fixture(scope="module")
def lab_design():
    return DesignModel.build(LAB.replace(n_transverse=2, n_axial=2), 0.0, 0.01)


@pytest.mark.parametrize("cls", [PD, LQR, LQG, MPC])
def test_every_controller_saturates_at_the_motor_limit(lab_design, cls):
    settings = MPCSettings(horizon=5) if cls is MPC else None
    ctrl = cls(lab_design, settings)
    assert ctrl.tau_max == 1.5
    y = np.zeros(lab_design.n_x if ctrl.measurement == "state" else 3)
    y[0] = -10.0                              # 10 rad behind the reference
    ctrl.reset()
    assert abs(ctrl(0.0, y)) == pytest.approx(1.5)           # clipped at the motor limit


def test_a_smaller_controller_limit_is_kept_a_larger_one_refused(lab_design):
    assert LQR(lab_design, LQRSettings(tau_max=1.0)).tau_max == 1.0
    with pytest.raises(ParameterError, match=r"^tau_max must be in \(0, 1.5\] N m"):
        LQR(lab_design, LQRSettings(tau_max=2.48))
    with pytest.raises(ParameterError, match=r"abs\(tau_m\) must be in \(0, 1.5\] N m"):
        OpenLoop(lab_design, OpenLoopSettings(tau_m=200.0))


# -- item 2: tasks in physical terms ---------------------------------------------------------------
def test_slew_baseline_is_eq44_scaled_to_angle_and_duration():
    J = LAB.total_inertia
    task = Slew(math.pi / 2, 1.2)
    assert task.baseline_torque(J) == pytest.approx(2 * math.pi * J * (math.pi / 2) / 1.2 ** 2)
    # the Eq. 44 slew of that amplitude turns by the same angle
    assert Slew.eq44(task.baseline_torque(J), 1.2, J).angle == pytest.approx(math.pi / 2)
    t_min = task.shortest_duration(J, 1.5)
    assert Slew(math.pi / 2, t_min).baseline_torque(J) == pytest.approx(1.5)
    sc = make_scenario(task, plant="foam", params=LAB, t_end=4.0)
    assert sc.target == math.pi / 2 and sc.t_f == 1.2 and sc.tau_max == 1.5
    assert sc.baseline_tau_m == pytest.approx(task.baseline_torque(J))
    assert sc.reference.theta[-1] == pytest.approx(math.pi / 2)
    assert np.max(np.abs(sc.reference.torque)) <= 1.5
    same = make_scenario("slew", plant="foam", params=LAB, slew_angle=math.pi / 2, t_f=1.2, t_end=4.0)
    assert same.baseline_tau_m == sc.baseline_tau_m and same.target == sc.target


def test_without_angle_the_slew_is_eq44_as_before():
    sc = make_scenario("slew", plant="foam")
    p = Params()
    assert sc.baseline_tau_m == 200.0 and sc.tau_max == 200.0
    assert sc.target == pytest.approx(200 * 10 ** 2 / (2 * math.pi * p.total_inertia))


def test_spinup_task():
    sc = make_scenario(SpinUp(2.0, 12.0), plant="foam", t_end=20.0)
    assert sc.design_spin == 2.0 and sc.t_f == 12.0 and sc.baseline == "feedforward"
    J = Params().total_inertia
    assert SpinUp(2.0, 12.0).peak_torque(J) == pytest.approx(2 * J * 2.0 / 12.0)


@pytest.mark.parametrize("make, words", [
    (lambda: Slew(0.0, 1.0), r"^angle must be a finite number != 0 \[rad\]"),
    (lambda: Slew(float("nan"), 1.0), r"^angle must be a finite number \[rad\], got nan"),
    (lambda: Slew(float("inf"), 1.0), r"^angle must be a finite number \[rad\], got inf"),
    (lambda: Slew(1.0, 0.0), r"^duration must be a finite number > 0 \[s\]"),
    (lambda: SpinUp(float("nan"), 1.0), r"^rate must be a finite number"),
    (lambda: make_scenario("slew", plant="foam", params=LAB, slew_angle=0.0, t_f=1.2, t_end=4.0),
     r"^slew_angle must be a finite number != 0"),
    (lambda: make_scenario("slew", plant="foam", params=LAB, slew_angle=math.inf, t_f=1.2, t_end=4.0),
     r"^slew_angle must be a finite number"),
    (lambda: make_scenario("slew", plant="foam", params=LAB, slew_angle=math.pi / 2, t_f=0.9, t_end=4.0),
     r"^tf must be >= 1.0541 s \(the shortest in which tau_max = 1.5 N m turns 1.571 rad"),
    (lambda: make_scenario(Slew(math.pi / 2, 0.9), plant="foam", params=LAB, t_end=4.0),
     r"^duration must be >= 1.0541 s"),
    (lambda: make_scenario("slew", plant="foam", params=LAB, tau_max=2.0, t_f=1.2, t_end=4.0),
     r"^tau_max must be in \(0, 1.5\] N m"),
    (lambda: make_scenario(SpinUp(10.0, 1.0), plant="foam", params=LAB, t_end=4.0),
     r"^duration must be >= 2.2518 s"),
])
def test_bad_tasks_are_one_line(make, words):
    with pytest.raises(ParameterError, match=words) as info:
        make()
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("argv, words", [
    (["--slew-angle", "0"], "slew-angle must be a finite number != 0"),
    (["--slew-angle", "nan"], "slew-angle must be a finite number"),
    (["--slew-angle", "inf"], "slew-angle must be a finite number"),
    (["--slew-angle", "1.5708", "--tf", "0.9"], "tf must be >= 1.0541 s"),
    (["--tau-max", "2"], "tau-max must be in (0, 1.5] N m"),
    (["--scenario", "spinup", "--slew-angle", "1"], "slew-angle applies to --scenario slew only"),
])
def test_cli_bad_tasks_exit_2_with_one_line(tmp_path, capsys, argv, words):
    toml = tmp_path / "arm.toml"
    save_params(LAB, toml)
    rc = main(["compare", "--plant", "foam", "--params", str(toml), "--tf", "1.2", "--t-end", "4",
               "--out", str(tmp_path / "out")] + argv)
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and words in err, err
