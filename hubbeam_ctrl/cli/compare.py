"""``hubbeam compare``: the controllers in closed loop on FOAM or CFOAM (see
:mod:`hubbeam_ctrl.study.compare`)."""

from __future__ import annotations

import argparse
import json
import math
import sys
import time

from controllers import CONTROLLERS, QP_SOLVERS, SHAPERS, controller_names
from hubbeam_ctrl.cli.main import RegistryChoices, finite_float, positive_float, positive_int
from hubbeam_ctrl.core.errors import ParameterError

__all__ = ["add_parser", "run", "stdout_to_stderr"]


class stdout_to_stderr:
    """Send file descriptor 1 to stderr for a while (native libraries such as qpOASES
    print banners with printf; ``--json`` output must stay clean)."""

    def __enter__(self):
        import os
        sys.stdout.flush()
        self._saved = os.dup(1)
        os.dup2(2, 1)
        return self

    def __exit__(self, *exc):
        import os
        sys.stdout.flush()
        os.dup2(self._saved, 1)
        os.close(self._saved)
        return False


def add_parser(subparsers, common) -> argparse.ArgumentParser:
    """Add the ``compare`` subcommand.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
    common : argparse.ArgumentParser
        Parent parser with ``--tip-mass``, ``--tip-position``, ``--n-modes``, ``--params``.
    """
    labels = ", ".join(spec.label for spec in CONTROLLERS.values())
    p = subparsers.add_parser(
        "compare", parents=[common], help="compare controllers in closed loop",
        description=(f"Design the registered controllers ({labels}) on SFOAM and compare them in "
                     "closed loop (zero-order hold at --dt) on the nonlinear FOAM or CFOAM evaluation "
                     "plant, which has every bending mode below the sampling frequency and at least "
                     "three more than the design model. --params and the common options set both the "
                     "design and the plant; --plant-params and --plant-tip-mass make the plant differ. "
                     "Writes metrics.csv, metrics.json, tip_deflection.png, hub_angle.png, "
                     "torque.png and report.md to --out."))
    # explicit metavars: argparse would otherwise read the choices (importing the study layer)
    # when the parser is built, not only when --help is shown or a value is checked
    p.add_argument("--plant", metavar="PLANT", choices=RegistryChoices("hubbeam_ctrl.study.scenarios", "PLANTS"),
                   default="foam", help="nonlinear plant: %(choices)s (default %(default)s: closer to an "
                                        "exact beam than cfoam)")
    p.add_argument("--plant-params", metavar="FILE.toml",
                   help="physical parameters of the plant when they differ from the design's")
    p.add_argument("--plant-tip-mass", metavar="KG", type=float, help="tip mass of the plant [kg], >= 0")
    p.add_argument("--design-modes", metavar="N", type=int,
                   help="transverse modes of the design model, 1..20 (default: --n-modes or 5)")
    p.add_argument("--plant-modes", metavar="N", type=int,
                   help="transverse modes of the plant, design modes..20 (default: every mode "
                        "below the sampling frequency and the first above it, >= design + 3)")
    p.add_argument("--range-limit", metavar="FRACTION", type=positive_float("range-limit"), default=0.3,
                   help="flag runs whose |v_tip| passes FRACTION * L (the models' validated "
                        "range; default 0.3); only L stops a run")
    p.add_argument("--scenario", metavar="NAME", choices=RegistryChoices("hubbeam_ctrl.study.scenarios",
                                                                         "SCENARIOS"),
                   default="slew", help="registered scenario: %(choices)s (default %(default)s; see "
                                        "hubbeam_ctrl.study.scenarios)")
    default = ",".join(controller_names(default=True))
    p.add_argument("--controllers", metavar="LIST", default=default,
                   help="comma-separated subset of the registered controllers "
                        + ", ".join(f"{n} ({s.label})" for n, s in CONTROLLERS.items())
                        + f" (default: {default})")
    p.add_argument("--shaping", choices=list(SHAPERS), default=None,
                   help="filter the reference of the controllers that track one ("
                        + ",".join(n for n, s in CONTROLLERS.items() if s.tracks_reference)
                        + ") through this input shaper, designed on the first mode of the design model")
    p.add_argument("--tau-max", metavar="NM", type=positive_float("tau-max"),
                   help="torque budget [N m], at most the motor's tau_max of the parameters "
                        "(default: that limit, 200 N m in Table 1)")
    p.add_argument("--slew-angle", metavar="RAD", type=finite_float("slew-angle"),
                   help="slew angle [rad], not 0 (default: the rigid angle of the Eq. 44 torque with "
                        "amplitude --tau-max in --tf); the open-loop baseline is Eq. 44 scaled to this "
                        "angle and --tf")
    p.add_argument("--tf", metavar="S", type=positive_float("tf"), default=10.0,
                   help="maneuver time [s] (default 10); refused, naming the shortest feasible one, "
                        "if the task needs more torque than --tau-max")
    p.add_argument("--t-end", metavar="S", type=positive_float("t-end"), default=30.0,
                   help="simulated time [s], > tf + 5 (default 30)")
    p.add_argument("--wf", metavar="RAD_S", type=finite_float("wf"), default=3.0,
                   help="spin-up final rate [rad/s] (default 3, above TLAM's critical speed)")
    p.add_argument("--dt", metavar="S", type=positive_float("dt"), default=0.01,
                   help="controller sample time [s] (default 0.01)")
    p.add_argument("--horizon", metavar="N", type=positive_int("horizon"), default=50,
                   help="MPC horizon [samples] (default 50)")
    p.add_argument("--solver", choices=list(QP_SOLVERS), default="daqp",
                   help="MPC QP solver: %(choices)s (default %(default)s)")
    p.add_argument("--schedule", metavar="N", type=positive_int("schedule"), default=1,
                   help="design the controllers with a scheduled version ("
                        + ",".join(n for n, s in CONTROLLERS.items() if s.scheduled)
                        + ") at N spin rates from 0 to the top reference rate and interpolate them on "
                          "the measured rate (default 1: one design point)")
    p.add_argument("--out", metavar="DIR", required=True, help="output folder (created if missing)")
    p.add_argument("--payload-range", metavar="MIN,MAX",
                   help="tip payloads [kg] that LQR, LQG and MPC are designed for (must hold the tip mass "
                        "of the parameters); runs the plant at MIN, the nominal tip mass and MAX and "
                        "writes payload.json and payload_report.md")
    p.add_argument("--json", action="store_true", help="print the metrics as JSON instead of a table")
    p.set_defaults(func=run)
    return p


