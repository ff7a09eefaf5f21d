"""Issue 39's targets: designs certified over a payload set, checked by nonlinear runs, and the
certificate's cost.

Prints one JSON object (``--out FILE`` also writes it). Run:
``.venv/bin/python benchmarks/bench_robust.py --out benchmarks/results/bench_robust.json``.

Cases (every option default but the set and the task):

* ``table1``: the paper's beam and its default slew, payload 0-0.5 kg, damping floor 0.05 %
  in every mode (and the undamped radius of each design reported);
* ``lab``: the 1 m aluminium lab arm of the limit benchmarks, a 90 degree slew in 1.5 T*
  (its own time-optimal slew), payload 0-0.2 kg, floor 0.05 %;
* ``servo_link``: the rig preset (drive in volts, friction, encoder, 1 ms, half a sample of
  delay, its measured 3.4 % damping), a 90 degree slew in 1.5 T*, payload 0-30 g;
* ``servo_identified``: the same rig calibrated from its own records (a chirp and a step made
  by ``excitation`` on a guess 5 % off in E and 8 % in J_h, recorded on the preset with
  ``synthetic_record``, fitted by ``fit_rig``: E, J_h and the friction), its set the fit's 95 %
  intervals (``Uncertainty.from_intervals``) and a payload of 0-30 g.

For each controller: the nominal design's certificate, the robust design
(:func:`hubbeam_ctrl.study.robust_design.design_for_set`) and its certificate, and nonlinear runs
of it and of the open loop at the worst plant found, every corner and the centre of the set.

``timing``: the certificate of Table 1's nominal LQR (10-mode plant) over a 4-parameter set
(payload, E, J_h, damping), the search (a 3-point grid and 3 local climbs) against the named
alternative, a 6-point grid alone (1296 loops), in the same run.
"""

from __future__ import annotations

import math
import os
import sys
import time

sys.path.insert(0, os.path.dirname(__file__))
from benchjson import bench_parser, emit  # noqa: E402

from hubbeam_ctrl import Params  # noqa: E402
from hubbeam_ctrl.limit import time_optimal_slew  # noqa: E402
from hubbeam_ctrl.plant.rig import Rig, load_rig  # noqa: E402
from hubbeam_ctrl.plant.uncertainty import Uncertainty  # noqa: E402
from hubbeam_ctrl.study import Slew, compare  # noqa: E402
from hubbeam_ctrl.study.compare_values import CompareSettings, PlantChoice
from hubbeam_ctrl.study.robust_check import check_points, residual_score, run_at  # noqa: E402
from hubbeam_ctrl.study.robust_design import design_for_set  # noqa: E402
from hubbeam_ctrl.study.worst_case import certify_set  # noqa: E402

LAB = Params(L=1, rho=2700, A=9e-5, E=69e9, I=6.75e-11, J_h=0.02, r=0.05, m_t=0.05, tau_max=1.5)
CONTROLLERS = ("lqr", "lqg", "mpc")
FACTOR = 1.5
FLOOR = 0.0005


def _task(rig: Rig):
    t_opt = time_optimal_slew(rig, math.pi / 2).duration_s
    return Slew(math.pi / 2, FACTOR * t_opt), t_opt


def identified_servo() -> tuple:
    """``servo_link`` calibrated from its own synthetic records: the fitted rig and the fit's summary."""
    from hubbeam_ctrl.calibrate import FitSettings, excitation, fit_rig, synthetic_record
    truth = load_rig("servo_link")
    b = truth.beam
    guess = truth.replace(beam=b.replace(E=0.95 * b.E, J_h=1.08 * b.J_h))
    records = []
    for seed, kind, duration in ((1, "chirp", 6.0), (2, "step", 3.0)):
        x = excitation(guess, kind, duration, max_tip_deflection=0.02, max_hub_travel=1.0)
        records.append(synthetic_record(truth, x.t, x.input, seed=seed, source=kind))
    t0 = time.perf_counter()
    res = fit_rig(guess, records, "E,J_h,friction", settings=FitSettings(plant_modes=2), progress=False)
    intervals = {f.name: (float(lo), float(hi)) for f, (lo, hi) in zip(res.fields, res.interval)}
    truths = {"E": b.E, "J_h": b.J_h, "friction.viscous": truth.friction.viscous,
              "friction.coulomb": truth.friction.coulomb}
    summary = {"status": res.status, "wall_s": time.perf_counter() - t0, "intervals": intervals,
               "truth_inside": {k: bool(lo <= truths[k] <= hi) for k, (lo, hi) in intervals.items() if k in truths}}
    return res.rig, intervals, summary


