"""Multi-stage (scenario-tree) MPC against the robust MPC of ``compare --payload-range`` (issue 39 item 3).

Both controllers are designed for the same payload range in the same run
(:func:`hubbeam_ctrl.study.payload.payload_comparison`, controllers ``openloop,mpc,msmpc``): the
MPC by :func:`controllers.robust.design_for_range` (a search over design payloads and weightings,
measured on the nonlinear plant), the multi-stage MPC with one scenario per payload of the grid
(the range's ends and the nominal payload, :func:`controllers.msmpc.scenario_range_design`).
Each is run on the FOAM evaluation plant at every payload of ``masses`` (and at the worst payload
its certificate finds, if that is not one of them) and judged against the open loop on the same
plant; the certificate (:func:`hubbeam_ctrl.study.worst_case.certify_set`, the unconstrained law
of each MPC with the linear plant of all the evaluation plant's modes) is taken over the payload
range undamped and with a 0.05 % damping floor in every mode. Step time: the controller's wall
time per sample in the nonlinear runs (mean and 99th percentile).

Cases: ``table1`` (the paper's beam, its default slew, 0-0.5 kg), ``lab`` (the 1 m aluminium
lab arm of the robust benchmark, a 90 degree slew in 1.5 T* of the nominal 0.05 kg, 0-0.2 kg) and
``lab_heavy`` (the same in 1.5 T* of the heaviest payload, 0.2 kg: 1.79 s instead of 1.26 s). On the
lab cases ``known_plant`` runs LQR and MPC designed and planned on each payload's own beam: at
0.2 kg the 1.26 s task is below the Eq. 44 slew's shortest duration (1.483 s) and 5.5 % above the
time-optimal one (1.195 s), so no design reaches it there. On ``table1`` the other
robust MPC, the certified one of ``hubbeam certify mpc --design robust`` over the range with the
0.05 % floor, is designed and run on the same plants too (``set_mpc``).

Run: ``.venv/bin/python benchmarks/bench_msmpc.py [--case table1|lab|all] [--out F.json]``
(Table 1 about 3 min on 2 cores, most of it the two MPC design searches).
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from benchjson import emit  # noqa: E402

from hubbeam_ctrl import Params  # noqa: E402
from hubbeam_ctrl.plant.rig import Rig  # noqa: E402
from hubbeam_ctrl.plant.uncertainty import Uncertainty  # noqa: E402
from hubbeam_ctrl.study import CompareSettings, PayloadChoice, Slew, payload_comparison, payload_table  # noqa: E402
from hubbeam_ctrl.study.worst_case import RADIUS_MARGIN, certify_set  # noqa: E402

LAB = Params(L=1, rho=2700, A=9e-5, E=69e9, I=6.75e-11, J_h=0.02, r=0.05, m_t=0.05, tau_max=1.5)
FLOOR = 0.0005
NAMES = ("mpc", "msmpc")
RESIDUAL_TARGET_PCT = 2.0


def setup(name: str):
    """``(params, task, payload range, masses)`` of a case."""
    if name == "table1":
        return Params(), "slew", (0.0, 0.5), (0.0, 0.1, 0.25, 0.5)
    from hubbeam_ctrl.limit import time_optimal_slew
    # lab: 1.5 x the time-optimal slew of the nominal 0.05 kg; lab_heavy: of the heaviest payload
    at = LAB if name == "lab" else LAB.replace(m_t=0.2)
    t_opt = time_optimal_slew(Rig(beam=at), math.pi / 2).duration_s
    return LAB, Slew(math.pi / 2, 1.5 * t_opt), (0.0, 0.2), (0.0, 0.05, 0.1, 0.2)


def known_plant(params: Params, task, masses) -> dict:
    """The plant known: LQR and MPC designed and the slew planned on each payload's own beam (``compare``
    at that payload); a payload at which the task cannot be planned says why (the yardstick of
    what a design that does not know the payload can reach)."""
    from hubbeam_ctrl.core.errors import ParameterError
    from hubbeam_ctrl.limit import time_optimal_slew
    from hubbeam_ctrl.study import compare
    out = {}
    for m in masses:
        p = params.replace(m_t=m)
        row = {"time_optimal_s": time_optimal_slew(Rig(beam=p), task.angle).duration_s}
        try:
            comp = compare(p, task, ("openloop", "lqr", "mpc"))
        except ParameterError as exc:
            row["infeasible"] = str(exc)
        else:
            for n in ("lqr", "mpc"):
                mm = comp.metrics[n]
                row[n] = {k: mm.get(k) for k in ("verdict", "settling_time_s", "residual_pct_of_openloop",
                                                 "peak_torque_nm", "final_angle_error_rad")}
        out[f"{m:g}"] = row
    return out


def _row(comp, name: str) -> dict:
    mm, res = comp.metrics[name], comp.results[name]
    st = np.asarray(res.step_time_s, dtype=float)
    st = st[np.isfinite(st)]
    return {"verdict": mm["verdict"], "settling_time_s": mm.get("settling_time_s"),
            "residual_pct_of_openloop": mm.get("residual_pct_of_openloop"),
            "peak_torque_nm": mm["peak_torque_nm"], "loop_spectral_radius": mm.get("loop_spectral_radius"),
            "step_time_mean_s": float(st.mean()) if st.size else None,
            "step_time_p99_s": float(np.percentile(st, 99)) if st.size else None,
            "qp_fallbacks": (getattr(res, "controller_stats", None) or {}).get("qp_fallbacks")}


def case(name: str, names: tuple = NAMES, masses: tuple | None = None) -> dict:
    """Design ``names`` for the case's payload range, run them at ``masses`` (default the case's) and
    at the worst payload each one's certificate finds, and certify them undamped and at the floor."""
    params, task, rng, default_masses = setup(name)
    masses = default_masses if masses is None else masses
    start = time.perf_counter()
    pc = payload_comparison(params, task, ("openloop",) + tuple(names),
                            CompareSettings(payload=PayloadChoice(payload_range=rng)), masses=masses)
    print(payload_table(pc), file=sys.stderr)
    wall_compare = time.perf_counter() - start
    first = pc.comparisons[masses[0]]
    bare = Rig(beam=params)
    out = {"payload_range_kg": list(rng), "masses_kg": list(masses), "task": first.scenario.description,
           "plant_modes": first.plant.modes, "designs": {}, "controllers": {}}
    for n in names:
        d = pc.designs[n]
        out["designs"][n] = {"choice": d.choice, "design_mass_kg": d.design_mass, "linear_score": d.score}
    for n in names:
        ctrl = first.controllers[n]
        cert = {}
        for label, z in (("undamped", 0.0), ("floor_0.05pct", FLOOR)):
            u = Uncertainty.from_table({"m_t": rng, "damping": (z, z)})
            wc = certify_set(ctrl, bare, u, plant_modes=first.plant.modes, name=n, margins=False)
            cert[label] = {"radius": wc.worst.radius, "worst_payload_kg": wc.worst.values["m_t"],
                           "certified": wc.certified, "worst_source": wc.worst_source, "wall_s": wc.wall_s}
        rows = {f"{m:g}": _row(pc.comparisons[m], n) for m in masses}
        worst_m = cert["undamped"]["worst_payload_kg"]
        if not any(abs(worst_m - m) < 1e-12 for m in masses):     # the worst plant found, run too
            extra = payload_comparison(params, task, ("openloop", n),
                                       CompareSettings(payload=PayloadChoice(payload_range=rng)), masses=(worst_m,))
            rows[f"{worst_m:g} (worst found)"] = _row(extra.comparisons[worst_m], n)
        out["controllers"][n] = {
            "certificate": cert, "runs": rows,
            "all_settled": all(r["verdict"] == "settled" for r in rows.values()),
            "worst_residual_pct_of_openloop": max(r["residual_pct_of_openloop"] for r in rows.values()),
            "peak_torque_nm": max(r["peak_torque_nm"] for r in rows.values()),
            "meets_targets": bool(all(r["verdict"] == "settled" for r in rows.values())
                                  and max(r["residual_pct_of_openloop"] for r in rows.values()) <= RESIDUAL_TARGET_PCT
                                  and max(r["peak_torque_nm"] for r in rows.values()) <= params.tau_max + 1e-9
                                  and cert["floor_0.05pct"]["radius"] <= 1.0 - RADIUS_MARGIN)}
    if name == "table1" and "mpc" in names:
        out["set_mpc"] = set_mpc(params, rng, masses)
    elif name != "table1":
        out["known_plant"] = known_plant(params, task, masses)
    out["wall_compare_s"] = wall_compare
    out["wall_s"] = time.perf_counter() - start
    return out


