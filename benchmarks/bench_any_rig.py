"""Issue 36's targets on rigs of other kinds: all defaults, a slew at 1.5 x each rig's own time-optimal T*.

Run: ``.venv/bin/python benchmarks/bench_any_rig.py [--rigs servo_link,...] [--out FILE]``

For each rig (a preset, or ``servo_link_delay1``: ``servo_link`` with a full sample of delay) the
time-optimal slew of the rig (``hubbeam_ctrl.limit.time_optimal_slew``: its drive, 5 modes), then
``compare`` of LQR, LQG and MPC on it at 1.5 T* with every other option default, and the same
comparison 4 times longer (the verdict must not change). Per controller: verdict, residual tip
[m] and as a fraction of L, final angle error [rad] and in counts (2 standard deviations of an
absolute angle sensor without an encoder), peak command and its limit, certificate radius, the
loop's disk and delay margins. ``docs/rig.md`` quotes this JSON (``benchmarks/results/bench_any_rig.json``;
``tests/test_any_rig.py`` keeps the two equal).
"""

from __future__ import annotations

import dataclasses
import math
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from benchjson import bench_parser, emit  # noqa: E402

from hubbeam_ctrl.limit import time_optimal_slew  # noqa: E402
from hubbeam_ctrl.plant.rig import load_rig  # noqa: E402
from hubbeam_ctrl.study import Slew, compare  # noqa: E402
from hubbeam_ctrl.study.bands import angle_count as sensor_count  # noqa: E402
from hubbeam_ctrl.study.compare_values import CompareSettings, RunChoice

#: Slew angle per rig [rad]: 90 degrees, 30 on the space boom (a 0.1 N m wheel turns a 100 kg m^2
#: spacecraft by 90 degrees in 1.5 minutes; 30 degrees is its everyday re-pointing).
ANGLES = {"space_boom": math.pi / 6}
FACTOR = 1.5
CONTROLLERS = ("lqr", "lqg", "mpc")


def rig_named(name: str):
    """A preset, or ``servo_link_delay1``: ``servo_link`` with one full sample of delay."""
    if name == "servo_link_delay1":
        rig = load_rig("servo_link")
        return dataclasses.replace(rig, timing=dataclasses.replace(rig.timing, delay=1.0))
    return load_rig(name)


def angle_count(rig) -> float:
    """One count of the angle sensor [rad]: the encoder's, or 2 standard deviations of an absolute
    angle sensor's noise (:func:`hubbeam_ctrl.study.bands.angle_count`)."""
    return sensor_count(rig)[0]


def case(name: str) -> dict:
    rig = rig_named(name)
    angle = ANGLES.get(name, math.pi / 2)
    start = time.perf_counter()
    t_opt = time_optimal_slew(rig, angle).duration_s
    t_opt_s = time.perf_counter() - start
    task = Slew(angle, FACTOR * t_opt)
    c = compare(rig, task, ",".join(CONTROLLERS))
    longer = compare(rig, task, ",".join(CONTROLLERS), CompareSettings(run=RunChoice(t_end=4 * c.scenario.t_end)))
    count = angle_count(rig)
    rows = {}
    for ctrl in CONTROLLERS:
        m = c.metrics[ctrl]
        rows[ctrl] = {
            "verdict": m["verdict"], "verdict_4x": longer.metrics[ctrl]["verdict"],
            "residual_tip_m": m["residual_tip_max_m"], "residual_fraction_of_L": m["residual_tip_max_m"] / rig.beam.L,
            "final_angle_error_rad": m["final_angle_error_rad"],
            "final_angle_error_counts": m["final_angle_error_rad"] / count,
            "peak_command": m.get("peak_command"), "command_unit": m.get("command_unit"),
            "within_drive_limits": m.get("within_drive_limits"),
            "loop_spectral_radius": m.get("loop_spectral_radius"), "disk_margin": m.get("disk_margin"),
            "delay_margin_s": m.get("delay_margin_s"), "settling_time_s": m.get("settling_time_s"),
            "settle_angle_rad": m.get("settle_angle_rad"), "settle_angle_source": m.get("settle_angle_source"),
            "verdict_reason": m["verdict_reason"]}
    return {"angle_rad": angle, "t_opt_s": t_opt, "t_opt_wall_s": t_opt_s, "t_f_s": task.duration,
            "t_end_s": c.scenario.t_end, "count_rad": count, "controllers": rows}


def table_lines(doc: dict) -> list:
    """The rows of docs/rig.md's table of these targets, from the JSON (a test keeps the two equal)."""
    lines = ["| rig | T* [s] | t_f [s] | LQR / LQG / MPC | same 4 x longer | largest residual tip | "
             "largest final error [counts] | within the drive's limits |",
             "|---|---|---|---|---|---|---|---|"]
    for name, case in doc["rigs"].items():
        rows = case["controllers"].values()
        verdicts = " / ".join(r["verdict"] for r in rows)
        same = all(r["verdict"] == r["verdict_4x"] for r in rows)
        resid = max(rows, key=lambda r: r["residual_tip_m"])
        err = max(abs(r["final_angle_error_counts"]) for r in rows)
        limits = all(r["within_drive_limits"] for r in rows)
        lines.append(f"| `{name}` | {case['t_opt_s']:.4g} | {case['t_f_s']:.4g} | {verdicts} | "
                     f"{'yes' if same else 'no'} | {resid['residual_tip_m']:.2g} m "
                     f"({resid['residual_fraction_of_L']:.2g} L) | "
                     f"{err:.2f} | {'yes' if limits else 'no'} |")
    return lines


def main(argv=None) -> None:
    """Run the rigs of ``--rigs`` and print (and keep) the JSON."""
    ap = bench_parser(__doc__)
    ap.add_argument("--rigs", default="servo_link,servo_link_delay1,accel_link,servo_payload,space_boom")
    args = ap.parse_args(argv)
    out = {"factor": FACTOR, "rigs": {}}
    for name in args.rigs.split(","):
        out["rigs"][name] = case(name)
    emit(out, args.out)


if __name__ == "__main__":
    main()
