"""Command-line interface: ``hubbeam COMMAND``, each command's ``COMMAND`` in its module
(:data:`EXTRA_COMMANDS`, :class:`hubbeam_ctrl.cli.args.Command`).

The commands of a beam accept the common options ``--tip-mass KG``, ``--tip-position M``,
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
    check_output,
    integer,
    nonempty,
    params_from_args,
    real,
    rename_options,
)
from hubbeam_ctrl.core.errors import RESOURCE_ERRNOS, HubbeamError, ParameterError, ResourceError
from hubbeam_ctrl.core.native import capture_native_output

__all__ = ["main", "params_from_args", "build_parser", "positive_float", "positive_int", "finite_float",
           "RegistryChoices", "add_backend_option"]

#: Subcommands contributed by other modules, each holding its ``COMMAND`` (:class:`~hubbeam_ctrl.cli.args.Command`).
EXTRA_COMMANDS = ("hubbeam_ctrl.cli.modes", "hubbeam_ctrl.cli.critical_speed", "hubbeam_ctrl.cli.simulate",
                  "hubbeam_ctrl.cli.linearize", "hubbeam_ctrl.cli.compare", "hubbeam_ctrl.cli.design",
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


def build_parser() -> argparse.ArgumentParser:
    """The ``hubbeam`` argument parser (with the subcommands of other modules)."""
    common = _common_parser()
    parser = _Parser(prog="hubbeam", description=(
        "Rotating hub-beam toolbox: nonlinear models with dynamic stiffening (CFOAM, FOAM, "
        "TLAM, SFOAM), modal analysis, simulation, linear models and controllers."))
    parser.add_argument("--version", action="version", version=f"%(prog)s {sys.modules['hubbeam_ctrl'].__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

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
