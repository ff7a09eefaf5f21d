"""``hubbeam compare``: the controllers in closed loop on FOAM or CFOAM (see :mod:`.compare`)."""

from __future__ import annotations

import argparse
import sys
import time

from controllers import CONTROLLERS, QP_SOLVERS, SHAPERS, controller_names
from hubbeam_ctrl.cli.args import (
    add_run_options,
    check_output_dir,
    integer,
    real,
    refuse_inapplicable,
    run_limits,
    stdout,
)
from hubbeam_ctrl.cli.main import RegistryChoices, positive_int
from hubbeam_ctrl.core.fileio import strict_json
from hubbeam_ctrl.core.native import stdout_to_stderr  # noqa: F401  (kept importable from here)

__all__ = ["add_parser", "run", "stdout_to_stderr"]


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
                     "closed loop (zero-order hold at --dt) on the nonlinear FOAM or CFOAM plant. "
                     "Writes metrics.csv, metrics.json, tip_deflection.png, hub_angle.png, "
                     "torque.png and report.md to --out."))
    # explicit metavars: argparse would otherwise read the choices (importing the study layer)
    # when the parser is built, not only when --help is shown or a value is checked
    p.add_argument("--plant", metavar="PLANT", choices=RegistryChoices("hubbeam_ctrl.study.scenarios", "PLANTS"),
                   required=True, help="nonlinear plant: %(choices)s")
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
    p.add_argument("--tau-max", metavar="NM", type=real("N m"), default=200.0,
                   help="torque budget = Eq. 44 amplitude [N m] (default 200)")
    p.add_argument("--tf", metavar="S", type=real("s"), default=10.0,
                   help="maneuver time [s] (default 10)")
    p.add_argument("--t-end", metavar="S", type=real("s"), default=30.0,
                   help="simulated time [s], > tf + 5 (default 30)")
    p.add_argument("--wf", metavar="RAD_S", type=real("rad/s"),
                   help="spin-up final rate [rad/s] (default 3, above TLAM's critical speed; "
                        "--scenario spinup only)")
    p.add_argument("--dt", metavar="S", type=real("s"), default=0.01,
                   help="controller sample time [s] (default 0.01)")
    p.add_argument("--horizon", metavar="N", type=integer(),
                   help="MPC horizon [samples] (default 50; only with mpc among --controllers)")
    p.add_argument("--solver", choices=list(QP_SOLVERS),
                   help="MPC QP solver: %(choices)s (default daqp; only with mpc among --controllers)")
    p.add_argument("--schedule", metavar="N", type=positive_int("schedule"), default=1,
                   help="design the controllers with a scheduled version ("
                        + ",".join(n for n, s in CONTROLLERS.items() if s.scheduled)
                        + ") at N spin rates from 0 to the top reference rate and interpolate them on "
                          "the measured rate (default 1: one design point)")
    p.add_argument("--out", metavar="DIR", required=True,
                   help="output folder (created if missing; MANIFEST.json, written last, marks it complete)")
    p.add_argument("--json", action="store_true", help="print the metrics as JSON instead of a table")
    add_run_options(p)
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    """Run ``hubbeam compare``; returns the exit status (0)."""
    sink = stdout(args)
    from hubbeam_ctrl.cli.main import params_from_args
    from hubbeam_ctrl.sim.closedloop import ClosedLoopSettings
    from hubbeam_ctrl.study.compare import _parse_controllers, compare
    from hubbeam_ctrl.study.report import _json_metrics, format_table, write_outputs
    out = check_output_dir("--out", args.out)
    names = _parse_controllers(args.controllers)
    refuse_inapplicable(args, f"--scenario {args.scenario}", {"--wf": ("spinup",)})
    if "mpc" not in names:
        refuse_inapplicable(args, "--controllers " + ",".join(names), {"--horizon": ("mpc",),
                                                                       "--solver": ("mpc",)})
    params = params_from_args(args)
    t0 = time.perf_counter()
    comparison = compare(args.plant, args.scenario, names, params=params,
                         tau_max=args.tau_max, t_f=args.tf, t_end=args.t_end, dt=args.dt,
                         w_f=3.0 if args.wf is None else args.wf,
                         horizon=50 if args.horizon is None else args.horizon,
                         solver=args.solver or "daqp", shaping=args.shaping, schedule=args.schedule,
                         sim_settings=ClosedLoopSettings(**run_limits(args)), progress=not args.json)
    write_outputs(comparison, out)
    wall = time.perf_counter() - t0
    if args.json:
        print(strict_json(_json_metrics(comparison.metrics)), file=sink)
    else:
        sc = comparison.scenario
        print(f"{sc.plant.upper()}, {sc.name}: {sc.description}", file=sink)
        print(format_table(comparison.metrics), file=sink)
        print(f"wrote {out}/metrics.csv, metrics.json, tip_deflection.png, hub_angle.png, "
              f"torque.png, report.md, MANIFEST.json ({wall:.1f} s)", file=sink)
    for name, m in comparison.metrics.items():
        if not m["completed"]:
            print(f"warning: {name}: {m['message']}", file=sys.stderr)
    skipped = [n for n in names if n not in comparison.metrics]
    if skipped:
        print(f"warning: not run (the wall-time limit was reached): {', '.join(skipped)}", file=sys.stderr)
    return 0