def setup(name: str):
    """``(rig with its set, task or None, T* or None, notes)`` of a case."""
    if name == "table1":
        return Rig(beam=Params(), uncertainty=Uncertainty.from_table({"m_t": (0.0, 0.5), "damping": (FLOOR, FLOOR)})), \
            None, None, {}
    if name == "lab":
        rig = Rig(beam=LAB, uncertainty=Uncertainty.from_table({"m_t": (0.0, 0.2), "damping": (FLOOR, FLOOR)}))
        return (rig, *_task(rig), {})
    if name == "servo_identified":
        fitted, intervals, summary = identified_servo()
        table = {**Uncertainty.from_intervals(intervals).to_table(), "m_t": (0.0, 0.03)}
        table = {k: (max(lo, 0.0), hi) for k, (lo, hi) in table.items()}
        rig = fitted.replace(uncertainty=Uncertainty.from_table(table))
        return (rig, *_task(rig), {"identify": summary})
    rig = load_rig("servo_link").replace(uncertainty=Uncertainty.from_table({"m_t": (0.0, 0.03)}))
    return (rig, *_task(rig), {})


def case(name: str) -> dict:
    rig, task, t_opt, notes = setup(name)
    start = time.perf_counter()
    cmp = compare(rig, task or "slew", ("openloop",) + CONTROLLERS)
    u, bare = rig.uncertainty, rig.replace(uncertainty=Uncertainty())
    score = residual_score(cmp, bare, u)
    out = {"set": u.to_table(), "task": cmp.scenario.description, "t_opt_s": t_opt, "controllers": {}, **notes}
    for ctrl_name in CONTROLLERS:
        t0 = time.perf_counter()
        nominal = cmp.robust[ctrl_name]
        sd = design_for_set(cmp, ctrl_name, bare, u, score=score)
        wc = sd.certificate
        undamped = None
        if "damping" in u.names:
            zero = Uncertainty.from_table({**u.to_table(), "damping": (0.0, 0.0)})
            undamped = certify_set(sd.controller, bare, zero, plant_modes=cmp.plant.modes, margins=False).worst.radius
        checks = []
        for kind, values in check_points(u, wc.worst.values):
            m = run_at(cmp, sd.controller, bare, values, u)
            checks.append({"point": kind, **m})
        out["controllers"][ctrl_name] = {
            "nominal_radius": nominal.worst.radius, "nominal_verdict": nominal.verdict(),
            "nominal_worst": nominal.worst.values, "design": sd.label(), "candidates": len(sd.tried),
            "radius": wc.worst.radius, "verdict": wc.verdict(), "worst": wc.worst.values,
            "worst_source": wc.worst_source, "undamped_radius": undamped, "disk_margin": wc.disk_margin,
            "checks": checks,
            "all_settled": all(c["verdict"] == "settled" for c in checks),
            "worst_residual_pct_of_openloop": max((c["residual_pct_of_openloop"] for c in checks), default=None),
            "peak_torque_nm": max(c["peak_torque_nm"] for c in checks),
            "all_within_drive_limits": all(bool(c["within_drive_limits"]) for c in checks),
            "wall_s": time.perf_counter() - t0}
    if name == "table1":
        out["range_designs"] = range_alternative(cmp, bare, u)
    out["wall_s"] = time.perf_counter() - start
    return out


def range_alternative(cmp, bare: Rig, u: Uncertainty) -> dict:
    """The named alternative: the payload-range designs of ``compare --payload-range``
    (:func:`hubbeam_ctrl.study.range_design.range_designs`, chosen by nonlinear runs at the two
    ends and the nominal payload, stability checked on the design model) under the same certificate."""
    from controllers import DesignModel, make_controller
    from hubbeam_ctrl.study.range_design import range_designs
    sc = cmp.scenario
    lo, hi = u["m_t"].lo, u["m_t"].hi
    design = DesignModel.build(sc.params, sc.design_spin, sc.dt, sc.params.n_transverse)
    t0 = time.perf_counter()
    chosen = range_designs(CONTROLLERS, sc, design, (lo, hi), plant_modes=cmp.plant.modes)
    out = {"wall_s": time.perf_counter() - t0}
    for name, rd in chosen.items():
        ctrl = make_controller(name, rd.design, rd.settings, sc.reference)
        wc = certify_set(ctrl, bare, u, plant_modes=cmp.plant.modes, margins=False)
        out[name] = {"choice": rd.choice, "radius": wc.worst.radius, "verdict": wc.verdict(),
                     "worst": wc.worst.values, "nonlinear_score": rd.score}
    return out


def timing() -> dict:
    """The certificate of a 10-mode loop over a 4-parameter set: search vs a grid alone."""
    p = Params()
    u = Uncertainty.from_table({"m_t": (0.0, 0.5), "E": (0.95 * p.E, 1.05 * p.E), "J_h": (180.0, 220.0),
                                "damping": (FLOOR, 0.01)})
    rig = Rig(beam=p)
    cmp = compare(rig, "slew", ["lqr"], CompareSettings(plant=PlantChoice(plant_modes=10)))
    ctrl = cmp.controllers["lqr"]
    t0 = time.perf_counter()
    search = certify_set(ctrl, rig, u, plant_modes=10)
    t_search = time.perf_counter() - t0
    t0 = time.perf_counter()
    grid = certify_set(ctrl, rig, u, plant_modes=10, grid=6, local_starts=0, margins=False)
    t_grid = time.perf_counter() - t0
    return {"set": u.to_table(), "plant_modes": 10, "loop_states": None,
            "search": {"wall_s": t_search, "evaluations": search.evaluations, "radius": search.worst.radius,
                       "worst": search.worst.values, "bound": search.bound},
            "grid6_alone": {"wall_s": t_grid, "evaluations": grid.evaluations, "radius": grid.worst.radius,
                            "worst": grid.worst.values},
            "cores": os.cpu_count()}


