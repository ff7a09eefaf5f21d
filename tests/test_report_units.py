"""The report's columns and Targets hold each quantity in its own unit (issue 36, Build 4).

On ``servo_link`` (a DC motor) the controllers command volts: the table shows the command with
its unit, the hub torque in N m, the voltage and the current; the Targets check ``abs(u) <=
V_max`` and ``abs(i) <= I_max``, not volts against ``tau_max`` in N m (before, every feedback
controller was marked "no" at 3.5 V against 1.86 N m).
"""

import csv
import math

import pytest

from hubbeam_ctrl.plant.rig import load_rig
from hubbeam_ctrl.study import Slew, compare
from hubbeam_ctrl.study.compare_values import CompareSettings, RunChoice
from hubbeam_ctrl.study.report import drive_limits_text, format_table, markdown_table, write_outputs


@pytest.fixture(scope="module")
def servo():
    return compare(load_rig("servo_link"), Slew(math.pi / 2, 0.6), "openloop,lqr",
                   CompareSettings(run=RunChoice(t_end=3.0)))


def _column(table: str, header: str) -> list:
    rows = [[c.strip() for c in line.strip("|").split("|")] for line in table.splitlines() if line.startswith("|")]
    k = rows[0].index(header)
    return [r[k] for r in rows[2:]]


@pytest.mark.slow
def test_servo_link_table_and_targets_in_the_drives_units(servo, tmp_path):
    m = servo.metrics["lqr"]
    rig = load_rig("servo_link")
    assert m["command_unit"] == "V" and m["peak_command"] > rig.beam.tau_max      # volts above 1.86
    assert m["peak_voltage_v"] == m["peak_command"] <= rig.drive.V_max
    assert m["peak_hub_torque_nm"] < rig.beam.tau_max and m["peak_torque_nm"] == m["peak_hub_torque_nm"]
    assert m["within_drive_limits"] is True
    table = markdown_table(servo.metrics)
    assert _column(table, "peak u") == [f"{servo.metrics[n]['peak_command']:.3g} V" for n in servo.metrics]
    assert _column(table, "max du/sample") == [f"{servo.metrics[n]['peak_command_step']:.3g} V"
                                               for n in servo.metrics]
    assert _column(table, "peak tau_hub Nm") == [f"{servo.metrics[n]['peak_hub_torque_nm']:.4g}" for n in servo.metrics]
    assert _column(table, "peak A") == [f"{servo.metrics[n]['peak_current_a']:.3g}" for n in servo.metrics]
    assert _column(table, "u at limit s") == [f"{servo.metrics[n]['time_at_limit_s']:.3g}" for n in servo.metrics]
    assert "peak A" in format_table(servo.metrics)
    check = drive_limits_text(servo)
    assert check == "abs(u) <= V_max = 10 V, abs(i) <= I_max = 4 A, hub torque within the drive's 3.12 N m"
    write_outputs(servo, tmp_path / "out")
    report = (tmp_path / "out" / "report.md").read_text()
    targets = report.split("## Targets (slew)", 1)[1].split("\n## ", 1)[0]
    assert _column(targets, check) == ["yes", "yes"]
    assert "abs(tau) <= tau_max" not in report
    assert "- Command: the DC motor's voltage [V] within +-V_max = 10 V (current limit I_max = 4 A)" in report
    rows = list(csv.DictReader(open(tmp_path / "out" / "metrics.csv")))
    assert [r["command_unit"] for r in rows] == ["V", "V"] and rows[1]["within_drive_limits"] == "True"


def test_torque_source_table_has_no_voltage_columns():
    from test_metrics import _run

    from hubbeam_ctrl.study.metrics import closed_loop_metrics
    m = closed_loop_metrics(_run(), 10.0, tau_max=100.0)
    table = markdown_table({"toy": m})
    assert _column(table, "peak u") == ["100 N m"] and _column(table, "peak tau_hub Nm") == ["100"]
    assert "peak V" not in table and "peak A" not in table


def test_command_figure_is_in_volts_with_v_max_on_a_dc_motor(servo):
    from hubbeam_ctrl.study.report import _command_figure
    ax = _command_figure(servo, "", None).axes[0]
    assert ax.get_ylabel() == "command voltage [V]"
    limits = sorted(line.get_ydata()[0] for line in ax.lines if line.get_linestyle() == ":")
    assert limits == [-10.0, 10.0]


def test_the_tip_figure_shades_the_residual_window_the_metrics_use(servo, tmp_path, monkeypatch):
    """The shaded window starts at t_f + the task's residual delay (the metrics' window), not at
    t_f + 5 s, which is the paper's slew's only (here t_f = 0.6 s, t_end = 3 s: the old shading
    started past the run's end)."""
    import hubbeam_ctrl.study.report as report
    calls = {}
    real = report.render

    def spy(plot, *args, **kwargs):
        calls[plot.__name__] = args
        return real(plot, *args, **kwargs)

    monkeypatch.setattr(report, "render", spy)
    write_outputs(servo, tmp_path / "out")
    sc = servo.scenario
    start = calls["plot_tip_deflection"][2]
    assert start == sc.t_f + sc.bands["residual_delay"] < sc.t_end
    assert f"from tf + {sc.bands['residual_delay']:g} s = {start:g} s" in (tmp_path / "out" / "report.md").read_text()


def test_a_quiet_open_loop_gives_no_percentage_in_the_table():
    """Where the open loop's residual already lies within the tip band (slow space booms: the table read
    10^6-10^20 %), ``% of OL`` reads "OL in band" and a note says why; metrics.json keeps the ratio. A
    loud open loop keeps the percentage."""
    from hubbeam_ctrl.study.report_tables import against_openloop, markdown_table
    base = {"verdict": "settled", "completed": True}
    quiet = {"openloop": {**base, "residual_tip_max_m": 2e-6}, "lqr": {**base, "residual_tip_max_m": 4e-3}}
    (note,) = against_openloop(quiet, 1e-4)
    assert "within the tip band 0.0001 m" in note and "2e-06 m" in note
    assert quiet["lqr"]["residual_pct_of_openloop"] == pytest.approx(2e5)
    assert quiet["lqr"]["openloop_within_tip_band"] is True
    assert markdown_table(quiet).count("OL in band") == 2 and "2e+05" not in markdown_table(quiet)
    loud = {"openloop": {**base, "residual_tip_max_m": 2e-2}, "lqr": {**base, "residual_tip_max_m": 4e-5}}
    assert against_openloop(loud, 1e-4) == []
    assert loud["lqr"]["residual_pct_of_openloop"] == pytest.approx(0.2) and "OL in band" not in markdown_table(loud)
    assert against_openloop({"lqr": dict(loud["lqr"])}, 1e-4) == []
    # an open loop that never moved (a fuzzed 2.4 m link whose drive cannot break 216 N m of Coulomb friction away)
    stuck = {"openloop": {**base, "residual_tip_max_m": 0.0, "final_angle_error_rad": -1.5708,
                          "settle_angle_rad": 1.6e-3}, "lqr": {**base, "residual_tip_max_m": 8e-4}}
    (note,) = against_openloop(stuck, 3e-4)
    assert "but it ends 1.57 rad off the target, outside the angle band 0.0016 rad: it did not do the task" in note
    assert "off the target" not in against_openloop(quiet, 1e-4)[0]
