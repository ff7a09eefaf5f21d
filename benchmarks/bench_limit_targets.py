"""Issue 22's targets, measured: every beam and rig at 1.5 x its time-optimal slew. Prints JSON.

Run: ``.venv/bin/python benchmarks/bench_limit_targets.py [--cases lab,servo,servo_beam,paper,payload]
[--controllers lqr,lqg,mpc] [--references task,rigid,optimal] [--factors 1.3,1.5,2] [--out F.json]``
(about 5-10 min on 2 idle cores with a C compiler; ``--controllers lqg --references optimal`` for one
column).

For each case the time-optimal rest-to-rest slew ``T_opt`` of the beam within its drive's limits
(:func:`hubbeam_ctrl.limit.time_optimal_slew`, FOAM, the design's modes) gives the task
``Slew(angle, 1.5 T_opt)``; LQR, LQG and MPC then run with all defaults on the FOAM evaluation
plant, with each of ``--references``: the default (``reference="task"``: the slew planned on the
design model, :func:`controllers.planning.planned_slew_reference`), the smooth rigid reference
(``"rigid"``, the default before) and the minimum-vibration slew of the nonlinear beam as
reference and feedforward (``"optimal"``). The issue's
targets, checked per controller:

* settled (hub and tip in their bands for good) no later than ``t_f`` plus one period of the
  first free-hub flexible mode of the design model;
* residual tip vibration <= 0.1 % of L;
* final angle error <= 1e-3 of the slew;
* within the drive's limits at every sample (torque, or volts on a DC motor).

Cases: ``lab`` (the 1 m aluminium lab arm of the tests, 90 degrees), ``servo`` (the ``servo_link``
preset with its DC drive, friction, encoder and delay, 90 degrees), ``servo_beam`` (the same link
without drive and friction: its beam with the rotor's inertia, a torque source at the stall
torque), ``paper`` (Table 1's beam, 1 rad, 200 N m) and ``payload`` (Table 1's beam designed for
0-0.5 kg, run at 0, 0.1, 0.3 and 0.5 kg; the 1.5 x T_opt of the nominal 0.1 kg),
``payload_heaviest`` (the same at 1.5 x T_opt of the heaviest payload, 0.5 kg) and
``matched_heaviest`` (a design that knows the 0.5 kg payload, at the nominal's 1.5 x T_opt) and
``matched_range`` (at each payload a design that knows it, at 1.5 x T_opt of the heaviest) and
``payload_error`` (designs for a payload 2-5 % or 10-20 g off the plant's, the same task) and
``payload_learning`` (the nominal LQR, LQG and MPC learning the payload during that task,
:mod:`controllers.payload_learning`) and ``payload_learning_lab`` (the same on the lab arm,
0-0.2 kg: all defaults, and instant re-plans on the design's modes).
"""

from __future__ import annotations

import functools
import math
import os
import platform
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from benchjson import bench_parser, comma_floats, emit  # noqa: E402

from controllers import DesignModel  # noqa: E402
from controllers.scaling import first_mode  # noqa: E402
from hubbeam_ctrl import Params  # noqa: E402
from hubbeam_ctrl.limit import time_optimal_slew  # noqa: E402
from hubbeam_ctrl.plant.rig import Rig, load_rig  # noqa: E402
from hubbeam_ctrl.study.compare import compare  # noqa: E402
from hubbeam_ctrl.study.compare_values import (  # noqa: E402
    CompareSettings,
    DesignChoice,
    PayloadChoice,
    PlantChoice,
    compare_arguments,
)
from hubbeam_ctrl.study.payload import payload_comparison  # noqa: E402
from hubbeam_ctrl.study.tasks import Slew  # noqa: E402

LAB = Params(L=1, rho=2700, A=9e-5, E=69e9, I=6.75e-11, J_h=0.02, r=0.05, m_t=0.05, tau_max=1.5)
NAMES = "lqr,lqg,mpc"
REFERENCES = ("task", "optimal")
FACTOR = 1.5
PAYLOAD_RANGE = (0.0, 0.5)
PAYLOADS = (0.0, 0.1, 0.3, 0.5)
LAB_RANGE = (0.0, 0.2)
LAB_PAYLOADS = (0.0, 0.05, 0.1, 0.2)


