"""Command-line interface: ``hubbeam modes | critical-speed | simulate | linearize | compare | design | codegen``.

Every subcommand accepts the common options ``--tip-mass KG``, ``--tip-position M``,
``--n-modes N`` (both families) and ``--params FILE.toml``. Bad input prints one line on
stderr naming the parameter and exits with status 2, without a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import re
import sys
import warnings
from collections.abc import Sequence

from hubbeam_ctrl.cli.args import (
    UNSTABLE_NOTE,
    add_run_options,
    add_verbose,
    check_output,
    integer,
    nonempty,
    params_from_args,
    real,
    refuse_inapplicable,
    rename_options,
    run_limits,
    stdout,
)
from hubbeam_ctrl.core.errors import RESOURCE_ERRNOS, HubbeamError, ParameterError, ResourceError
from hubbeam_ctrl.core.fileio import strict_json
from hubbeam_ctrl.core.native import capture_native_output
from hubbeam_ctrl.plant.convergence import CLI_ASSUMED_MODES
from hubbeam_ctrl.plant.models import AXIAL_TREATMENTS, MODEL_SPECS
from hubbeam_ctrl.plant.params import MAX_MODES

__all__ = ["main", "params_from_args", "build_parser", "positive_float", "positive_int", "finite_float",
           "RegistryChoices", "add_backend_option"]

#: Models whose bending stiffness is quadratic in the spin (``critical-speed`` needs it; CFOAM's
#: complete foreshortening is not).
CRITICAL_SPEED_MODELS = tuple(n for n, spec in MODEL_SPECS.items() if spec.foreshortening != "complete")

#: Subcommands contributed by other modules, each holding its ``COMMAND`` (:class:`~hubbeam_ctrl.cli.args.Command`).
EXTRA_COMMANDS = ("hubbeam_ctrl.cli.linearize", "hubbeam_ctrl.cli.compare", "hubbeam_ctrl.cli.design",
                  "hubbeam_ctrl.cli.sweep", "hubbeam_ctrl.cli.tune", "hubbeam_ctrl.cli.cache",
                  "hubbeam_ctrl.cli.optimal", "hubbeam_ctrl.cli.fmu", "hubbeam_ctrl.cli.demo",
                  "hubbeam_ctrl.cli.codegen", "hubbeam_ctrl.cli.excite", "hubbeam_ctrl.cli.identify",
                  "hubbeam_ctrl.cli.certify")


class _Parser(argparse.ArgumentParser):
    """argparse that raises instead of printing usage, so errors are one line.

    ``argument --t-end: must be a number, got 'x'`` becomes ``--t-end must be a number, got 'x'``.
    """

    def error(self, message):
        match = re.match(r"^argument (-[-\w]+)(?:/-[-\w]+)*: (.*)$", message, re.S)
        if match:
            option, text = match.groups()
            message = f"{option} {text}" if text.startswith("must ") else f"{option}: {text}"
        raise ParameterError(message)


class RegistryChoices(Sequence):
    """argparse ``choices`` read from a registry the first time they are needed.

    The registry's module is imported only when a value is checked or the help is shown, so
    building the parser stays cheap (``hubbeam modes`` does not import the study layer).

    Parameters
    ----------
    module : str
        Module holding the registry (e.g. ``"hubbeam_ctrl.study.scenarios"``).
    attr : str
        Its name in the module (a mapping or sequence of names, e.g. ``"SCENARIOS"``).
    """

    def __init__(self, module: str, attr: str):
        self.module, self.attr = module, attr

    def _names(self) -> tuple:
        return tuple(getattr(importlib.import_module(self.module), self.attr))

    def __getitem__(self, i):
        return self._names()[i]

    def __len__(self):
        return len(self._names())

    def __contains__(self, value):
        return value in self._names()


def _common_parser() -> argparse.ArgumentParser:
    common = _Parser(add_help=False)
    g = common.add_argument_group("system parameters (default: the paper's Table 1)")
    g.add_argument("--params", metavar="FILE.toml", type=nonempty("file"),
                   help="TOML file with Params fields (SI units)")
    g.add_argument("--tip-mass", metavar="KG", type=real("kg"),
                   help="tip mass m_t [kg], 0..1000 x the beam mass")
    g.add_argument("--tip-position", metavar="M", type=real("m"),
                   help="tip-mass position l along the beam [m], 0..L (default L)")
    g.add_argument("--n-modes", metavar="N", type=integer(),
                   help="number of axial and of transverse modes, 1..20 (default 5)")
    return common


def positive_float(name):
    """argparse type: a finite number > 0 (its upper range is checked by the library).

    Parameters
    ----------
    name : str
        The option's name (for the message).
    """
    return real(positive=True)


def positive_int(name):
    """argparse type: an integer > 0 (its upper range is checked by the library).

    Parameters
    ----------
    name : str
        The option's name (for the message).
    """
    def parse(text):
        value = integer()(text)
        if value <= 0:
            raise argparse.ArgumentTypeError(f"must be an integer > 0, got {text[:40]}")
        return value
    return parse


def finite_float(name):
    """argparse type: a finite number (its range is checked by the library).

    Parameters
    ----------
    name : str
        The option's name (kept for the callers; the message names the option).
    """
    return real()


def add_backend_option(parser) -> None:
    """Add ``--backend {auto,compiled,vm}`` (see :mod:`hubbeam_ctrl.core.compiled`).

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    """
    from hubbeam_ctrl.core.compiled import BACKENDS
    parser.add_argument("--backend", choices=BACKENDS, default=None,
                        help="evaluate the plant in CasADi's VM or as generated C (compiled once, "
                             "cached; see `hubbeam cache info`); auto: compiled when a C compiler "
                             "works (default: $HUBBEAM_BACKEND or auto)")


def check_output_folder(option: str, path) -> None:
    """Raise :class:`ParameterError` unless a file can be written at ``path`` (see
    :func:`hubbeam_ctrl.cli.args.check_output`).

    Parameters
    ----------
    option : str
        The option as typed (``--out``).
    path : str or Path
        The file to be written.
    """
    check_output(option, path)


# -- modes ----------------------------------------------------------------------
def _cmd_modes(args) -> int:
    sink = stdout(args)
    from hubbeam_ctrl.plant.convergence import CONVERGENCE_TARGET, converged_modes
    params = params_from_args(args)
    shown = max(params.n_transverse, params.n_axial)
    assumed = args.assumed_modes if args.assumed_modes is not None else max(CLI_ASSUMED_MODES, shown)
    if not 4 <= assumed <= MAX_MODES:
        raise ParameterError(f"--assumed-modes must be an integer in 4..{MAX_MODES}, got {assumed}")
    if max(params.n_transverse, params.n_axial) > assumed:
        raise ParameterError(f"--n-modes (the frequencies shown) must be at most --assumed-modes ({assumed}), "
                             f"got {max(params.n_transverse, params.n_axial)}")
    res = converged_modes(args.model, args.spin, args.hub, params, assumed_modes=assumed)
    ok_bending, ok_axial = res.converged()
    out = {"model": args.model, "spin_rad_s": args.spin, "hub": args.hub,
           "frequencies_hz": [float(f) for f in res.bending_hz],
           "axial_frequencies_hz": [float(f) for f in res.axial_hz],
           "assumed_modes": res.assumed_modes,
           "frequency_errors": [float(e) for e in res.bending_error],
           "axial_frequency_errors": [float(e) for e in res.axial_error],
           "convergence_target": CONVERGENCE_TARGET,
           "unstable": res.unstable}
    if args.json:
        print(strict_json(out), file=sink)
    else:
        counts = ", ".join(str(n) for n in (res.assumed_modes // 2 + res.assumed_modes % 2,
                                             (3 * res.assumed_modes + 3) // 4, res.assumed_modes))
        print(f"{args.model.upper()} at {args.spin:g} rad/s, hub {args.hub}, {res.assumed_modes} assumed modes"
              + (UNSTABLE_NOTE if res.unstable else ""), file=sink)
        print(f"  (last column: estimated error from {counts} modes; "
              f"* = not converged to {100 * CONVERGENCE_TARGET:g} %)", file=sink)
        def error(e, ok):
            return (f"{100 * e:+7.3f} %" if e == e else "    n/a  ") + ("" if ok else " *")
        for i, (f, e, ok) in enumerate(zip(res.bending_hz, res.bending_error, ok_bending), 1):
            print(f"  bending mode {i}: {f:10.4f} Hz  {error(e, ok)}", file=sink)
        for i, (f, e, ok) in enumerate(zip(res.axial_hz, res.axial_error, ok_axial), 1):
            print(f"  axial mode {i}:   {f:10.2f} Hz  {error(e, ok)}", file=sink)
        if not (ok_bending.all() and ok_axial.all()):
            print(f"  * not shown converged to {100 * CONVERGENCE_TARGET:g} % by {res.assumed_modes} assumed "
                  "modes (n/a: the coarser models lack the mode)", file=sink)
    return 0


# -- critical speed ---------------------------------------------------------------
def _cmd_critical(args) -> int:
    sink = stdout(args)
    from hubbeam_ctrl.plant.modal import critical_speed
    params = params_from_args(args)
    w = critical_speed(args.model, params)
    if args.json:
        print(strict_json({"model": args.model, "critical_speed_rad_s": w}), file=sink)
    if w is None:
        print(f"{args.model.upper()} keeps positive bending stiffness at every spin rate up to "
              "1000 rad/s: no critical speed", file=sys.stderr if args.json else sink)
    elif not args.json:
        print(f"{args.model.upper()} critical speed: {w:.4f} rad/s "
              f"(m_t = {params.m_t:g} kg at l = {params.tip_position:g} m)", file=sink)
    return 0


#: Output sample period of the fixed-step torque runs [s] (IDAS's default dt).
FIXED_STEP_DT = 0.01


# -- simulate -----------------------------------------------------------------------
def _cmd_simulate(args) -> int:
    sink = stdout(args)
    from hubbeam_ctrl.plant.maneuvers import SpinUp, TorquePulse
    from hubbeam_ctrl.sim.simulate import simulate
    check_output("--out", args.out, (".csv", ".npz"))
    check_output("--plot", args.plot, (".png",))
    refuse_inapplicable(args, f"--maneuver {args.maneuver}", {"--wf": ("spinup",), "--tau-max": ("torque",)})
    params = params_from_args(args)
    if args.maneuver == "spinup":
        maneuver = SpinUp(args.wf if args.wf is not None else 3.0, args.tf if args.tf is not None else 30.0)
    else:
        maneuver = TorquePulse(args.tau_max if args.tau_max is not None else 200.0,
                               args.tf if args.tf is not None else 10.0)
    if args.plant == "ancf":
        return _simulate_exact(args, maneuver, params, sink)
    refuse_inapplicable(args, "an assumed-mode model", {"--substeps": ("--plant ancf",),
                                                        "--elements": ("--plant ancf",)})
    if args.model is None:
        raise ParameterError("--model is required (cfoam, foam, tlam, sfoam), or --plant ancf for the exact beam")
    integrator = args.integrator
    if integrator == "auto":
        integrator = "fixed-step" if args.maneuver == "torque" and args.t_end >= 2 * FIXED_STEP_DT else "idas"
    if integrator == "fixed-step":
        if args.maneuver != "torque":
            raise ParameterError("--integrator fixed-step needs --maneuver torque (a spin-up prescribes the "
                                 "hub: use --integrator idas)")
        from hubbeam_ctrl.sim.estimated import simulate_estimated
        res = simulate_estimated(args.model, maneuver, args.t_end, params=params, dt=FIXED_STEP_DT,
                                 range_limit=args.range_limit, backend=args.backend, axial=args.axial,
                                 outputs=bool(args.out), **run_limits(args))
    else:
        res = simulate(args.model, maneuver, args.t_end, params=params, progress=not args.json,
                       range_limit=args.range_limit, **run_limits(args), backend=args.backend, axial=args.axial)
    _print_simulation(args, res, integrator, sink)
    return 0


def _simulate_exact(args, maneuver, params, sink) -> int:
    """``hubbeam simulate --plant ancf``: the maneuver on the exact beam (Exudyn ANCF)."""
    for option, value, default in (("--model", args.model, None), ("--axial", args.axial, "dynamic"),
                                   ("--integrator", args.integrator, "auto"), ("--backend", args.backend, None)):
        if value != default:
            raise ParameterError(f"{option} does not apply to --plant ancf (the exact beam: Exudyn's ANCF "
                                 "elements and generalized-alpha; FOAM's modes for the projected state)")
    from hubbeam_ctrl.sim.exactbeam import simulate_exact
    res = simulate_exact(maneuver, args.t_end, params=params, dt=FIXED_STEP_DT, substeps=args.substeps,
                         n_elements=args.elements, range_limit=args.range_limit, progress=not args.json,
                         option_names={"substeps": "--substeps", "dt": "dt", "plant": "--plant ancf",
                                       "n_elements": "--elements"},
                         **run_limits(args))
    _print_simulation(args, res, "exudyn-ancf", sink)
    return 0


def _print_simulation(args, res, integrator: str, sink) -> None:
    """Save, plot and print the summary of a ``hubbeam simulate`` run."""
    if args.out:
        res.save(args.out)
    if args.plot:
        from hubbeam_ctrl.plots.plant import plot_result, save_figure
        save_figure(plot_result(res), args.plot, option="plot")
    s = res.summary()
    out = {k: s[k] for k in ("peak_tip_m", "residual_tip_m", "peak_axial_m", "final_theta_rad",
                             "final_theta_dot_rad_s", "diverged", "wall_s")}
    out["integrator"] = integrator
    out["peak_error_estimate"] = res.stats.get("peak_error_estimate")     # None: IDAS's error control
    if res.model == "ancf":
        out.update(plant="ancf", plant_elements=res.settings["plant_elements"], substeps=res.settings["substeps"],
                   past_assumed_mode_range_time_s=res.stats.get("past_assumed_mode_range_time_s"))
    if args.json:
        print(strict_json(out), file=sink)
    else:
        for k, v in out.items():
            print(f"{k:>22}: {v}", file=sink)
        print(f"{'message':>22}: {res.message}", file=sink)
    if res.diverged or res.outside_validated_range or res.stats.get("past_assumed_mode_range_time_s") is not None:
        print(f"warning: {res.message}", file=sys.stderr)


def build_parser() -> argparse.ArgumentParser:
    """The ``hubbeam`` argument parser (with the subcommands of other modules)."""
    common = _common_parser()
    parser = _Parser(prog="hubbeam", description=(
        "Rotating hub-beam toolbox: nonlinear models with dynamic stiffening (CFOAM, FOAM, "
        "TLAM, SFOAM), modal analysis, simulation, linear models and controllers."))
    parser.add_argument("--version", action="version", version=f"%(prog)s {sys.modules['hubbeam_ctrl'].__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    p = sub.add_parser("modes", parents=[common], help="natural frequencies at a spin rate",
                       description="Bending (and axial) natural frequencies of a model linearised "
                                   "about steady rotation: the first --n-modes (default 5) of each "
                                   "family, from a model with --assumed-modes modes (default 16), "
                                   "each with its estimated error.")
    p.add_argument("--model", choices=list(MODEL_SPECS), default="foam")
    p.add_argument("--spin", metavar="RAD_S", type=real("rad/s"), default=0.0,
                   help="spin rate [rad/s], at most the 1 %% root-strain spin Params.max_spin (default 0)")
    p.add_argument("--hub", choices=["prescribed", "free"], default="prescribed",
                   help="prescribed: clamped root turning at --spin (Table 2); free: hub free")
    p.add_argument("--assumed-modes", metavar="N", type=integer(), default=None,
                   help=f"axial and transverse modes of the model the frequencies come from, 4..{MAX_MODES} "
                        f"(default {CLI_ASSUMED_MODES}, or --n-modes if more: the bending frequencies "
                        "converged to 0.05 %%; --n-modes is how many are shown); each frequency "
                        "carries its error estimated from models with N/2 and 3N/4 modes")
    p.add_argument("--json", action="store_true", help="print JSON")
    add_verbose(p)
    p.set_defaults(func=_cmd_modes)

    p = sub.add_parser("critical-speed", parents=[common],
                       help="spin rate at which the bending stiffness is lost",
                       description="Critical speed of TLAM (or FOAM, which has none).")
    p.add_argument("--model", choices=CRITICAL_SPEED_MODELS, default="tlam")
    p.add_argument("--json", action="store_true", help="print JSON")
    add_verbose(p)
    p.set_defaults(func=_cmd_critical)

    p = sub.add_parser("simulate", parents=[common], help="simulate a maneuver",
                       description="Simulate the Eq. 43 spin-up (prescribed hub) or the Eq. 44 "
                                   "torque pulse (free hub).")
    p.add_argument("--model", choices=list(MODEL_SPECS), default=None,
                   help="the assumed-mode model (required unless --plant ancf)")
    p.add_argument("--plant", choices=["ancf"], default=None,
                   help="ancf: the geometrically exact beam of Exudyn (ANCF cable elements, optional extra: "
                        "pip install 'hubbeam-ctrl[exact]') instead of --model; the torque is applied at every "
                        "integration step, the step is FOAM's rule and the elements 3 per mode")
    p.add_argument("--substeps", metavar="K", type=integer(), default=None,
                   help="--plant ancf: integration steps per 10 ms sample (default: FOAM's rule, 0.5 %% on the "
                        "highest mode; at least 12 steps per period of the highest mode)")
    p.add_argument("--elements", metavar="N", type=integer(), default=None,
                   help="--plant ancf: ANCF elements (default: 3 per bending mode, a multiple of 8, at least 16)")
    p.add_argument("--maneuver", choices=["spinup", "torque"], required=True)
    p.add_argument("--wf", metavar="RAD_S", type=real("rad/s"),
                   help="spin-up final rate [rad/s] (default 3; --maneuver spinup only)")
    p.add_argument("--tf", metavar="S", type=real("s"),
                   help="maneuver time [s] (default 30 for spinup, 10 for torque)")
    p.add_argument("--tau-max", metavar="NM", type=real("N m"),
                   help="torque amplitude [N m], > 0 (default 200; --maneuver torque only)")
    p.add_argument("--t-end", metavar="S", type=real("s"), required=True,
                   help="final time [s], at least one sample (0.01 s)")
    p.add_argument("--out", metavar="FILE.csv|FILE.npz", help="save the time series")
    p.add_argument("--plot", metavar="FILE.png", help="save a plot")
    p.add_argument("--range-limit", metavar="FRACTION", type=real("-"), default=0.3,
                   help="flag the run when |v_tip| passes FRACTION * L (the models' validated range; "
                        "default 0.3); only L stops it")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.add_argument("--axial", choices=AXIAL_TREATMENTS, default="dynamic",
                   help="dynamic: integrate the axial modes (default); quasi-static: solve them from "
                        "their static balance at every instant (cfoam, foam, tlam; no stiff modes)")
    p.add_argument("--integrator", choices=["auto", "fixed-step", "idas"], default="auto",
                   help="fixed-step: the compiled generalized-alpha path run at 10 ms and 20 ms steps, the "
                        "step halved until the estimated error of the peak tip deflection is below 1e-4 "
                        "(torque only; about 10 times faster); idas: SUNDIALS IDAS with error control; "
                        "auto (default): fixed-step for --maneuver torque, idas for spinup")
    add_run_options(p)
    add_backend_option(p)
    p.set_defaults(func=_cmd_simulate)

    for name in EXTRA_COMMANDS:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name != name:
                raise
            continue
        module.COMMAND.add_to(sub, common)
    return parser


def main(argv=None) -> int:
    """Entry point of the ``hubbeam`` console script. Returns the exit status.

    0: done (warnings, e.g. a run that stopped early, on stderr); 2: bad input, one line on
    stderr naming the option, nothing written; 1: the run failed, or the system could not
    write its output (disk full: one line; the details in the ``--verbose`` log); 130:
    interrupted.

    Parameters
    ----------
    argv : list of str, optional
        Command-line arguments (default: ``sys.argv[1:]``).
    """
    parser = build_parser()
    args, options = None, set()
    try:
        _refuse_missing_values(sys.argv[1:] if argv is None else argv)
        args = parser.parse_args(argv)
        if not getattr(args, "command", None):
            print(parser.format_usage().strip() + "  (hubbeam --help lists the commands)", file=sys.stderr)
            return 2
        options = _options_of(parser, args.command)
        return _run(args.func, args)
    except ResourceError as exc:       # disk full, quota, I/O: not bad input
        return _fail(1, rename_options(_one_line(exc), options))
    except (ParameterError, HubbeamError) as exc:
        return _fail(2, rename_options(_one_line(exc), options))
    except KeyboardInterrupt:
        print("hubbeam: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:            # the reader of the output left (hubbeam cache info | head)
        return _closed_pipe()
    except MemoryError:
        return _fail(1, "out of memory (lower --t-end, --horizon or --n-modes)", args)
    except OSError as exc:
        if exc.errno not in RESOURCE_ERRNOS:
            return _fail(1, f"{type(exc).__name__}: {_one_line(exc)}", args, exc)
        where = f" ({exc.filename})" if exc.filename else ""
        return _fail(1, f"the system could not write{where}: {exc.strerror or exc}")
    except Exception as exc:      # a failure inside the run: one line here, the traceback in the log
        return _fail(1, f"{type(exc).__name__}: {_one_line(exc)}", args, exc)


class _library_logging:
    """Collect the libraries' log records (Python ``logging``, which would otherwise print
    WARNING and above, e.g. solver matrices, on the terminal through ``logging.lastResort``)
    as warnings for the ``--verbose`` log."""

    def __enter__(self):
        import logging
        records = self.records = []

        class _Collect(logging.Handler):
            def emit(self, record):
                try:
                    text = record.getMessage()
                except Exception:  # noqa: BLE001 - a record that cannot be formatted is still counted
                    text = str(record.msg)
                records.append(warnings.WarningMessage(text, UserWarning, record.pathname, record.lineno))

        self._logging, self._handler = logging, _Collect(logging.WARNING)
        self._last = logging.lastResort
        logging.lastResort = self._handler
        logging.getLogger().addHandler(self._handler)
        return records

    def __exit__(self, *exc):
        self._logging.getLogger().removeHandler(self._handler)
        self._logging.lastResort = self._last
        return False


def _refuse_missing_values(argv) -> None:
    """``--tau-max=--`` (or ``=-``): argparse would pass on an empty list, not a value."""
    for token in argv:
        token = str(token)
        if token.startswith("--") and "=" in token:
            option, value = token.split("=", 1)
            if value.strip() in ("--", "-", ""):
                raise ParameterError(f"{option} must be given a value, got {value!r}")


def _run(func, args) -> int:
    """Run a subcommand with native output captured (to the ``--verbose`` log, if given)."""
    log = getattr(args, "verbose", None)
    if log is not None:
        check_output("--verbose", log)
    with capture_native_output(log) as cap, warnings.catch_warnings(record=True) as caught, \
            _library_logging() as logged:
        warnings.simplefilter("default")
        args.stdout = cap.stdout              # results go here; sys.stdout is captured
        status = int(func(args) or 0)
    caught = list(caught) + logged
    if log is not None and caught:
        with open(log, "a", encoding="utf-8") as fh:
            fh.writelines(warnings.formatwarning(w.message, w.category, w.filename, w.lineno) for w in caught)
    lines = cap.lines + len(caught)
    if lines and log is None:
        hint = " (--verbose LOG keeps them)" if hasattr(args, "verbose") else ""
        print(f"hubbeam: note: {lines} line{'s' if lines > 1 else ''} of solver output and warnings "
              f"suppressed{hint}", file=sys.stderr)
    return status


def _closed_pipe() -> int:
    """The reader of the standard output has gone: stop quietly, as a command killed by SIGPIPE
    does (status 128 + 13), with the standard output pointed at ``/dev/null`` so that the
    interpreter's last flush finds no pipe to fail on."""
    import os
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):      # no file descriptor behind sys.stdout (tests, notebooks)
        pass
    return 141


def _options_of(parser, command: str) -> set:
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {o for action in sub.choices[command]._actions for o in action.option_strings}


def _one_line(exc) -> str:
    text = " ".join(str(exc).split())
    return text if len(text) <= 500 else text[:497] + "..."


def _fail(status: int, message: str, args=None, exc=None) -> int:
    """Print ``hubbeam: error: message`` on stderr; write the traceback to the log if any."""
    log = getattr(args, "verbose", None) if args is not None else None
    if exc is not None and log is not None:
        import traceback
        try:
            with open(log, "a", encoding="utf-8") as fh:
                fh.write("".join(traceback.format_exception(exc)))
            message += f" (details in {log})"
        except OSError:
            pass
    elif exc is not None and args is not None and hasattr(args, "verbose"):
        message += " (--verbose LOG for details)"
    print(f"hubbeam: error: {message}", file=sys.stderr)
    return status


if __name__ == "__main__":
    sys.exit(main())
