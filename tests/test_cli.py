"""The ``hubbeam`` CLI: JSON outputs, files, and exit status 2 with one line on bad input."""

import json
import subprocess
import sys

import numpy as np
import pytest

from hubbeam_ctrl.cli.main import main


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_modes_json(capsys):
    code, out, _ = run(capsys, "modes", "--model", "tlam", "--spin", "1", "--tip-mass", "0", "--json")
    data = json.loads(out)
    assert code == 0 and data["model"] == "tlam" and data["hub"] == "prescribed"
    np.testing.assert_allclose(data["frequencies_hz"], [0.4353, 2.9003, 8.1316, 15.9369, 26.3457], rtol=1.5e-3)


def test_critical_speed_json(capsys):
    code, out, _ = run(capsys, "critical-speed", "--json")
    assert code == 0 and json.loads(out)["critical_speed_rad_s"] == pytest.approx(2.60, rel=0.01)
    code, out, err = run(capsys, "critical-speed", "--model", "foam", "--json")
    assert json.loads(out) == {"model": "foam", "critical_speed_rad_s": None} and "no critical speed" in err


def test_simulate_outputs(capsys, tmp_path):
    csv, png = tmp_path / "run.csv", tmp_path / "run.png"
    code, out, _ = run(capsys, "simulate", "--model", "foam", "--maneuver", "spinup", "--wf", "2.8",
                       "--tf", "30", "--t-end", "40", "--tip-mass", "0", "--out", str(csv),
                       "--plot", str(png), "--json")
    s = json.loads(out)
    assert code == 0 and set(s) == {"peak_tip_m", "residual_tip_m", "peak_axial_m", "final_theta_rad",
                                    "final_theta_dot_rad_s", "diverged", "wall_s", "integrator",
                                    "peak_error_estimate"}
    assert s["integrator"] == "idas" and s["peak_error_estimate"] is None      # a spin-up: IDAS
    assert s["peak_tip_m"] == pytest.approx(0.22, rel=0.15) and s["final_theta_dot_rad_s"] == pytest.approx(2.8)
    assert csv.read_text().splitlines()[0].startswith("t [s],theta [rad],theta_dot [rad/s],v_tip [m],")
    assert png.stat().st_size > 10000


def test_simulate_diverging_tlam_is_flagged(capsys):
    code, out, err = run(capsys, "simulate", "--model", "tlam", "--maneuver", "spinup", "--wf", "3",
                         "--t-end", "60", "--tip-mass", "0", "--json")
    assert code == 0 and json.loads(out)["diverged"] is True and "TLAM left its range" in err


@pytest.mark.parametrize("argv,needle", [
    (["modes", "--spin", "fast"], "spin"),
    (["modes", "--tip-mass", "-1"], "m_t"),
    (["modes", "--tip-position", "9"], "--tip-position (l) must be in"),
    (["modes", "--n-modes", "0"], "n_axial"),
    (["modes", "--model", "beam"], "--model"),
    (["simulate", "--model", "foam", "--maneuver", "spinup", "--t-end", "-3"], "t-end"),
    (["simulate", "--model", "foam", "--maneuver", "torque", "--t-end", "3", "--tf", "nan"], "tf"),
    (["simulate", "--model", "foam", "--maneuver", "spinup", "--t-end", "3", "--out", "x.txt"], "out"),
    (["simulate", "--model", "foam", "--maneuver", "spinup", "--t-end", "3", "--out", "/no/dir/x.csv"], "out"),
    (["modes", "--params", "/no/such.toml"], "params file"),
])
def test_bad_input_exit_2_one_line(capsys, argv, needle):
    code, out, err = run(capsys, *argv)
    assert code == 2
    assert err.count("\n") == 1 and needle in err and "Traceback" not in err


def test_console_script_exit_status():
    proc = subprocess.run([sys.executable, "-m", "hubbeam_ctrl.cli.main", "modes", "--n-modes", "30"],
                          capture_output=True, text=True)
    assert proc.returncode == 2 and "--n-modes (n_axial) must be an integer in 1..20" in proc.stderr
    assert "Traceback" not in proc.stderr
    proc = subprocess.run([sys.executable, "-m", "hubbeam_ctrl.cli.main", "--help"], capture_output=True, text=True)
    assert proc.returncode == 0
    for command in ("modes", "critical-speed", "simulate", "linearize"):
        assert command in proc.stdout


def test_cli_start_up_does_not_import_python_control():
    """``hubbeam modes`` starts fast (about 1 s instead of 2-3 s): importing the CLI, building
    its parser and running ``modes`` pull in neither python-control nor SciPy nor Matplotlib;
    the layers that need them load them when a command does."""
    code = ("import sys, hubbeam_ctrl.cli.main; heavy = ('control', 'scipy', 'matplotlib'); "
            "print(sorted(m for m in heavy if m in sys.modules)); "
            "sys.modules['hubbeam_ctrl.cli.main'].main(['modes', '--json']); "
            "print(sorted(m for m in heavy if m in sys.modules))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    after_import, modes_json, after_modes = proc.stdout.splitlines()
    assert after_import == "[]" and after_modes == "[]"
    assert json.loads(modes_json)["frequencies_hz"][0] == pytest.approx(0.41449, rel=1e-4)


def test_linearize_help_lists_the_outputs(capsys):
    from hubbeam_ctrl.linear.statespace import DEFAULT_OUTPUTS, OUTPUTS
    with pytest.raises(SystemExit):
        main(["linearize", "--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    assert f"among {','.join(OUTPUTS)} (default {','.join(DEFAULT_OUTPUTS)})" in help_text


def test_json_output_has_no_progress_lines(capfd, tmp_path):
    """``--json`` keeps stdout machine-readable and stderr free of progress output."""
    code = main(["simulate", "--model", "foam", "--maneuver", "torque", "--t-end", "2", "--n-modes", "2",
                 "--json"])
    out, err = capfd.readouterr()
    assert code == 0 and json.loads(out)["diverged"] is False and err == ""