def parse_payload_range(text: str, nominal: float) -> tuple:
    """``"MIN,MAX"`` -> ``(m_min, m_max)`` [kg], validated (one-line error naming payload-range)."""
    from controllers.robust import check_payload_range
    parts = [t.strip() for t in str(text).split(",")]
    try:
        values = tuple(float(t) for t in parts)
    except ValueError:
        values = None
    if values is None or len(values) != 2 or not all(math.isfinite(v) for v in values):
        raise ParameterError(f"payload-range must be two finite numbers MIN,MAX [kg], got {text!r}")
    return check_payload_range(values, nominal, "payload-range")


def _run_payload(args, params, out) -> int:
    from hubbeam_ctrl.study.payload import payload_comparison, payload_table, write_payload_outputs
    payload_range = parse_payload_range(args.payload_range, params.m_t)
    with stdout_to_stderr():
        pc = payload_comparison(args.plant, args.scenario, args.controllers, payload_range=payload_range,
                                params=params, tau_max=args.tau_max, t_f=args.tf, t_end=args.t_end, dt=args.dt,
                                w_f=args.wf, slew_angle=args.slew_angle, horizon=args.horizon,
                                solver=args.solver)
        write_payload_outputs(pc, out)
    if args.json:
        print(json.dumps(json.loads((out / "payload.json").read_text())))
    else:
        print(payload_table(pc))
        print(f"wrote {out}/payload.json, payload_report.md")
    return 0