def _period(params: Params, dt: float) -> float:
    """Period of the first free-hub flexible mode of the design model [s]."""
    return 2 * math.pi / first_mode(DesignModel.build(params, 0.0, dt, 1))


def _judge(comparison, params: Params, angle: float, limit: float) -> dict:
    """The issue's four targets for each controller of one comparison."""
    sc = comparison.scenario
    period = _period(params, sc.dt)
    rows = {}
    for name, m in comparison.metrics.items():
        res = comparison.results[name]
        hw = res.settings.get("hardware") or {}
        command = hw.get("command", "torque")
        peak = float(max((abs(float(v)) for v in res.tau if math.isfinite(v)), default=float("nan")))
        settle = m.get("settling_time_s")
        row = {"verdict": m["verdict"], "settling_time_s": settle, "settle_target_s": sc.t_f + period,
               "residual_pct_of_L": m["residual_pct_of_L"],
               "final_error_over_slew": abs(m["final_angle_error_rad"]) / abs(angle),
               "peak_command": peak, "command": command, "limit": limit}
        row["met"] = {"settled": m["verdict"] == "settled" and settle is not None and settle <= sc.t_f + period,
                      "residual": m["residual_pct_of_L"] <= 0.1,
                      "final_error": row["final_error_over_slew"] <= 1e-3,
                      "within_limits": peak <= limit * (1 + 1e-9)}
        row["all_met"] = all(row["met"].values())
        rows[name] = row
    return rows


def _case(label, beam, angle, t_opt, limit, factor=FACTOR, **options) -> dict:
    """The chosen references on one beam or rig at ``factor`` x T_opt."""
    t_f = factor * t_opt
    out = {"t_opt_s": t_opt, "t_f_s": t_f, "angle_rad": angle, "runs": {}}
    for reference in REFERENCES:
        t0 = time.perf_counter()
        c = compare(**compare_arguments("foam", Slew(angle, t_f), NAMES, reference=reference, **options))
        run = _judge(c, beam, angle, limit)
        out["runs"][reference] = {"controllers": run, "wall_s": time.perf_counter() - t0}
        print(f"{label:10s} {reference:8s} " + "  ".join(
            f"{n}: {r['verdict']} {r['settling_time_s'] or float('nan'):.3g}/{r['settle_target_s']:.3g} s "
            f"{r['residual_pct_of_L']:.3g} %L {'MET' if r['all_met'] else 'missed'}" for n, r in run.items()),
            file=sys.stderr)
    return out


def _learning_case(beam: Params, angle: float, t_f: float, payload_range, payloads, settings=None) -> dict:
    """``beam``'s nominal LQR, LQG and MPC learning the payload (``settings``, default all defaults over
    ``payload_range``) during a slew by ``angle`` in ``t_f``, on plants carrying each of ``payloads``."""
    from controllers.payload_learning import PayloadLearningSettings
    settings = (settings or PayloadLearningSettings()).replace(payload_min_kg=payload_range[0],
                                                               payload_max_kg=payload_range[1])
    runs = {}
    for m in payloads:
        t0 = time.perf_counter()
        c = compare(beam, Slew(angle, t_f), NAMES,
                    CompareSettings(plant=PlantChoice(plant_params=beam.replace(m_t=m)),
                                    payload=PayloadChoice(payload_learning=settings)))
        rows = _judge(c, beam.replace(m_t=m), angle, beam.tau_max)
        for name, row in rows.items():
            row["replans"] = c.controllers[name].log
        runs[f"{m:g}"] = {"controllers": rows, "wall_s": time.perf_counter() - t0}
        print(f"learning {m:g} kg " + "  ".join(
            f"{n}: {r['verdict']} {r['settling_time_s'] or float('nan'):.3g}/{r['settle_target_s']:.3g} s "
            f"{r['residual_pct_of_L']:.3g} %L {'MET' if r['all_met'] else 'missed'} re-plans "
            + ",".join(f"{e['wall_s']:.2f}s/{e['modes']}m{'/dropped' if e['dropped'] else ''}"
                       for e in r["replans"]) for n, r in rows.items()), file=sys.stderr)
    return {"t_f_s": t_f, "settings": settings.to_dict(), "runs": runs}