def table_lines(doc: dict) -> list:
    """The rows of docs/robust.md's table of results (a test keeps the page equal to the JSON)."""
    lines = ["| case | controller | nominal design: worst radius | robust design | worst radius (undamped) | "
             "settled everywhere | worst residual, % of that plant's OL | peak torque |",
             "|---|---|---|---|---|---|---|---|"]
    for case_name, c in doc["cases"].items():
        for name, r in c["controllers"].items():
            undamped = "" if r["undamped_radius"] is None else f" ({r['undamped_radius']:.6f})"
            lines.append(f"| {case_name} | {name} | {r['nominal_radius']:.6f} ({r['nominal_verdict']}) | "
                         f"{r['design']} | {r['radius']:.6f}{undamped} | {'yes' if r['all_settled'] else 'no'} | "
                         f"{r['worst_residual_pct_of_openloop']:.3g} | {r['peak_torque_nm']:.4g} N m |")
    alt = doc["cases"].get("table1", {}).get("range_designs")
    if alt:
        parts = [f"{n.upper()} {alt[n]['radius']:.6f} ({alt[n]['verdict']})" for n in CONTROLLERS if n in alt]
        lines.append("The named alternative on table1, the payload-range designs of `compare --payload-range` "
                     "under the same certificate: " + ", ".join(parts) + ".")
    t = doc["timing"]
    lines.append(f"Certificate of a {t['plant_modes']}-mode loop over a {len(t['set'])}-parameter set: "
                 f"{t['search']['wall_s']:.2f} s ({t['search']['evaluations']} loops, worst radius "
                 f"{t['search']['radius']:.7f}) against {t['grid6_alone']['wall_s']:.2f} s for a 6-point grid alone "
                 f"({t['grid6_alone']['evaluations']} loops, worst radius {t['grid6_alone']['radius']:.7f}).")
    return lines


def hinf_comparison() -> dict:
    """The H-infinity design (:mod:`controllers.hinf`, its robustness weight from the range's plants)
    against the multi-model Riccati (the LQR of ``compare --payload-range``,
    :func:`controllers.robust.design_for_range`) on Table 1 over 0-0.5 kg: both designed in one
    payload comparison, run on FOAM at 0 / 0.25 / 0.5 kg, certified over the range undamped and
    with the 0.05 % floor (``bench_msmpc.case`` with these two controllers)."""
    from bench_msmpc import case as range_case
    return range_case("table1", names=("lqr", "hinf"), masses=(0.0, 0.25, 0.5))


def hinf_lines(doc: dict) -> list:
    """docs/robust.md's H-infinity table from the JSON's ``hinf`` entry."""
    h = doc["hinf"]
    lines = ["| controller | design | radius undamped (worst payload) | radius 0.05 % | "
             + " | ".join(f"{m:g} kg: verdict, % of OL, peak N m" for m in h["masses_kg"]) + " |",
             "|---|---|---|---|" + "---|" * len(h["masses_kg"])]
    for n, r in h["controllers"].items():
        u, f = r["certificate"]["undamped"], r["certificate"]["floor_0.05pct"]
        cells = [f"{row['verdict']}, {row['residual_pct_of_openloop']:.3g}, {row['peak_torque_nm']:.4g}"
                 for m, row in r["runs"].items() if "worst" not in m]
        lines.append(f"| {n} | {h['designs'][n]['choice']} | {u['radius']:.7f} ({u['worst_payload_kg']:g} kg) | "
                     f"{f['radius']:.7f} | " + " | ".join(cells) + " |")
    return lines


def main(argv=None) -> None:
    """Certify the ``--cases`` (added to a previous JSON with ``--merge``); print the JSON."""
    ap = bench_parser(__doc__)
    ap.add_argument("--cases", default="table1,lab,servo_link,servo_identified")
    ap.add_argument("--merge", default=None, help="a previous JSON whose cases this run adds to (or replaces)")
    ap.add_argument("--hinf-only", action="store_true",
                    help="run only the H-infinity comparison (hinf_comparison) into the --merge JSON")
    args = ap.parse_args(argv)
    doc = {"floor": FLOOR, "factor": FACTOR, "cases": {}}
    if args.merge:
        import json
        with open(args.merge) as fh:
            previous = json.load(fh)
        doc["cases"].update(previous["cases"])
        if args.hinf_only:
            doc = previous
    if not args.hinf_only:
        for name in args.cases.split(","):
            doc["cases"][name] = case(name)
        doc["timing"] = timing()
    doc["hinf"] = hinf_comparison()
    emit(doc, args.out)


if __name__ == "__main__":
    main()
