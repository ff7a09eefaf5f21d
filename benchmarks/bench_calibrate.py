"""The issue's full-size calibration (issue 25, Speed), against central differences in the same run.

Run: ``.venv/bin/python benchmarks/bench_calibrate.py [--duration 10] [--backend auto] [--skip-alternative]
[--skip-servo] [--skip-link] [--out F.json]``. Prints one JSON object (and writes it to ``--out``).

Issue 38's case (``link``): the 3 m steel link with a 1 kg gripper of
``tests/test_calibrate_defaults.py`` (ideal torque drive; a chirp and a PRBS of 10 s at 1 kHz
by FOAM with 8 modes, encoder angle and tip deflection with 1 % noise), E, J_h and m_t
fitted with every default (plant modes from the records, the frequency-response start) from
starts 1.5x and 1/1.5x off in every field: wall time (target: under 60 s on two cores),
status, errors (targets E 0.5 %, J_h 2 %, m_t 5 %), the plant's modes and the start that won.

Two records of ``--duration`` s at 1 kHz (a chirp and a PRBS with a free-decay tail, voltages
from ``hubbeam excite``'s generator within 2 cm of tip deflection and 1 rad of hub travel) are
made by FOAM with the servo link's hardware from the "true" rig of the issue (E -7 %, J_h
+10 %, m_t +30 % of a 20 g payload, damping 0.02 against 0.005, Coulomb friction 10 mN m
against 0), with encoder quantisation and 1 mN m strain-gauge noise. Five fields are fitted
from the guess: wall time (the issue's target: under 2 minutes on two cores), evaluations,
errors against the truth, and the fit on a third (validation) record, beside the true rig's own
fit on it (the ceiling the sensors' noise and quantisation set). The named
alternative: the same fit with central differences (twice the simulations per Jacobian).
The records are made by a 2-mode plant, and the fit simulates 2 modes (``plant_modes=2``).
"""

from __future__ import annotations

import os
import platform
import sys
import time

import numpy as np
from benchjson import bench_parser, emit

from hubbeam_ctrl.calibrate import FitSettings, ModelSettings, excitation, fit_rig, synthetic_record, validate_record
from hubbeam_ctrl.plant.rig import load_rig

NAMES = ("E", "J_h", "m_t", "damping", "friction")


def rigs():
    base = load_rig("servo_link")
    guess = base.replace(beam=base.beam.replace(m_t=0.02), damping=base.damping.replace(ratios=(0.005,)),
                         friction=base.friction.replace(coulomb=0.0), sensors=base.sensors.replace(strain_noise=1e-3))
    b = guess.beam
    truth = guess.replace(beam=b.replace(E=0.93 * b.E, J_h=1.10 * b.J_h, m_t=1.30 * b.m_t),
                          damping=guess.damping.replace(ratios=(0.02,)), friction=guess.friction.replace(coulomb=10e-3))
    return guess, truth


def main(argv=None) -> int:
    ap = bench_parser(__doc__)
    ap.add_argument("--duration", type=float, default=10.0)
    ap.add_argument("--backend", default="auto")
    ap.add_argument("--skip-alternative", action="store_true")
    ap.add_argument("--skip-servo", action="store_true", help="leave out the servo link's five-field case")
    ap.add_argument("--skip-link", action="store_true", help="leave out issue 38's steel link")
    args = ap.parse_args(argv)
    os.environ["HUBBEAM_BACKEND"] = args.backend
    out = {"benchmark": "bench_calibrate", "date": time.strftime("%Y-%m-%d"), "python": sys.version.split()[0],
           "machine": platform.machine(), "cpus": os.cpu_count(), "backend": args.backend}
    if not args.skip_servo:
        out["servo_link"] = servo(args)
    if not args.skip_link:
        out["steel_link_defaults"] = steel_link_defaults()
    emit(out, args.out)
    return 0


def steel_link_defaults():
    """Issue 38: E, J_h, m_t with every default from starts 1.5x and 1/1.5x off."""
    from tests.test_calibrate_defaults import link_records, scaled, steel_link, truth_values
    truth = steel_link()
    records = link_records(truth)
    tv = truth_values(truth)
    out = {"records": [{"source": r.source, "samples": len(r.t), "duration_s": r.duration} for r in records],
           "fields": ["E", "J_h", "m_t"], "target_wall_s": 60.0,
           "target_error_percent": {"E": 0.5, "J_h": 2.0, "m_t": 5.0}, "starts": {}}
    for label, factor in (("x1.5", 1.5), ("x1/1.5", 1 / 1.5)):
        t0 = time.perf_counter()
        res = fit_rig(scaled(truth, [factor] * 3), records, "E,J_h,m_t", progress=False)
        wall = time.perf_counter() - t0
        out["starts"][label] = {
            "wall_s": wall, "status": res.status, "converged": res.converged, "evaluations": res.evaluations,
            "error_percent": dict(zip(("E", "J_h", "m_t"), np.round(100 * (res.estimate / tv - 1), 4).tolist())),
            "plant_modes": res.model.n_transverse, "identifiable_modes": list(res.design.identifiable),
            "band_hz": list(res.design.band_hz), "start_won": res.starts["won"],
            "fit_won": res.starts.get("fit_won"),
            "frequency_start_error_percent": dict(zip(("E", "J_h", "m_t"), np.round(
                100 * (np.array(res.starts["frequency response"]["values"]) / tv - 1), 3).tolist())),
            "fit_percent": res.fit, "fit_ceiling_percent": res.ceiling}
    return out


def servo(args):
    """The issue-25 case: five fields of the servo link, forward against central differences."""
    guess, truth = rigs()
    tv = np.array([truth.beam.E, truth.beam.J_h, truth.beam.m_t, 0.02, 10e-3])
    limits = {"max_tip_deflection": 0.02, "max_hub_travel": 1.0}
    inputs = [excitation(guess, kind, args.duration, **limits) for kind in ("chirp", "prbs", "multisine")]
    records = [synthetic_record(truth, r.t, r.input, seed=k, source=r.source) for k, r in enumerate(inputs)]
    out = {"records": [{"source": r.source, "samples": len(r.t), "duration_s": r.duration} for r in records[:2]],
           "validation_record": records[2].source, "target_wall_s": 120.0, "variants": {}}
    # the ceiling set by the sensors' noise and quantisation: the true rig's own fit on the validation record
    two = ModelSettings(n_transverse=2)
    out["validation_fit_percent_of_the_true_rig"] = validate_record(truth, records[2], settings=two)[0]
    variants = {"forward_differences": FitSettings(plant_modes=2)}
    if not args.skip_alternative:
        variants["central_differences"] = FitSettings(central=True, plant_modes=2)
    for name, settings in variants.items():
        t0 = time.perf_counter()
        res = fit_rig(guess, records[:2], ",".join(NAMES), settings=settings, progress=False)
        wall = time.perf_counter() - t0
        fits, _ = validate_record(res.rig, records[2], settings=res.model)
        out["variants"][name] = {
            "wall_s": wall, "converged": res.converged, "evaluations": res.evaluations,
            "error_percent": dict(zip(NAMES, np.round(100 * (res.estimate / tv - 1), 4).tolist())),
            "ci95_half_width_percent": dict(zip(NAMES, np.round(100 * 1.96 * res.std / tv, 4).tolist())),
            "fit_percent": res.fit, "fit_ceiling_percent": res.ceiling, "status": res.status,
            "validation_fit_percent": fits, "warnings": res.warnings}
    return out


if __name__ == "__main__":
    raise SystemExit(main())