def _payload_case(paper: Params, t_opt: float, factor: float = FACTOR) -> dict:
    """Table 1's beam designed for PAYLOAD_RANGE, run at PAYLOADS, the task at ``factor`` x ``t_opt``."""
    t_f = factor * t_opt
    payload = {"t_opt_s": t_opt, "t_f_s": t_f, "runs": {}}
    for reference in REFERENCES:
        t0 = time.perf_counter()
        pc = payload_comparison(None, Slew(1.0, t_f), "openloop," + NAMES,
                                CompareSettings(design=DesignChoice(reference=reference),
                                                payload=PayloadChoice(payload_range=PAYLOAD_RANGE)),
                                masses=PAYLOADS)
        by_mass = {}
        for m, c in pc.comparisons.items():
            c.metrics.pop("openloop", None)
            by_mass[f"{m:g}"] = _judge(c, paper.replace(m_t=m), 1.0, paper.tau_max)
        payload["runs"][reference] = {"by_payload_kg": by_mass, "wall_s": time.perf_counter() - t0}
        print(f"payload    {reference:8s} " + "; ".join(
            f"{m} kg: " + ",".join(f"{n} {r['verdict']} {r['settling_time_s'] or float('nan'):.3g}/"
                                   f"{r['settle_target_s']:.3g} s {r['residual_pct_of_L']:.2g} %L "
                                   f"{'MET' if r['all_met'] else 'missed'}" for n, r in rows.items())
            for m, rows in by_mass.items()), file=sys.stderr)
    return payload


@functools.cache
def _t_opt(beam: str) -> float:
    """Time-optimal duration [s] of each beam's slew (computed once, whatever the factors)."""
    servo = load_rig("servo_link")
    if beam == "lab":
        return time_optimal_slew(LAB, math.pi / 2).duration_s
    if beam == "servo":
        return time_optimal_slew(servo, math.pi / 2).duration_s
    if beam == "servo_beam":
        return time_optimal_slew(Rig(beam=servo.plant_params).plant_params, math.pi / 2).duration_s
    paper = Params()
    return time_optimal_slew(paper if beam == "paper" else paper.replace(m_t=PAYLOAD_RANGE[1]), 1.0).duration_s


