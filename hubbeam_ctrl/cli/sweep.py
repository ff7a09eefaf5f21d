"""``hubbeam sweep``: a robustness study over a plant spread (see :mod:`hubbeam_ctrl.study.sweep`).

Example::

    hubbeam sweep payload.toml --out payload_study --workers 2
    hubbeam sweep payload.toml --out payload_study --resume          # after an interruption
    hubbeam sweep payload.toml --out payload_study --scheduler tcp://10.0.0.5:8786
"""

from __future__ import annotations

import time

from hubbeam_ctrl.cli.args import Command, add_rig_option, add_verbose, nonempty, terminate_as_interrupt
from hubbeam_ctrl.cli.main import positive_float, positive_int

__all__ = ["add_engine_options", "study_plan", "study_engine", "STUDY_RIG"]


def add_engine_options(p) -> None:
    """Options shared by ``sweep`` and ``tune``: --workers, --scheduler, --scheduler-timeout, --json,
    --verbose.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The subcommand's parser.
    """
    p.add_argument("--workers", metavar="N", type=positive_int("workers"),
                   help="local worker processes (default: one per core; 1 runs in this process)")
    p.add_argument("--scheduler", metavar="ADDRESS", type=nonempty("scheduler address"),
                   help="run on the Dask cluster of this scheduler (e.g. tcp://host:8786) instead")
    p.add_argument("--scheduler-timeout", metavar="S", type=positive_float("scheduler-timeout"),
                   help="seconds to wait for the scheduler (default 10; with --scheduler only)")
    p.add_argument("--json", action="store_true", help="print a JSON summary, no progress bar")
    add_verbose(p)


def scheduler_plan(args):
    """``(address, timeout [s])`` of ``--scheduler`` and ``--scheduler-timeout``, or None without a
    scheduler; the options that do not apply are refused.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    """
    from hubbeam_ctrl.core.errors import ParameterError
    if not args.scheduler:
        if args.scheduler_timeout is not None:
            raise ParameterError("--scheduler-timeout applies with --scheduler only")
        return None
    if args.workers is not None:      # the cluster's workers run the cases
        raise ParameterError("--workers does not apply with --scheduler (the cluster's workers run the cases)")
    return args.scheduler, 10.0 if args.scheduler_timeout is None else args.scheduler_timeout


def study_plan(args) -> dict:
    """What ``sweep`` and ``tune`` share, as the values of the run, each option checked.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.

    Returns
    -------
    dict
        ``out`` (Path), ``spec`` (StudySpec with ``--rig``, ``--plant`` and ``--settings``),
        ``workers`` (int or None), ``scheduler`` (``(address, timeout)`` or None), ``json``.
    """
    from hubbeam_ctrl.cli.args import check_output_dir
    from hubbeam_ctrl.study.spec_files import load_settings
    out = check_output_dir("--out", args.out)
    spec = spec_from_args(args)
    if getattr(args, "settings", None):
        spec = load_settings(spec, args.settings)
    return {"out": out, "spec": spec, "workers": args.workers, "scheduler": scheduler_plan(args), "json": args.json}


class study_engine:
    """The Dask client of a plan's ``scheduler`` (None without one), closed on leaving; within the
    block the native output goes to stderr and SIGTERM acts as Ctrl-C.

    Parameters
    ----------
    plan : dict
        :func:`study_plan`'s values.
    """

    def __init__(self, plan):
        self.plan = plan

    def __enter__(self):
        from hubbeam_ctrl.cli.compare import stdout_to_stderr
        from hubbeam_ctrl.study.sweep import connect
        scheduler = self.plan["scheduler"]
        self.client = None if scheduler is None else connect(*scheduler)
        self._blocks = [stdout_to_stderr(), terminate_as_interrupt()]
        for block in self._blocks:
            block.__enter__()
        return self.client

    def __exit__(self, *exc):
        for block in reversed(self._blocks):
            block.__exit__(*exc)
        if self.client is not None:
            self.client.close()
        return False


#: ``--rig`` on a study command.
STUDY_RIG = ("run every case on this rig (a rig file or a preset), replacing the spec's [study] rig (docs/studies.md, "
             "'Sweeps on a rig'); its drive gives the torque limit")