def run(args) -> int:
    """Run ``hubbeam compare``; returns the exit status (0)."""
    from pathlib import Path

    from hubbeam_ctrl.cli.main import params_from_args
    from hubbeam_ctrl.plant.params import MAX_MODES, load_params
    from hubbeam_ctrl.sim.closedloop import ClosedLoopSettings
    from hubbeam_ctrl.study.compare import compare
    from hubbeam_ctrl.study.report import _json_metrics, format_table, write_outputs
    params = params_from_args(args)
    if args.tau_max is not None and args.tau_max > params.tau_max:
        raise ParameterError(f"tau-max must be in (0, {params.tau_max:g}] N m (the motor's tau_max of "
                             f"the parameters), got {args.tau_max:g}")
    if args.slew_angle is not None and args.slew_angle == 0:
        raise ParameterError("slew-angle must be a finite number != 0 [rad], got 0")
    if args.slew_angle is not None and args.scenario != "slew":
        raise ParameterError("slew-angle applies to --scenario slew only")
    plant_params = load_params(args.plant_params) if args.plant_params else None
    if args.plant_tip_mass is not None:
        if not args.plant_tip_mass >= 0:
            raise ParameterError(f"plant-tip-mass must be a number >= 0 [kg], got {args.plant_tip_mass}")
        plant_params = (plant_params or params).replace(m_t=args.plant_tip_mass)
    design_modes = args.design_modes if args.design_modes is not None else params.n_transverse
    if not 1 <= design_modes <= MAX_MODES:
        raise ParameterError(f"design-modes must be an integer in 1..{MAX_MODES}, got {design_modes}")
    if args.plant_modes is not None and not design_modes <= args.plant_modes <= MAX_MODES:
        raise ParameterError(f"plant-modes must be an integer in {design_modes}..{MAX_MODES} (at least "
                             f"the design model's {design_modes}), got {args.plant_modes}")
    out = Path(args.out)
    if not out.parent.is_dir():
        raise ParameterError(f"out: folder {out.parent} does not exist")
    if out.exists() and not out.is_dir():
        raise ParameterError(f"out: {out} exists and is not a folder")
    if args.payload_range is not None:
        return _run_payload(args, params, out)
    t0 = time.perf_counter()
    with stdout_to_stderr():
        comparison = compare(args.plant, args.scenario, args.controllers, params=params,
                             plant_params=plant_params, design_modes=design_modes,
                             plant_modes=args.plant_modes, tau_max=args.tau_max, t_f=args.tf,
                             t_end=args.t_end, dt=args.dt, w_f=args.wf, slew_angle=args.slew_angle,
                             horizon=args.horizon,
                             solver=args.solver, shaping=args.shaping, schedule=args.schedule,
                             sim_settings=ClosedLoopSettings(range_limit=args.range_limit),
                             progress=not args.json)
        write_outputs(comparison, out)
    wall = time.perf_counter() - t0
    if args.json:
        print(json.dumps(_json_metrics(comparison.metrics)))
    else:
        sc, ev = comparison.scenario, comparison.plant
        print(f"{sc.plant.upper()}, {sc.name}: {sc.description}")
        print(f"plant: {ev.model.upper()} with {ev.modes} transverse modes ({ev.reason})")
        print(format_table(comparison.metrics))
        print(f"wrote {out}/metrics.csv, metrics.json, tip_deflection.png, hub_angle.png, "
              f"torque.png, report.md ({wall:.1f} s)")
    for name, m in comparison.metrics.items():
        if not m["completed"] or m.get("outside_validated_range"):
            print(f"warning: {name}: {m['message']}", file=sys.stderr)
    return 0