def run_cases(cases, factor: float = FACTOR) -> dict:
    """Measure the chosen cases with tasks at ``factor`` x T_opt; returns a JSON-ready dict."""
    out = {}
    angle = math.pi / 2
    if "lab" in cases:
        out["lab"] = _case("lab", LAB, angle, _t_opt("lab"), LAB.tau_max, factor, params=LAB)
    servo = load_rig("servo_link")
    if "servo" in cases:
        out["servo"] = _case("servo", servo.plant_params, angle, _t_opt("servo"), servo.drive.V_max, factor, rig=servo)
    if "servo_beam" in cases:
        beam = Rig(beam=servo.plant_params)
        out["servo_beam"] = _case("servo_beam", beam.plant_params, angle, _t_opt("servo_beam"),
                                  beam.plant_params.tau_max, factor, rig=beam)
    paper = Params()
    if "paper" in cases:
        out["paper"] = _case("paper", paper, 1.0, _t_opt("paper"), paper.tau_max, factor)
    if "payload" in cases:
        out["payload"] = _payload_case(paper, _t_opt("paper"), factor)
    heaviest = paper.replace(m_t=PAYLOAD_RANGE[1])
    if "payload_heaviest" in cases:
        out["payload_heaviest"] = _payload_case(paper, _t_opt("heaviest"), factor)
    if "matched_heaviest" in cases:
        # the design knows the heaviest payload; the task of the nominal payload (its factor x T_opt)
        out["matched_heaviest"] = _case("matched", heaviest, 1.0, _t_opt("paper"), paper.tau_max, factor,
                                        params=heaviest)
        out["matched_heaviest"]["t_opt_heaviest_s"] = _t_opt("heaviest")
    if "matched_range" in cases:
        # each payload's own design (plan, gain, filter on it): what knowing the payload buys on
        # the range's task, factor x T_opt of the heaviest payload (the slowest in the range)
        out["matched_range"] = {f"{m:g}": _case(f"own {m:g} kg", paper.replace(m_t=m), 1.0, _t_opt("heaviest"),
                                                paper.tau_max, factor, params=paper.replace(m_t=m))
                                for m in PAYLOADS}
    if "payload_learning" in cases:
        # the nominal design learning the payload during the slew (controllers.payload_learning), at
        # factor x T_opt of the heaviest payload; LQR, MPC (the state) and LQG (its estimate)
        out["payload_learning"] = _learning_case(paper, 1.0, factor * _t_opt("heaviest"), PAYLOAD_RANGE, PAYLOADS)
    if "payload_learning_lab" in cases:
        # the same on the lab arm, 0-0.2 kg, 90 degrees at factor x T_opt of 0.2 kg: all defaults
        # (real time), and the method with instant re-plans on the design's modes (real_time off)
        from controllers.payload_learning import PayloadLearningSettings
        t_f = factor * time_optimal_slew(LAB.replace(m_t=LAB_RANGE[1]), math.pi / 2).duration_s
        instant = PayloadLearningSettings(allowance_s=0.0, real_time=False, modes=LAB.n_transverse)
        out["payload_learning_lab"] = {
            "defaults": _learning_case(LAB, math.pi / 2, t_f, LAB_RANGE, LAB_PAYLOADS),
            "instant_design_modes": _learning_case(LAB, math.pi / 2, t_f, LAB_RANGE, LAB_PAYLOADS, instant)}
    if "payload_error" in cases:
        # a design for a payload a little off the true one, at 1.5 x T_opt of the heaviest: how well
        # the payload must be known (relative errors; absolute ones at 0 kg)
        out["payload_error"] = {}
        for true, designs in ((0.5, (0.475, 0.49, 0.51, 0.525)), (0.3, (0.285, 0.294, 0.306, 0.315)),
                              (0.0, (0.01, 0.02))):
            for m in designs:
                out["payload_error"][f"{true:g} kg plant, {m:g} kg design"] = _case(
                    f"{true:g}|{m:g}", paper.replace(m_t=true), 1.0, _t_opt("heaviest"), paper.tau_max, factor,
                    params=paper.replace(m_t=m), plant_params=paper.replace(m_t=true))
    return out


def _factors(text: str) -> list:
    """``--factors``: comma-separated positive numbers."""
    return comma_floats(text, lambda vs: all(math.isfinite(v) and v > 0 for v in vs),
                        "comma-separated numbers > 0 (units of T_opt)")


def main(argv=None) -> int:
    """Entry point; prints the JSON and writes it to ``--out`` when given."""
    global NAMES, REFERENCES
    ap = bench_parser(__doc__)
    ap.add_argument("--cases", default="lab,servo,servo_beam,paper,payload")
    ap.add_argument("--controllers", default=NAMES, help="controllers to run (default %(default)s)")
    ap.add_argument("--references", default=",".join(REFERENCES),
                    help="comma-separated compare(reference=...): task (the default: a slew task's planned "
                         "slew), rigid (the smooth rigid reference, the default before), planned, optimal "
                         "(default %(default)s)")
    ap.add_argument("--factors", type=_factors, default=str(FACTOR),
                    help="comma-separated task durations in units of T_opt (default %(default)s: the issue's); "
                         "several give a scan over fast and slow tasks, keyed by factor in the JSON")
    args = ap.parse_args(argv)
    NAMES, REFERENCES = args.controllers, tuple(args.references.split(","))
    cases = set(args.cases.split(","))
    factors = args.factors
    t0 = time.perf_counter()
    doc = {"benchmark": "limit_targets", "issue": 22, "factor_of_t_opt": factors[0] if len(factors) == 1 else factors,
           "controllers": NAMES, "references": list(REFERENCES),
           "machine": {"python": platform.python_version(), "cpus": os.cpu_count()},
           "cases": None, "wall_s": None}
    scan = {}
    for factor in factors:
        print(f"-- tasks at {factor:g} x T_opt", file=sys.stderr)
        scan[f"{factor:g}"] = run_cases(cases, factor)
    doc["cases"] = scan[f"{factors[0]:g}"] if len(factors) == 1 else scan
    doc["wall_s"] = time.perf_counter() - t0
    emit(doc, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
