"""Issue 38: the truncation bias of item 5's fit (J_h, viscous friction) against the plant's modes.

Run: ``.venv/bin/python benchmarks/bench_calibrate_truncation.py [--record-modes 10]
[--fit-modes 5,6,8] [--out F.json]``. Prints one JSON object (and writes it to ``--out``).

The truth has infinitely many bending modes, so item 5's records (``bench_calibrate.py``'s
``servo_from_records``: the servo link with its friction, damping and drive unknown, a chirp and
a PRBS of 10 s, one noise seed) are made by FOAM with ``--record-modes`` modes, more than any
fit. Three measurements:

``static``: the root moment per hub acceleration of the linear plant (free hub, at 1 % of the
first bending frequency: quasi-static) with n modes against 20 (``MAX_MODES``) [%]. The root
moment is the modes' displacements times their root curvature, so each mode left out removes
its quasi-static share; it does not depend on E or J_h.

``sensor_truncation``: the simulated ``root_moment`` of each record's input with n modes against
``--record-modes`` modes: the least-squares gain [%] and the rms difference [% of the record's].

``fits``: item 5's nine fields with ``plant_modes`` = each of ``--fit-modes`` (one fit at a
time): errors against the truth [%], k_t / R, wall and CPU time; ``--residual-moment``: records
and fits with the mode-acceleration correction of the omitted modes' root moment.
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np
from bench_calibrate import ITEM5, item5_rigs
from benchjson import bench_parser, emit

from hubbeam_ctrl.calibrate import (
    FitSettings,
    ModelSettings,
    excitation,
    fit_rig,
    resolve_fields,
    simulate_sensors,
    synthetic_record,
)


def static_root_moment(params, modes: int) -> float:
    """Root moment per hub acceleration of the linear plant with ``modes`` modes [N m s^2/rad]."""
    from hubbeam_ctrl.calibrate.model import _bending_hz
    from hubbeam_ctrl.plant.linearization import second_order_linearization
    from hubbeam_ctrl.plant.models import build_model
    from hubbeam_ctrl.plant.sensors import sensor_matrix
    q = params.replace(n_transverse=modes)
    model = build_model("foam", q, axial="quasi-static")
    lin = second_order_linearization(model, 0.0, "free")
    M, K, B = (np.asarray(m, dtype=float) for m in (lin.M, lin.K, lin.B))
    w = 2 * np.pi * 0.01 * float(np.min(_bending_hz(q, "foam")))
    x = np.linalg.solve(K - w ** 2 * M, B)
    C = sensor_matrix(model.params, model.n_transverse, model.n_axial)[2, :model.n_q]
    return float(C @ x / (-w ** 2 * x[0]))


def main(argv=None) -> int:
    ap = bench_parser(__doc__)
    ap.add_argument("--record-modes", type=int, default=10)
    ap.add_argument("--fit-modes", default="5,6,8", help="comma-separated plant_modes of the fits ('' : none)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--residual-moment", action="store_true",
                    help="records and fits with ModelSettings.residual_moment (the mode-acceleration correction)")
    args = ap.parse_args(argv)
    guess, truth = item5_rigs()
    out = {"benchmark": "bench_calibrate_truncation", "date": time.strftime("%Y-%m-%d"),
           "record_modes": args.record_modes, "seed": args.seed}
    ref = static_root_moment(truth.plant_params, 20)
    out["static_root_moment_percent_vs_20_modes"] = {
        n: round(100 * (static_root_moment(truth.plant_params, n) / ref - 1), 4) for n in range(2, 13)}
    out["sensor_truncation"] = {}
    for kind in ("chirp", "prbs"):
        ex = excitation(guess, kind, 10.0)
        y0 = simulate_sensors(truth, ex.t, ex.input, ("root_moment",),
                              ModelSettings(n_transverse=args.record_modes))["root_moment"]
        rows = {}
        for n in range(4, min(args.record_modes, 9)):
            y = simulate_sensors(truth, ex.t, ex.input, ("root_moment",), ModelSettings(n_transverse=n))["root_moment"]
            rows[n] = {"gain_percent": round(100 * (float(y @ y0 / (y0 @ y0)) - 1), 4),
                       "rms_percent": round(100 * float(np.linalg.norm(y - y0) / np.linalg.norm(y0)), 4)}
        out["sensor_truncation"][kind] = rows
    tv = {f.path: f.get(truth) for f in resolve_fields(",".join(ITEM5), truth)}
    rm = args.residual_moment
    out["residual_moment"] = rm
    records = [synthetic_record(truth, ex.t, ex.input, seed=2 * args.seed + k, source=ex.source,
                                settings=ModelSettings(n_transverse=args.record_modes, residual_moment=rm))
               for k, ex in enumerate(excitation(guess, kind, 10.0) for kind in ("chirp", "prbs"))]
    out["fits"] = []
    for m in [int(v) for v in args.fit_modes.split(",") if v.strip()]:
        t0, c0 = time.perf_counter(), time.process_time()
        fs = FitSettings(plant_modes=m, model=ModelSettings(residual_moment=rm))
        res = fit_rig(guess, records, ",".join(ITEM5), settings=fs, progress=False)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        err = {f.name: round(100 * (e / tv[f.path] - 1), 3) for f, e in zip(res.fields, res.estimate)}
        ratio = res.drive.values["motor.k_t / motor.R"]["value"]
        err["motor.k_t / motor.R"] = round(100 * (ratio / (truth.drive.k_t / truth.drive.R) - 1), 3)
        out["fits"].append({"fit_modes": m, "wall_s": round(wall, 1), "cpu_s": round(cpu, 1), "status": res.status,
                            "evaluations": res.evaluations, "error_percent": err, "fit_percent": res.fit})
        print(json.dumps(out["fits"][-1]), file=sys.stderr, flush=True)
    emit(out, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
