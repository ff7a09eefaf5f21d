"""``hubbeam tune``: robust weights for LQR, LQG or MPC over a study's plant spread
(see :mod:`hubbeam_ctrl.study.tune`).

Example::

    hubbeam tune payload.toml --controller lqr --out tuned/ --workers 2
    hubbeam sweep payload.toml --settings tuned/tuned_settings.toml --out check/
"""

from __future__ import annotations

from hubbeam_ctrl.cli.args import Command, add_rig_option
from hubbeam_ctrl.cli.main import finite_float, positive_int

__all__ = []


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


def _options(p) -> None:
    """``hubbeam tune``'s options on its parser ``p``."""
    from hubbeam_ctrl.cli.sweep import STUDY_RIG, add_engine_options
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
    add_rig_option(p, STUDY_RIG)
    add_engine_options(p)


def _plan(args) -> dict:
    """:func:`~hubbeam_ctrl.cli.sweep.study_plan`'s values, ``controller`` and ``options`` (TuneOptions: the
    spec's ``[tune]`` table, the flags over it)."""
    from hubbeam_ctrl.cli.sweep import study_plan
    from hubbeam_ctrl.core.reading import read_toml
    from hubbeam_ctrl.study.spec_files import MAX_SPEC_BYTES
    from hubbeam_ctrl.study.tune import TuneOptions

    plan = study_plan(args)
    table = dict(read_toml(args.spec, "spec: file", MAX_SPEC_BYTES).get("tune", {}))
    table.update({key: getattr(args, key) for key in TUNE_OPTIONS if getattr(args, key) is not None})
    return {**plan, "controller": args.controller, "options": TuneOptions.from_dict(table)}


#: The flags that override the spec's ``[tune]`` table (TuneOptions fields).
TUNE_OPTIONS = ("objective", "maxiter", "popsize", "decades", "seed")


def _run(args) -> int:
    """Tune the weights and write them."""
    from hubbeam_ctrl.cli.args import print_result
    from hubbeam_ctrl.cli.sweep import study_engine
    from hubbeam_ctrl.study.tune import tune, write_tune_outputs

    plan = _plan(args)
    with study_engine(plan) as client:
        result = tune(plan["spec"], plan["controller"], options=plan["options"], workers=plan["workers"],
                      client=client, progress=not plan["json"])
        paths = write_tune_outputs(result, plan["out"])
    r = result
    out = {"controller": r.controller, "objective": r.objective, "default_objective": r.default_objective,
           "worst_residual_m": r.worst_residual_m, "default_worst_residual_m": r.default_worst_residual_m,
           "x": r.x, "weights": r.settings_table()[r.controller]["weights"], "n_runs": r.n_runs,
           "wall_s": r.wall_s, "files": sorted(p.name for p in paths.values())}
    text = [f"{r.controller}: objective {r.objective:.4f} (scaled defaults {r.default_objective:.4f}); worst residual "
            f"{r.worst_residual_m:.3e} m (scaled defaults {r.default_worst_residual_m:.3e} m)",
            "weights: " + ", ".join(f"{k} = {v:.4g}" for k, v in out["weights"].items()),
            f"{r.n_runs} closed-loop runs in {r.wall_s:.1f} s; wrote {args.out}/tuned_settings.toml, tune.json, "
            "convergence.png"]
    print_result(args, out, "\n".join(text))
    return 0


COMMAND = Command(
    "tune", _options, _run, beam=False, plan=_plan, help="robust LQR/LQG/MPC weights over a study's plant spread",
    description=("Search the controller's weights (scaled, dimensionless; differential evolution started from the "
                 "scaled defaults) for the best worst case (or a quantile) over the cases of a study spec: residual "
                 "vibration in decades of L plus effort, settling and final-angle penalties. Writes "
                 "tuned_settings.toml (for hubbeam sweep --settings), tune.json and convergence.png to --out. The "
                 "spec's [tune] table sets the options; the flags below override it."))
