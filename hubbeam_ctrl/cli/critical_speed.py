"""``hubbeam critical-speed``: the spin rate at which a model's bending stiffness is lost
(:func:`hubbeam_ctrl.plant.modal.critical_speed`)."""

from __future__ import annotations

import sys

from hubbeam_ctrl.cli.args import Command, add_verbose, params_from_args, stdout
from hubbeam_ctrl.core.jsonio import strict_json
from hubbeam_ctrl.plant.models import MODEL_SPECS

__all__ = ["CRITICAL_SPEED_MODELS"]

#: Models whose bending stiffness is quadratic in the spin (``critical-speed`` needs it; CFOAM's
#: complete foreshortening is not).
CRITICAL_SPEED_MODELS = tuple(n for n, spec in MODEL_SPECS.items() if spec.foreshortening != "complete")


def _options(p) -> None:
    """``hubbeam critical-speed``'s options on its parser ``p``."""
    p.add_argument("--model", choices=CRITICAL_SPEED_MODELS, default="tlam")
    p.add_argument("--json", action="store_true", help="print JSON")
    add_verbose(p)


def _run(args) -> int:
    """The critical speed, or that there is none (status 0)."""
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


COMMAND = Command("critical-speed", _options, _run, help="spin rate at which the bending stiffness is lost",
                  description="Critical speed of TLAM (or FOAM, which has none).")
