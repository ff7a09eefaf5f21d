"""The map of the plant models (issue 23): FOAM and CFOAM against the exact beam over tip deflection and spin.

Prints a Markdown table and writes benchmarks/results/bench_physics_map.json. Run:
``.venv/bin/python benchmarks/bench_physics_map.py [--modes 5] [--quick]``.

Two axes, Table 1's beam with ``--modes`` transverse and 5 axial modes, no damping:

* **Tip deflection**: the Eq. 44 torque pulse (``t_f`` = 10 s, free hub) with ``tau_m`` scaled so
  that the peak tip deflection runs from about 0.05 L to 0.6 L (200 N m gives 0.16 L); 20 s
  simulated; the residual is ``max |v_tip|`` over 10-20 s.
* **Spin**: the Eq. 43 spin-up (prescribed hub, ``t_f`` = 30 s, no tip mass) to ``w_f`` = 1..40
  rad/s (40 rad/s: about half of Params.max_spin); 40 s simulated; the residual is ``max |v_tip|`` over 30-40 s.

FOAM and CFOAM run on IDAS (:func:`hubbeam_ctrl.simulate`, error control); the exact beam
(:func:`hubbeam_ctrl.sim.simulate_exact`, Exudyn ANCF, the element and step rules) is the
reference. For each case and model: the relative error of the peak and of the residual (not
compared, ``-``, when the exact residual is below 1 % of its peak), and the band it falls in:
within 1 % (both), within 5 % (both), or beyond.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import time

import numpy as np

from hubbeam_ctrl import Params, SpinUp, TorquePulse, simulate
from hubbeam_ctrl.core.fileio import atomic_write_text
from hubbeam_ctrl.sim import simulate_exact

#: tau_m of Eq. 44 [N m]: peak deflections of 0.05 L to about 0.6 L (measured on the exact beam).
TORQUES = (62.0, 124.0, 200.0, 248.0, 373.0, 497.0, 621.0, 745.0, 870.0, 990.0)
#: Residuals below this fraction of the exact beam's peak are not compared [-].
RESIDUAL_FLOOR = 0.01
#: Final spin rates of the spin-ups [rad/s].
SPINS = (1.0, 3.0, 5.0, 10.0, 20.0, 40.0)


def _band(errors) -> str:
    worst = max(abs(e) for e in errors)
    if not np.isfinite(worst):
        return "failed"
    return "1 %" if worst <= 0.01 else "5 %" if worst <= 0.05 else "> 5 %"


def _case(maneuver, t_end: float, window: float, params: Params, dt: float) -> dict:
    """Peak and residual on the exact beam, FOAM and CFOAM for one maneuver."""
    row = {}
    t0 = time.perf_counter()
    ex = simulate_exact(maneuver, t_end, params=params, dt=dt, max_wall_s=3600.0)
    row["ancf"] = {"peak_m": float(np.max(np.abs(ex.v_tip))),
                   "residual_m": float(np.max(np.abs(ex.v_tip[ex.t >= window]))),
                   "wall_s": time.perf_counter() - t0, "message": ex.message,
                   "substeps": ex.settings["substeps"], "elements": ex.settings["plant_elements"]}
    L = params.L
    row["ancf"]["peak_over_L"] = row["ancf"]["peak_m"] / L
    for model in ("foam", "cfoam"):
        t0 = time.perf_counter()
        try:
            r = simulate(model, maneuver, t_end, params=params, dt=dt)
            peak = float(np.max(np.abs(r.v_tip)))
            resid = float(np.max(np.abs(r.v_tip[r.t >= window]))) if r.t[-1] >= window else float("nan")
            msg, outside = r.message, r.stats.get("outside_range_time_s")
        except Exception as exc:          # a model that fails at large deflection is a result of the map
            peak = resid = float("nan")
            msg, outside = f"{type(exc).__name__}: {str(exc)[:200]}", None
        e_peak = peak / row["ancf"]["peak_m"] - 1
        # a residual below 1 % of the peak is not compared (its relative error measures round-off and
        # the integrators' damping of a few 1e-5 m, not the model)
        counted = row["ancf"]["residual_m"] >= RESIDUAL_FLOOR * row["ancf"]["peak_m"]
        e_res = resid / row["ancf"]["residual_m"] - 1 if counted else None
        row[model] = {"peak_m": peak, "residual_m": resid, "peak_rel_err": e_peak, "residual_rel_err": e_res,
                      "band": _band([e_peak] + ([e_res] if counted else [])), "peak_band": _band([e_peak]),
                      "outside_range_time_s": outside, "message": msg, "wall_s": time.perf_counter() - t0}
    return row


def _pct(x) -> str:
    return "-" if x is None else "n/a" if not np.isfinite(x) else f"{100 * x:+.1f} %"


def table(out: dict) -> str:
    """The Markdown table of the map."""
    lines = ["| case | exact beam: peak abs(v_tip)/L, residual [m] | FOAM peak, residual | FOAM within "
             "| CFOAM peak, residual | CFOAM within |", "|---|---|---|---|---|---|"]
    for case in out["cases"]:
        a, f, c = case["ancf"], case["foam"], case["cfoam"]
        lines.append(f"| {case['case']} | {a['peak_over_L']:.3f} L, {a['residual_m']:.3g} | "
                     f"{_pct(f['peak_rel_err'])}, {_pct(f['residual_rel_err'])} | {f['band']} | "
                     f"{_pct(c['peak_rel_err'])}, {_pct(c['residual_rel_err'])} | {c['band']} |")
    return "\n".join(lines)


def _add(out: dict, row: dict) -> None:
    """Keep a case's row and print its line."""
    out["cases"].append(row)
    print(f"{row['case']}: {row['ancf']['peak_over_L']:.3f} L, FOAM {_pct(row['foam']['peak_rel_err'])}, "
          f"CFOAM {_pct(row['cfoam']['peak_rel_err'])}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--modes", type=int, default=5, help="transverse modes of every model (default 5)")
    ap.add_argument("--quick", action="store_true", help="two torques and two spins, short runs (a smoke test)")
    args = ap.parse_args()
    torques = TORQUES[:2] if args.quick else TORQUES
    spins = SPINS[:2] if args.quick else SPINS
    t_torque, t_spin = (12.0, 32.0) if args.quick else (20.0, 40.0)
    start = time.perf_counter()
    out = {"modes": args.modes, "torque_t_end_s": t_torque, "spin_t_end_s": t_spin, "cases": []}
    base = Params(n_transverse=args.modes, tau_max=1000.0)
    for tau in torques:
        row = _case(TorquePulse(tau_m=tau, t_f=10.0), t_torque, 10.0, base, 0.01)
        row.update(case=f"Eq. 44, {tau:g} N m", axis="deflection", tau_m=tau)
        _add(out, row)
    spin_p = base.replace(m_t=0.0)
    for w in spins:
        row = _case(SpinUp(w_f=w, t_f=30.0), t_spin, 30.0, spin_p, 0.05)
        row.update(case=f"spin-up to {w:g} rad/s", axis="spin", w_f=w)
        _add(out, row)
    out["wall_s"] = time.perf_counter() - start
    out["table_markdown"] = table(out)
    text = json.dumps(out, indent=2, default=float)
    print(out["table_markdown"])
    name = "bench_physics_map_quick.json" if args.quick else "bench_physics_map.json"
    atomic_write_text(pathlib.Path(__file__).parent / "results" / name, text + "\n")


if __name__ == "__main__":
    main()
