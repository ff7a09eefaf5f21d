"""``hubbeam modes``: the natural frequencies of a model linearised about steady rotation, each with
its estimated error (:func:`hubbeam_ctrl.plant.convergence.converged_modes`)."""

from __future__ import annotations

from hubbeam_ctrl.cli.args import (
    UNSTABLE_NOTE,
    Command,
    add_verbose,
    integer,
    params_from_args,
    real,
    stdout,
)
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.jsonio import strict_json
from hubbeam_ctrl.plant.convergence import CLI_ASSUMED_MODES
from hubbeam_ctrl.plant.models import MODEL_SPECS
from hubbeam_ctrl.plant.params import MAX_MODES

__all__ = []


def _options(p) -> None:
    """``hubbeam modes``'s options on its parser ``p``."""
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


def _run(args) -> int:
    """The frequencies and their estimated errors (status 0)."""
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


COMMAND = Command(
    "modes", _options, _run, help="natural frequencies at a spin rate",
    description=("Bending (and axial) natural frequencies of a model linearised about steady rotation: the first "
                 "--n-modes (default 5) of each family, from a model with --assumed-modes modes (default 16), each "
                 "with its estimated error."))
