"""Command-line interface: ``hubbeam modes | critical-speed | simulate | linearize | compare | design``.

Every subcommand accepts the common options ``--tip-mass KG``, ``--tip-position M``,
``--n-modes N`` (both families) and ``--params FILE.toml``. Bad input prints one line on
stderr naming the parameter and exits with status 2, without a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import json
import math
import sys
from collections.abc import Sequence

from hubbeam_ctrl.core.errors import HubbeamError, ParameterError
from hubbeam_ctrl.plant.models import MODEL_SPECS
from hubbeam_ctrl.plant.params import Params, load_params

__all__ = ["main", "params_from_args", "build_parser", "positive_float", "positive_int", "finite_float",
           "RegistryChoices"]

#: Models whose bending stiffness is quadratic in the spin (``critical-speed`` needs it; CFOAM's
#: complete foreshortening is not).
CRITICAL_SPEED_MODELS = tuple(n for n, spec in MODEL_SPECS.items() if spec.foreshortening != "complete")

#: Subcommands contributed by other modules: module name -> provides add_parser/run.
EXTRA_COMMANDS = ("hubbeam_ctrl.cli.linearize", "hubbeam_ctrl.cli.compare", "hubbeam_ctrl.cli.design",
                  "hubbeam_ctrl.cli.sweep", "hubbeam_ctrl.cli.tune")


class _Parser(argparse.ArgumentParser):
    """argparse that raises instead of printing usage, so errors are one line."""

    def error(self, message):
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
    g.add_argument("--params", metavar="FILE.toml", help="TOML file with Params fields (SI units)")
    g.add_argument("--tip-mass", metavar="KG", type=float, help="tip mass m_t [kg], >= 0")
    g.add_argument("--tip-position", metavar="M", type=float,
                   help="tip-mass position l along the beam [m], 0..L (default L)")
    g.add_argument("--n-modes", metavar="N", type=int,
                   help="number of axial and of transverse modes, 1..20 (default 5)")
    return common


def params_from_args(args) -> Params:
    """Build :class:`Params` from the common options (file first, then flags)."""
    base = load_params(args.params) if getattr(args, "params", None) else Params()
    changes = {}
    if getattr(args, "tip_mass", None) is not None:
        changes["m_t"] = args.tip_mass
    if getattr(args, "tip_position", None) is not None:
        changes["l"] = args.tip_position
    if getattr(args, "n_modes", None) is not None:
        changes["n_axial"] = changes["n_transverse"] = args.n_modes
    return base.replace(**changes) if changes else base


def positive_float(name):
    """argparse type: a finite number > 0, errors naming ``name``."""
    def parse(text):
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None
        if not (math.isfinite(value) and value > 0):
            raise argparse.ArgumentTypeError(f"{name} must be a finite number > 0, got {text}")
        return value
    return parse


def positive_int(name):
    """argparse type: an integer > 0, errors naming ``name``."""
    def parse(text):
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be an integer, got {text!r}") from None
        if value <= 0:
            raise argparse.ArgumentTypeError(f"{name} must be an integer > 0, got {text}")
        return value
    return parse


def finite_float(name):
    """argparse type: a finite number, errors naming ``name``."""
    def parse(text):
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"{name} must be finite, got {text}")
        return value
    return parse


def check_output_folder(option: str, path) -> None:
    """Raise :class:`ParameterError` unless the folder of ``path`` exists and is writable."""
    import os
    from pathlib import Path
    folder = Path(path).parent
    if not folder.is_dir():
        raise ParameterError(f"{option}: folder {folder} does not exist")
    if not os.access(folder, os.W_OK):
        raise ParameterError(f"{option}: folder {folder} is not writable")


# -- modes ----------------------------------------------------------------------
def _cmd_modes(args) -> int:
    from hubbeam_ctrl.plant.modal import modal_analysis
    params = params_from_args(args)
    res = modal_analysis(args.model, args.spin, args.hub, params)
    out = {"model": args.model, "spin_rad_s": args.spin, "hub": args.hub,
           "frequencies_hz": [float(f) for f in res.bending_hz],
           "axial_frequencies_hz": [float(f) for f in res.axial_hz],
           "unstable": res.unstable}
    if args.json:
        print(json.dumps(out))
    else:
        print(f"{args.model.upper()} at {args.spin:g} rad/s, hub {args.hub}"
              + (" (UNSTABLE: a mode has lost its stiffness)" if res.unstable else ""))
        for i, f in enumerate(res.bending_hz, 1):
            print(f"  bending mode {i}: {f:10.4f} Hz")
        for i, f in enumerate(res.axial_hz, 1):
            print(f"  axial mode {i}:   {f:10.2f} Hz")
    return 0


# -- critical speed ---------------------------------------------------------------
def _cmd_critical(args) -> int:
    from hubbeam_ctrl.plant.modal import critical_speed
    params = params_from_args(args)
    w = critical_speed(args.model, params)
    if args.json:
        print(json.dumps({"model": args.model, "critical_speed_rad_s": w}))
    if w is None:
        print(f"{args.model.upper()} keeps positive bending stiffness at every spin rate up to "
              "1000 rad/s: no critical speed", file=sys.stderr if args.json else sys.stdout)
    elif not args.json:
        print(f"{args.model.upper()} critical speed: {w:.4f} rad/s "
              f"(m_t = {params.m_t:g} kg at l = {params.tip_position:g} m)")
    return 0


# -- simulate -----------------------------------------------------------------------
def _cmd_simulate(args) -> int:
    from hubbeam_ctrl.plant.maneuvers import SpinUp, TorquePulse
    from hubbeam_ctrl.sim.simulate import simulate
    params = params_from_args(args)
    if args.out and not args.out.lower().endswith((".csv", ".npz")):
        raise ParameterError(f"out must end in .csv or .npz, got {args.out!r}")
    if args.plot and not args.plot.lower().endswith(".png"):
        raise ParameterError(f"plot must end in .png, got {args.plot!r}")
    for option, path in (("out", args.out), ("plot", args.plot)):
        if path:
            check_output_folder(option, path)
    if args.maneuver == "spinup":
        maneuver = SpinUp(args.wf if args.wf is not None else 3.0, args.tf if args.tf is not None else 30.0)
    else:
        maneuver = TorquePulse(args.tau_max if args.tau_max is not None else 200.0,
                               args.tf if args.tf is not None else 10.0)
    res = simulate(args.model, maneuver, args.t_end, params=params, progress=not args.json,
                   range_limit=args.range_limit)
    if args.out:
        res.save(args.out)
    if args.plot:
        from hubbeam_ctrl.plots.plant import plot_result, save_figure
        save_figure(plot_result(res), args.plot)
    s = res.summary()
    out = {k: s[k] for k in ("peak_tip_m", "residual_tip_m", "peak_axial_m", "final_theta_rad",
                             "final_theta_dot_rad_s", "diverged", "wall_s")}
    if args.json:
        print(json.dumps(out))
    else:
        for k, v in out.items():
            print(f"{k:>22}: {v}")
        print(f"{'message':>22}: {res.message}")
    if res.diverged or res.outside_validated_range:
        print(f"warning: {res.message}", file=sys.stderr)
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The ``hubbeam`` argument parser (with the subcommands of other modules)."""
    common = _common_parser()
    parser = _Parser(prog="hubbeam", description=(
        "Rotating hub-beam toolbox: nonlinear models with dynamic stiffening (CFOAM, FOAM, "
        "TLAM, SFOAM), modal analysis, simulation, linear models and controllers."))
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    p = sub.add_parser("modes", parents=[common], help="natural frequencies at a spin rate",
                       description="Bending (and axial) natural frequencies of a model linearised "
                                   "about steady rotation.")
    p.add_argument("--model", choices=list(MODEL_SPECS), default="foam")
    p.add_argument("--spin", metavar="RAD_S", type=finite_float("spin"), default=0.0,
                   help="spin rate [rad/s] (default 0)")
    p.add_argument("--hub", choices=["prescribed", "free"], default="prescribed",
                   help="prescribed: clamped root turning at --spin (Table 2); free: hub free")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=_cmd_modes)

    p = sub.add_parser("critical-speed", parents=[common],
                       help="spin rate at which the bending stiffness is lost",
                       description="Critical speed of TLAM (or FOAM, which has none).")
    p.add_argument("--model", choices=CRITICAL_SPEED_MODELS, default="tlam")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=_cmd_critical)

    p = sub.add_parser("simulate", parents=[common], help="simulate a maneuver",
                       description="Simulate the Eq. 43 spin-up (prescribed hub) or the Eq. 44 "
                                   "torque pulse (free hub).")
    p.add_argument("--model", choices=list(MODEL_SPECS), required=True)
    p.add_argument("--maneuver", choices=["spinup", "torque"], required=True)
    p.add_argument("--wf", metavar="RAD_S", type=finite_float("wf"), help="spin-up final rate [rad/s] (default 3)")
    p.add_argument("--tf", metavar="S", type=positive_float("tf"),
                   help="maneuver time [s] (default 30 for spinup, 10 for torque)")
    p.add_argument("--tau-max", metavar="NM", type=positive_float("tau-max"),
                   help="torque amplitude [N m], > 0 (default 200)")
    p.add_argument("--t-end", metavar="S", type=positive_float("t-end"), required=True, help="final time [s]")
    p.add_argument("--out", metavar="FILE.csv|FILE.npz", help="save the time series")
    p.add_argument("--plot", metavar="FILE.png", help="save a plot")
    p.add_argument("--range-limit", metavar="FRACTION", type=positive_float("range-limit"), default=0.3,
                   help="flag the run when |v_tip| passes FRACTION * L (the models' validated range; "
                        "default 0.3); only L stops it")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.set_defaults(func=_cmd_simulate)

    for name in EXTRA_COMMANDS:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name != name:
                raise
            continue
        module.add_parser(sub, common)
    return parser


def main(argv=None) -> int:
    """Entry point of the ``hubbeam`` console script. Returns the exit status."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        if not getattr(args, "command", None):
            parser.print_help()
            return 2
        func = getattr(args, "func", None)
        if func is None:
            module = importlib.import_module(f"hubbeam_ctrl.cli.{args.command}")
            func = module.run
        return int(func(args) or 0)
    except (ParameterError, HubbeamError) as exc:
        print(f"hubbeam: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("hubbeam: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