def _options(p) -> None:
    """``hubbeam sweep``'s options on its parser ``p``."""
    p.add_argument("spec", metavar="SPEC.toml", help="study spec")
    p.add_argument("--out", metavar="DIR", required=True, help="output folder (created if missing)")
    p.add_argument("--resume", action="store_true", help="finish an interrupted study in --out")
    p.add_argument("--settings", metavar="FILE.toml",
                   help="controller settings merged into the spec's [settings] (e.g. hubbeam tune's output)")
    p.add_argument("--plant", metavar="PLANT", type=nonempty("plant"),
                   help="run every case on this plant (foam, cfoam, or ancf: the geometrically exact beam of "
                        "Exudyn, extra 'exact'), replacing the spec's [study] plant")
    add_rig_option(p, STUDY_RIG)
    add_engine_options(p)


def spec_from_args(args):
    """The study spec of ``args.spec`` with ``--rig`` and ``--plant`` applied; a bad one names its option.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line (reads ``spec``, ``rig`` and, when the command has it, ``plant``).

    Returns
    -------
    hubbeam_ctrl.study.spec.StudySpec
    """
    from hubbeam_ctrl.core.errors import ParameterError
    from hubbeam_ctrl.study.spec_files import load_spec

    try:
        return load_spec(args.spec, rig=args.rig, plant=getattr(args, "plant", None))
    except ParameterError as exc:
        for option, key in (("--rig", "study.rig"), ("--plant", "study.plant")):
            if getattr(args, option[2:], None) is not None and str(exc).startswith(key):
                rest = str(exc)[len(key):]
                rest = " " + rest[len(": rig "):] if rest.startswith(": rig ") else rest
                raise ParameterError(f"{option}{rest}") from None
        raise


def _plan(args) -> dict:
    """:func:`study_plan`'s values and ``resume``."""
    return {**study_plan(args), "resume": args.resume}


def _run(args) -> int:
    """Run the study and write its outputs."""
    from hubbeam_ctrl.cli.args import print_result
    from hubbeam_ctrl.study.sweep import sweep
    from hubbeam_ctrl.study.sweep_report import write_sweep_outputs

    plan = _plan(args)
    spec, out = plan["spec"], plan["out"]
    t0 = time.perf_counter()
    with study_engine(plan) as client:
        df = sweep(spec, workers=plan["workers"], client=client, progress=not plan["json"], out_dir=out,
                   resume=plan["resume"])
        wall = time.perf_counter() - t0
        paths = write_sweep_outputs(df, spec, out, wall)
    n_cases = int(df["case"].nunique()) if len(df) else 0
    failed = int(df.loc[df["error"].astype(str) != "", "case"].nunique())
    summary = {"out": str(args.out), "n_cases": n_cases, "n_failed": failed, "wall_s": wall,
               "files": sorted(p.name for p in paths.values()), "summary": _summary_records(df)}
    print_result(args, summary, lambda: _text(df, n_cases, failed, wall, args.out, paths))
    return 0


def _text(df, n_cases, failed, wall, out, paths) -> str:
    """The text result of ``hubbeam sweep``: summary.csv's table and what was written."""
    from hubbeam_ctrl.study.sweep_report import summarize
    return (summarize(df).to_string(index=False, float_format=lambda v: f"{v:.3g}")
            + f"\n{n_cases} cases ({failed} with errors) in {wall:.1f} s; wrote {out}/results.csv, summary.csv, "
              f"report.md and {sum(str(p).endswith('.png') for p in paths.values())} plots")


def _summary_records(df) -> list:
    """summary.csv as JSON-ready records (full precision; NaN as None)."""
    import math

    from hubbeam_ctrl.study.sweep_report import summarize
    clean = lambda v: None if isinstance(v, float) and not math.isfinite(v) else v
    return [{k: clean(v.item() if hasattr(v, "item") else v) for k, v in r.items()}
            for r in summarize(df).to_dict("records")]


COMMAND = Command(
    "sweep", _options, _run, beam=False, plan=_plan,
    help="robustness study: controllers over a plant spread (grid / Monte Carlo)",
    description=("Run every controller of a study spec (TOML: [study], [params], [settings.NAME], [grid], [random]) "
                 "on every case of its plant spread, on local worker processes or a Dask cluster. Writes "
                 "results.csv (appended as cases finish), summary.csv, robustness_<factor>.png, heatmap.png, "
                 "stable_region.png and report.md to --out."))