def set_mpc(params: Params, rng: tuple, masses: tuple) -> dict:
    """The other robust MPC: ``hubbeam certify mpc --design robust`` over the payload range with the
    0.05 % floor (:func:`hubbeam_ctrl.study.robust_design.design_for_set`, ranked by the certificate,
    then by nonlinear runs at the set's corners and centre), run on the same undamped plants."""
    from hubbeam_ctrl.study import compare
    from hubbeam_ctrl.study.robust_check import residual_score, run_at
    from hubbeam_ctrl.study.robust_design import design_for_set
    t0 = time.perf_counter()
    u = Uncertainty.from_table({"m_t": rng, "damping": (FLOOR, FLOOR)})
    bare = Rig(beam=params)
    cmp = compare(bare.replace(uncertainty=u), "slew", ("openloop", "mpc"))
    sd = design_for_set(cmp, "mpc", bare, u, score=residual_score(cmp, bare, u))
    undamped = certify_set(sd.controller, bare, Uncertainty.from_table({"m_t": rng, "damping": (0.0, 0.0)}),
                           plant_modes=cmp.plant.modes, margins=False)
    payload = Uncertainty.from_table({"m_t": rng})
    runs = {f"{m:g}": run_at(cmp, sd.controller, bare, {"m_t": m}, payload) for m in masses}
    keep = ("verdict", "settling_time_s", "residual_pct_of_openloop", "peak_torque_nm", "loop_spectral_radius")
    return {"design": sd.label(), "candidates": len(sd.tried),
            "certificate": {"undamped": {"radius": undamped.worst.radius,
                                         "worst_payload_kg": undamped.worst.values["m_t"]},
                            "floor_0.05pct": {"radius": sd.certificate.worst.radius,
                                              "worst_payload_kg": sd.certificate.worst.values["m_t"]}},
            "runs": {m: {k: r.get(k) for k in keep} for m, r in runs.items()},
            "worst_residual_pct_of_openloop": max(r["residual_pct_of_openloop"] for r in runs.values()),
            "all_settled": all(r["verdict"] == "settled" for r in runs.values()),
            "wall_s": time.perf_counter() - t0}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", choices=("table1", "lab", "lab_heavy", "all"), default="table1")
    ap.add_argument("--out", help="also write the JSON here")
    args = ap.parse_args(argv)
    names = ("table1", "lab", "lab_heavy") if args.case == "all" else (args.case,)
    doc = {"benchmark": "msmpc", "machine": {"python": platform.python_version(), "cpus": os.cpu_count()},
           "floor": FLOOR, "cases": {n: case(n) for n in names}}
    emit(doc, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
