"""``hubbeam linearize``: a linear state-space model about steady spin, saved to a file.

Example::

    hubbeam linearize --model sfoam --spin 0 --n-modes 4 \\
        --outputs theta,tip_deflection,root_moment --dt 0.01 --out plant.mat --json
"""

from __future__ import annotations

import argparse
import sys

from hubbeam_ctrl.cli.args import UNSTABLE_NOTE, Command

__all__ = ["UNSTABLE_NOTE"]      # UNSTABLE_NOTE: re-exported (its old home)


class _OutputsHelpFormatter(argparse.HelpFormatter):
    """Fills ``{outputs}`` and ``{default}`` in the help from :mod:`hubbeam_ctrl.linear.statespace`
    only when the help is printed, so that building the parser does not import python-control."""

    def _get_help_string(self, action):
        text = super()._get_help_string(action)
        if "{outputs}" in text:
            from hubbeam_ctrl.linear.statespace import DEFAULT_OUTPUTS, OUTPUTS
            text = text.format(outputs=",".join(OUTPUTS), default=",".join(DEFAULT_OUTPUTS))
        return text


def _options(p) -> None:
    """``hubbeam linearize``'s options on its parser ``p``."""
    from hubbeam_ctrl.cli.args import add_verbose, real
    from hubbeam_ctrl.plant.models import MODEL_SPECS

    p.add_argument("--model", choices=list(MODEL_SPECS), default="sfoam",
                   help="source model (default sfoam, the design model)")
    p.add_argument("--spin", metavar="RAD_S", type=real("rad/s"), default=0.0,
                   help="steady spin rate Omega [rad/s] (default 0, the slew design point)")
    p.add_argument("--outputs", metavar="NAMES",
                   help="comma-separated outputs among {outputs} (default {default})")
    p.add_argument("--dt", metavar="S", type=real("s"),
                   help="sample time [s]: discretise with a zero-order hold (default: continuous)")
    p.add_argument("--damping", metavar="ZETA", type=real("-"),
                   help="modal damping ratio of the clamped modes, 0 <= ZETA < 1 (default 0)")
    p.add_argument("--out", metavar="FILE.mat|FILE.npz|FILE.json", required=True,
                   help="output file; the format follows the extension")
    p.add_argument("--json", action="store_true",
                   help='print {"model", "spin_rad_s", "n_states", "poles_hz", "unstable", "out"} as JSON')
    add_verbose(p)


def _run(args) -> int:
    """Linearise the model, save it and print its poles."""
    from hubbeam_ctrl.cli.args import check_output, params_from_args, print_result
    from hubbeam_ctrl.core.validation import check_in_range
    from hubbeam_ctrl.linear.export import FORMATS, save_model
    from hubbeam_ctrl.linear.statespace import DT_RANGE, linearize
    from hubbeam_ctrl.linear.transforms import discretize

    out = check_output("--out", args.out, FORMATS)
    if args.dt is not None:
        check_in_range("dt", args.dt, "s", *DT_RANGE)
    params = params_from_args(args)
    if args.damping is not None:
        params = params.replace(damping_ratio=args.damping)
    outputs = {} if args.outputs is None else {"outputs": args.outputs}
    lm = linearize(args.model, args.spin, params, **outputs)
    if args.dt is not None:
        lm = discretize(lm, args.dt)
    save_model(lm, out)
    poles = [float(f) for f in lm.poles_hz()]
    note = UNSTABLE_NOTE if lm.unstable else ""
    kind = f"sampled at dt = {lm.dt:g} s (zero-order hold)" if lm.is_discrete else "continuous"
    text = [f"{lm.model.upper()} linearised at spin {lm.spin:g} rad/s: {lm.n_states} states, input tau, outputs "
            f"{', '.join(lm.output_names)}; {kind}{note}",
            "  oscillatory poles [Hz]: " + ", ".join(f"{f:.4f}" for f in poles),
            f"  saved to {out}" + (" (marked unstable)" if note else "")]
    print_result(args, {"model": lm.model, "spin_rad_s": lm.spin, "n_states": lm.n_states, "poles_hz": poles,
                        "unstable": lm.unstable, "out": str(out)}, "\n".join(text))
    if note:
        print(f"warning: {lm.model.upper()} at {lm.spin:g} rad/s{note}", file=sys.stderr)
    return 0


COMMAND = Command(
    "linearize", _options, _run, formatter_class=_OutputsHelpFormatter,
    help="linear state-space model about steady spin (.mat/.npz/.json)",
    description=("Linearise a model about steady rotation at --spin with the hub free (input: hub torque tau [N m]) "
                 "and save A, B, C, D with the state, input and output names, the sample time and every parameter. "
                 "States: theta [rad], q1_i, q2_i [m] (modal coordinates; q2 is half the mode's tip deflection), and "
                 "their rates. --n-modes sets the axial and the transverse mode count."))
