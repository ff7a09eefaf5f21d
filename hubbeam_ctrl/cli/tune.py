"""``hubbeam tune``: robust weights for LQR, LQG or MPC over a study's plant spread
(see :mod:`hubbeam_ctrl.study.tune`).

Example::

    hubbeam tune payload.toml --controller lqr --out tuned/ --workers 2
    hubbeam sweep payload.toml --settings tuned/tuned_settings.toml --out check/
"""

from __future__ import annotations

from hubbeam_ctrl.cli.args import terminate_as_interrupt
from hubbeam_ctrl.cli.main import finite_float, positive_int

__all__ = ["add_parser", "run"]


def _objective(text):
    import argparse
    if text == "worst":
        return text
    try:
        q = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"objective must be 'worst' or a quantile in (0, 1], got {text!r}") from None
    if not 0 < q <= 1:
        raise argparse.ArgumentTypeError(f"objective must be 'worst' or a quantile in (0, 1], got {text}")
    return q


def add_parser(subparsers, common) -> None:
    """Add the ``tune`` subcommand (``common`` is not used: the spec holds the parameters).

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The ``hubbeam`` subcommands to add to.
    common : argparse.ArgumentParser
        Parent parser with the common plant options.
    """
    from hubbeam_ctrl.cli.sweep import add_engine_options, add_rig_option
    p = subparsers.add_parser(
        "tune", help="robust LQR/LQG/MPC weights over a study's plant spread",
        description=("Search the controller's weights (scaled, dimensionless; differential evolution "
                     "started from the scaled defaults) for the best worst case (or a quantile) over the "
                     "cases of a study spec: residual vibration in decades of L plus effort, settling and "
                     "final-angle penalties. Writes tuned_settings.toml (for hubbeam sweep --settings), "
                     "tune.json and convergence.png to --out. The spec's [tune] table sets the options; "
                     "the flags below override it."))
    p.add_argument("spec", metavar="SPEC.toml", help="study spec (its cases are the plant spread)")
    p.add_argument("--controller", choices=["lqr", "lqg", "mpc"], required=True)
    p.add_argument("--out", metavar="DIR", required=True, help="output folder (created if missing)")
    p.add_argument("--objective", type=_objective, help="'worst' (default) or a quantile in (0, 1]")
    p.add_argument("--maxiter", metavar="N", type=positive_int("maxiter"), help="generations (default 8)")
    p.add_argument("--popsize", metavar="N", type=positive_int("popsize"),
                   help="population per searched weight (default 4)")
    p.add_argument("--decades", metavar="D", type=finite_float("decades"),
                   help="search within D decades of the scaled defaults (default 2)")
    p.add_argument("--seed", metavar="N", type=int, help="optimiser seed (default 0)")
    add_rig_option(p)
    add_engine_options(p)
    p.set_defaults(func=run)


def run(args) -> int:
    """Run ``hubbeam tune``; bad input raises ParameterError (exit 2).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    """
    from hubbeam_ctrl.cli.args import check_output_dir, stdout
    from hubbeam_ctrl.cli.compare import stdout_to_stderr
    from hubbeam_ctrl.cli.sweep import engine_from_args, spec_from_args
    from hubbeam_ctrl.core.jsonio import strict_json
    from hubbeam_ctrl.core.reading import read_toml
    from hubbeam_ctrl.study.spec_files import MAX_SPEC_BYTES
    from hubbeam_ctrl.study.tune import TuneOptions, tune, write_tune_outputs

    sink = stdout(args)
    check_output_dir("--out", args.out)
    spec = spec_from_args(args)
    table = dict(read_toml(args.spec, "spec: file", MAX_SPEC_BYTES).get("tune", {}))
    for key in ("objective", "maxiter", "popsize", "decades", "seed"):
        if getattr(args, key) is not None:
            table[key] = getattr(args, key)
    options = TuneOptions.from_dict(table)
    client = engine_from_args(args)
    try:
        with stdout_to_stderr(), terminate_as_interrupt():
            result = tune(spec, args.controller, options=options, workers=args.workers, client=client,
                          progress=not args.json)
            paths = write_tune_outputs(result, args.out)
    finally:
        if client is not None:
            client.close()
    out = {"controller": result.controller, "objective": result.objective,
           "default_objective": result.default_objective, "worst_residual_m": result.worst_residual_m,
           "default_worst_residual_m": result.default_worst_residual_m, "x": result.x,
           "weights": result.settings_table()[result.controller]["weights"], "n_runs": result.n_runs,
           "wall_s": result.wall_s, "files": sorted(p.name for p in paths.values())}
    if args.json:
        print(strict_json(out), file=sink)
    else:
        r = result
        print(f"{r.controller}: objective {r.objective:.4f} (scaled defaults {r.default_objective:.4f}); "
              f"worst residual {r.worst_residual_m:.3e} m (scaled defaults {r.default_worst_residual_m:.3e} m)",
              file=sink)
        print("weights: " + ", ".join(f"{k} = {v:.4g}" for k, v in out["weights"].items()), file=sink)
        print(f"{result.n_runs} closed-loop runs in {result.wall_s:.1f} s; wrote {args.out}/tuned_settings.toml, "
              "tune.json, convergence.png", file=sink)
    return 0
