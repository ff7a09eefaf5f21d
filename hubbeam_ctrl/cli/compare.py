"""``hubbeam compare``: the controllers in closed loop on FOAM or CFOAM (see :mod:`.compare`)."""

from __future__ import annotations

import argparse
import json
import sys
import time

from controllers import CONTROLLERS, QP_SOLVERS, controller_names
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
    p.add_argument("--tau-max", metavar="NM", type=positive_float("tau-max"), default=200.0,
                   help="torque budget = Eq. 44 amplitude [N m] (default 200)")
    p.add_argument("--tf", metavar="S", type=positive_float("tf"), default=10.0,
                   help="maneuver time [s] (default 10)")
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
    p.add_argument("--out", metavar="DIR", required=True, help="output folder (created if missing)")
    p.add_argument("--json", action="store_true", help="print the metrics as JSON instead of a table")
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    """Run ``hubbeam compare``; returns the exit status (0)."""
    from pathlib import Path

    from hubbeam_ctrl.cli.main import params_from_args
    from hubbeam_ctrl.study.compare import compare
    from hubbeam_ctrl.study.report import _json_metrics, format_table, write_outputs
    params = params_from_args(args)
    out = Path(args.out)
    if not out.parent.is_dir():
        raise ParameterError(f"out: folder {out.parent} does not exist")
    if out.exists() and not out.is_dir():
        raise ParameterError(f"out: {out} exists and is not a folder")
    t0 = time.perf_counter()
    with stdout_to_stderr():
        comparison = compare(args.plant, args.scenario, args.controllers, params=params,
                             tau_max=args.tau_max, t_f=args.tf, t_end=args.t_end, dt=args.dt,
                             w_f=args.wf, horizon=args.horizon, solver=args.solver,
                             progress=not args.json)
        write_outputs(comparison, out)
    wall = time.perf_counter() - t0
    if args.json:
        print(json.dumps(_json_metrics(comparison.metrics)))
    else:
        sc = comparison.scenario
        print(f"{sc.plant.upper()}, {sc.name}: {sc.description}")
        print(format_table(comparison.metrics))
        print(f"wrote {out}/metrics.csv, metrics.json, tip_deflection.png, hub_angle.png, "
              f"torque.png, report.md ({wall:.1f} s)")
    for name, m in comparison.metrics.items():
        if not m["completed"]:
            print(f"warning: {name}: {m['message']}", file=sys.stderr)
    return 0
