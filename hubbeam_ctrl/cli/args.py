"""Option handling shared by the subcommands: value types, option names, output checks.

Ranges live in one place, the library (field metadata of the settings and the checks of the
public functions); the command line only parses numbers and paths and then renames, in the
one-line error the library raises, the Python name to the option the user typed
(:data:`OPTION_NAMES`, :func:`rename_options`)::

    m_t must be in [0, 1e+06] [kg], got -1   ->   --tip-mass (m_t) must be in [0, 1e+06] [kg], got -1
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from hubbeam_ctrl.core.errors import ParameterError

__all__ = ["params_from_args", "rig_from_args", "beam_from_args", "source_from_args", "Command", "add_rig_option",
           "add_task_options", "print_result", "UNSTABLE_NOTE",
           "stdout", "check_rig_dt", "OPTION_NAMES", "rename_options", "real", "integer", "nonempty", "check_output",
           "check_output_dir", "refuse_inapplicable", "add_run_options", "run_limits",
           "terminate_as_interrupt"]

#: Python names (Params fields, function arguments, settings) -> the option that sets them.
#: Used to rename the library's messages; a name is renamed only on a subcommand that has
#: the option.
OPTION_NAMES = {
    "m_t": "--tip-mass", "l": "--tip-position", "n_axial": "--n-modes", "n_transverse": "--n-modes",
    "damping_ratio": "--damping", "damping": "--damping", "spin": "--spin",
    "w_f": "--wf", "wf": "--wf", "t_f": "--tf", "tf": "--tf", "tau_m": "--tau-max",
    "tau_max": "--tau-max", "t_end": "--t-end", "dt": "--dt", "horizon": "--horizon",
    "solver": "--solver", "controllers": "--controllers", "outputs": "--outputs",
    "max_wall_s": "--max-wall", "max_memory_mb": "--allow-large", "out": "--out", "plot": "--plot",
    "params": "--params", "scenario": "--scenario", "plant": "--plant", "model": "--model",
    "range_limit": "--range-limit", "design_modes": "--design-modes", "plant_modes": "--plant-modes",
    "schedule": "--schedule", "shaping": "--shaping", "axial": "--axial", "scheduler": "--scheduler",
    "timeout": "--scheduler-timeout", "tune.popsize": "--popsize", "tune.maxiter": "--maxiter",
    "tune.objective": "--objective", "tune.decades": "--decades", "tune.seed": "--seed",
    "max_tip_deflection": "--max-tip", "max_hub_travel": "--max-hub", "band_hz": "--band", "n_modes": "--modes",
    "slew_angle": "--slew-angle", "tolerance": "--tolerance", "duration": "--duration",
}

#: Names set by a second option on the subcommands that lack the first (``identify`` sets the
#: plant's ``n_transverse`` with ``--plant-modes``, not ``--n-modes``).
OTHER_OPTION_NAMES = {"n_transverse": "--plant-modes"}

#: What ``modes`` and ``linearize`` say about a model with a growing mode.
UNSTABLE_NOTE = " (UNSTABLE: a mode has lost its stiffness)"


def params_from_args(args, base=None):
    """Build :class:`Params` from the common options (file first, then flags).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    base : Params, optional
        The parameters the flags change when no ``--params`` file is given (default Table 1;
        a rig's beam with ``--rig``).
    """
    from hubbeam_ctrl.plant.params import Params, load_params
    if getattr(args, "params", None) is not None:
        base = load_params(args.params)
    elif base is None:
        base = Params()
    changes = {}
    if getattr(args, "tip_mass", None) is not None:
        changes["m_t"] = args.tip_mass
    if getattr(args, "tip_position", None) is not None:
        changes["l"] = args.tip_position
    if getattr(args, "n_modes", None) is not None:
        changes["n_axial"] = changes["n_transverse"] = args.n_modes
    params = base.replace(**changes) if changes else base
    if "l" in changes and params.m_t == 0 and all(getattr(args, k, None) is None for k in MASS_OPTIONS):
        raise ParameterError("--tip-position does not apply with a zero --tip-mass (m_t = 0 kg: there is no "
                             "tip mass to place)")
    return params


#: Options that put a mass at ``--tip-position`` besides ``--tip-mass`` (as argparse names).
MASS_OPTIONS = ("plant_tip_mass", "payload_range")


def rig_from_args(args):
    """The rig of ``--rig`` (a file or a preset) with the common options applied to its beam; None
    without ``--rig``. ``--rig`` and ``--params`` are exclusive (a rig file holds the beam).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    """
    if getattr(args, "rig", None) is None:
        return None
    from hubbeam_ctrl.plant.rig import load_rig
    if getattr(args, "params", None) is not None:
        raise ParameterError("--rig and --params are exclusive: a rig file holds the beam in its [beam] table")
    rig = load_rig(args.rig)
    beam = params_from_args(args, rig.beam)         # --tip-mass, --tip-position, --n-modes on the rig's beam
    return rig if beam == rig.beam else rig.replace(beam=beam)


def check_rig_dt(args, rig) -> None:
    """Refuse a ``--dt`` other than the rig's sample time ``timing.dt`` (the controller runs at the
    rig's rate: a design for another one is wrong on the rig), as the closed loop does.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line (``dt``: ``--dt`` or None).
    rig : Rig or None
        The rig of ``--rig``.
    """
    dt = getattr(args, "dt", None)
    rig_dt = None if rig is None else rig.timing.dt
    if dt is not None and rig_dt is not None and abs(dt - rig_dt) > 1e-12 * rig_dt:
        raise ParameterError(f"--dt must be the --rig's sample time timing.dt = {rig_dt:g} s (or left out), got {dt:g}")


def stdout(args):
    """The stream a subcommand prints its results to: the standard output saved before the
    run (during the run ``sys.stdout`` collects native and CasADi output, see
    :class:`~hubbeam_ctrl.core.native.capture_native_output`).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    """
    return getattr(args, "stdout", None) or sys.stdout


def print_result(args, summary: dict, text) -> None:
    """Print a command's result on its result stream (:func:`stdout`): ``summary`` as strict JSON with
    ``--json``, else ``text``.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line (reads ``json``).
    summary : dict
        The result, JSON-ready (non-finite numbers become null, flagged).
    text : str or callable
        The result as text, or a function returning it (called only without ``--json``).
    """
    from hubbeam_ctrl.core.jsonio import strict_json
    print(strict_json(summary) if args.json else text() if callable(text) else text, file=stdout(args))


_LEADING_NAME = re.compile(r"^([A-Za-z_][A-Za-z0-9_-]*(?:\.[A-Za-z_][A-Za-z0-9_]*)?)(?=[ :=])")


def rename_options(message: str, options) -> str:
    """Put the option the user typed in front of the Python name that starts ``message``.

    Parameters
    ----------
    message : str
        A one-line error of the library (``"m_t must be ..."``, ``"out: folder ..."``).
    options : collection of str
        The options of the subcommand that ran (``{"--tip-mass", ...}``).

    Returns
    -------
    str

    Examples
    --------
    >>> rename_options("m_t must be in [0, 1e+06] [kg], got -1", {"--tip-mass"})
    '--tip-mass (m_t) must be in [0, 1e+06] [kg], got -1'
    >>> rename_options("out: folder /no does not exist", {"--out"})
    '--out: folder /no does not exist'
    """
    match = _LEADING_NAME.match(message)
    if not match:
        return message
    name = match.group(1)
    option = OPTION_NAMES.get(name)
    if option not in options:
        option = OTHER_OPTION_NAMES.get(name)
    if option is None or option not in options:
        # a message that names the option without its dashes (``tau-max must ...``,
        # ``design_modes must ...``): the option as typed
        option = "--" + name.replace("_", "-")
        if option not in options:
            return message
    label = option if option.lstrip("-").replace("-", "_") == name.replace("-", "_") else f"{option} ({name})"
    return label + message[match.end():]


def _number_text(text: str):
    try:
        value = float(text)
    except (TypeError, ValueError, OverflowError):
        raise argparse.ArgumentTypeError(f"must be a number, got {text[:40]!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text[:40]}")
    return value


def real(unit: str = "-", *, positive: bool = False):
    """argparse type: a finite number (its range is checked by the library, before any work).

    Parameters
    ----------
    unit : str
        Unit, for the help text only.
    positive : bool
        Refuse a number <= 0 here (for the options whose only lower bound is 0).
    """
    def parse(text):
        value = _number_text(text)
        if positive and not value > 0:
            raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text[:40]}")
        return value
    parse.unit = unit
    return parse


def integer():
    """argparse type: an integer (``5`` or ``5.0``; its range is checked by the library)."""
    def parse(text):
        try:
            return int(text)
        except ValueError:
            pass
        try:
            value = _number_text(text)
        except argparse.ArgumentTypeError:
            raise argparse.ArgumentTypeError(f"must be an integer, got {text[:40]!r}") from None
        if not float(value).is_integer():
            raise argparse.ArgumentTypeError(f"must be an integer, got {text[:40]}")
        return int(value)
    return parse


def nonempty(what: str = "file"):
    """argparse type: a non-empty path (an empty ``--params ''`` is an error, not "none").

    Parameters
    ----------
    what : str
        What the path names (for the message).
    """
    def parse(text):
        if not text.strip():
            raise argparse.ArgumentTypeError(f"must name a {what}, got {text!r}")
        if "\x00" in text:
            raise argparse.ArgumentTypeError(f"must name a {what}, got a name with a NUL byte")
        return text
    return parse


def check_output(option: str, path, suffixes=None) -> Path | None:
    """Check an output file option before any work (see :func:`~hubbeam_ctrl.core.fileio.check_writable`).

    Parameters
    ----------
    option : str
        The option as typed (``"--out"``).
    path : str or None
        Its value (``None``: not given, nothing to check).
    suffixes : sequence of str, optional
        Allowed extensions (lower case, with the dot).

    Returns
    -------
    Path or None
    """
    from hubbeam_ctrl.core.fileio import check_writable
    if path is None:
        return None
    if suffixes and not str(path).lower().endswith(tuple(suffixes)):
        raise ParameterError(f"{option} must end in {', '.join(suffixes)}, got {str(path)[:80]!r}")
    return check_writable(path, option)


def check_output_dir(option: str, path) -> Path:
    """Check an output folder option before any work: a non-empty name, an existing and
    writable parent folder, not an existing file, a name the system takes.

    Parameters
    ----------
    option : str
    path : str

    Returns
    -------
    Path
    """
    from hubbeam_ctrl.core.fileio import check_writable
    if path is None or not str(path).strip():
        raise ParameterError(f"{option} must name a folder, got {path!r}")
    out = Path(path)
    check_writable(out.parent / (out.name + ".probe"), option)   # name length, parent exists and writable
    if out.exists() and not out.is_dir():
        raise ParameterError(f"{option}: {out} exists and is not a folder")
    if out.is_dir():
        check_writable(out / "metrics.probe", option)               # the folder itself is writable
    return out


def refuse_inapplicable(args, chosen: str, applies: dict) -> None:
    """Refuse options given for a choice they do not apply to.

    Parameters
    ----------
    args : argparse.Namespace
    chosen : str
        The choice made (e.g. the maneuver, ``"torque"``), as ``--option value`` text.
    applies : dict
        Option (as typed) -> the choices it applies to; its value is read from ``args`` by
        the option's name (``--tau-max`` -> ``tau_max``) and counts as given unless ``None``.

    Raises
    ------
    ParameterError
        ``--wf does not apply to --maneuver torque (only to spinup)``.
    """
    for option, choices in applies.items():
        value = getattr(args, option.lstrip("-").replace("-", "_"), None)
        if value is not None and chosen.split()[-1] not in choices:
            raise ParameterError(f"{option} does not apply to {chosen} (only to {', '.join(choices)})")


def add_run_options(parser) -> None:
    """Add ``--max-wall``, ``--allow-large`` and ``--verbose`` to a long-running subcommand.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    """
    parser.add_argument("--max-wall", metavar="S", type=real("s"),
                        help="wall-time limit of the run [s] (default 600): a run estimated to take "
                             "longer is refused, a run that takes longer stops, flagged, keeping its "
                             "results; checked at least once per second")
    parser.add_argument("--allow-large", action="store_true",
                        help="lift the memory limit (default 2048 MB) on runs whose results or "
                             "matrices would need more")
    add_verbose(parser)


def add_verbose(parser) -> None:
    """Add ``--verbose [LOG]``: native solver output and failure details go to a log file.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    """
    parser.add_argument("--verbose", metavar="LOG", nargs="?", const="hubbeam.log", type=nonempty("file"),
                        help="write native solver output and the details of failures to LOG "
                             "(default hubbeam.log); without it they are summarised in one line")


def run_limits(args) -> dict:
    """``max_wall_s`` and ``max_memory_mb`` settings from ``--max-wall`` and ``--allow-large``.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    """
    limits = {}
    if getattr(args, "max_wall", None) is not None:
        limits["max_wall_s"] = args.max_wall
    if getattr(args, "allow_large", False):
        limits["max_memory_mb"] = 1e9
    return limits


class terminate_as_interrupt:
    """Within the block, SIGTERM to this process acts as Ctrl-C (``KeyboardInterrupt``), so the
    clean-up of a run with worker processes (:meth:`hubbeam_ctrl.study.sweep.Engine.terminate`)
    runs and stops them; the default action would end this process alone and leave the
    workers holding the terminal's pipes. Outside the main thread it does nothing."""

    def __enter__(self):
        import signal
        import threading
        self._previous = None
        if threading.current_thread() is threading.main_thread():
            def interrupt(signum, frame):
                raise KeyboardInterrupt("SIGTERM")
            self._previous = signal.signal(signal.SIGTERM, interrupt)
        return self

    def __exit__(self, *exc):
        if self._previous is not None:
            import signal
            signal.signal(signal.SIGTERM, self._previous)
        return False


@dataclass(frozen=True)
class Command:
    """A ``hubbeam`` subcommand: its texts, its options and what runs it (each command module holds
    one, ``COMMAND``, and :func:`hubbeam_ctrl.cli.main.build_parser` adds them all).

    Attributes
    ----------
    name : str
        The subcommand (``hubbeam NAME``).
    options : callable
        ``options(parser)``: adds the command's own options.
    func : callable
        ``func(args) -> int``: runs the command and returns the exit status; bad input raises
        ParameterError (exit 2).
    help : str
        Its line in ``hubbeam --help``.
    description : str
        Its ``hubbeam NAME --help`` text.
    beam : bool
        Whether it takes the beam options ``--params``, ``--tip-mass``, ``--tip-position``, ``--n-modes``.
    formatter_class : type or None
        argparse help formatter (None: argparse's).
    plan : callable or None
        ``plan(args)``: the command line as the run's values (the keywords of the library call it makes),
        each option checked before any work: every option sets a value or is refused in one line naming it
        and what it conflicts with (what tests/test_options_walk.py compares). None: the command has none.
    """

    name: str
    options: Callable
    func: Callable
    help: str
    description: str
    beam: bool = True
    formatter_class: type | None = None
    plan: Callable | None = None

    def add_to(self, subparsers, common) -> argparse.ArgumentParser:
        """Add the subcommand to ``hubbeam``'s.

        Parameters
        ----------
        subparsers : argparse._SubParsersAction
            The ``hubbeam`` subcommands.
        common : argparse.ArgumentParser
            The parent parser with the beam options.

        Returns
        -------
        argparse.ArgumentParser
        """
        extra = {} if self.formatter_class is None else {"formatter_class": self.formatter_class}
        p = subparsers.add_parser(self.name, parents=[common] if self.beam else [], help=self.help,
                                  description=self.description, **extra)
        self.options(p)
        p.set_defaults(func=self.func)
        return p


def add_rig_option(p, help: str = "a rig file or preset (servo_link, paper): its beam, drive, sensors and sample "
                                  "time; not with --params", *, required: bool = False) -> None:
    """Add ``--rig RIG.toml|PRESET`` to a subcommand (or a group of its options).

    Parameters
    ----------
    p : argparse.ArgumentParser or argument group
        Where to add it.
    help : str
        What the rig is for, on this command.
    required : bool
        Whether the command needs one.
    """
    p.add_argument("--rig", metavar="RIG.toml|PRESET", type=nonempty("rig"), required=required, help=help)


def add_task_options(p, dt_help: str) -> None:
    """Add the task of a design, as :func:`design_task` reads it: ``--scenario``, ``--slew-angle``,
    ``--tf``, ``--wf``, ``--dt``, ``--design-modes`` and ``--tau-max``.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The subcommand's parser.
    dt_help : str
        What ``--dt`` defaults to on this command.
    """
    p.add_argument("--scenario", choices=["slew", "spinup"], default="slew",
                   help="the task: slew (default, design at rest) or spinup (design at --wf)")
    p.add_argument("--slew-angle", metavar="RAD", type=real("rad"),
                   help="slew angle [rad], not 0 (default: the Eq. 44 angle of --tau-max in --tf)")
    p.add_argument("--tf", metavar="S", type=real("s", positive=True),
                   help="maneuver time [s] (default: a slew on a --rig with hardware is the rig's default slew, "
                        "as compare --rig runs; else 10); a slew on such a rig turns --slew-angle, default a "
                        "quarter turn, in it")
    p.add_argument("--wf", metavar="RAD_S", type=real("rad/s"),
                   help="spin-up final rate [rad/s] (default 3; --scenario spinup only)")
    p.add_argument("--dt", metavar="S", type=real("s", positive=True), help=f"sample time [s] (default: {dt_help})")
    p.add_argument("--design-modes", metavar="N", type=int,
                   help="transverse modes of the design model, 1..20 (default: --n-modes or 5)")
    p.add_argument("--tau-max", metavar="NM", type=real("N m", positive=True),
                   help="torque budget [N m], at most the motor's tau_max (default: that)")


def beam_from_args(args):
    """``(rig, params)``: the rig of ``--rig`` (None without it) and the beam the command works on,
    the rig's plant beam (its rotor reflected) or the beam of the beam options.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    """
    rig = rig_from_args(args)
    return rig, rig.plant_params if rig is not None else params_from_args(args)


def source_from_args(args):
    """The rig of ``--rig``, else the beam of the beam options (what :func:`~hubbeam_ctrl.fmu.build_fmu`
    and the limit take as ``rig_or_params``).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    """
    rig = rig_from_args(args)
    return rig if rig is not None else params_from_args(args)


def design_task(args, rig, params):
    """The task and the design model of ``hubbeam design`` and ``hubbeam codegen``
    (:func:`~hubbeam_ctrl.study.design_task.task_and_design` of the options :func:`add_task_options` adds;
    a ``--dt`` other than the rig's is refused).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    rig : Rig or None
        The rig of ``--rig`` (:func:`rig_from_args`).
    params : Params
        The design's beam (the rig's ``plant_params`` with a rig).

    Returns
    -------
    scenario : hubbeam_ctrl.study.scenarios.Scenario
    design : controllers.DesignModel
    """
    from hubbeam_ctrl.study.design_task import task_and_design
    check_rig_dt(args, rig)
    return task_and_design(params, args.scenario, rig=rig, tau_max=args.tau_max, dt=args.dt,
                           design_modes=args.design_modes, slew_angle=args.slew_angle, t_f=args.tf, w_f=args.wf)
