"""``hubbeam excite``: an excitation record for a calibration, within the drive's and the user's limits.

Example::

    hubbeam excite --rig servo_link --kind chirp --duration 10 --max-tip 0.02 --out chirp.csv
"""

from __future__ import annotations

from hubbeam_ctrl.cli.args import Command

__all__ = ["KINDS"]

#: The signal kinds, as ``hubbeam_ctrl.calibrate.excitation.EXCITATION_KINDS`` (not imported here:
#: building the parser stays cheap).
KINDS = ("chirp", "prbs", "multisine", "step")


def _options(p) -> None:
    """``hubbeam excite``'s options on its parser ``p``."""
    from hubbeam_ctrl.cli.args import add_rig_option, add_verbose, integer, nonempty, real

    add_rig_option(p, "rig TOML file or preset (servo_link, paper)", required=True)
    p.add_argument("--kind", choices=KINDS, required=True)
    p.add_argument("--out", metavar="SIGNAL.csv|SIGNAL.npz", type=nonempty("file"), required=True)
    p.add_argument("--duration", metavar="S", type=real("s"), default=10.0, help="record length [s] (default 10)")
    p.add_argument("--dt", metavar="S", type=real("s"), help="sample period [s] (default the rig's, else 1 ms)")
    p.add_argument("--amplitude", metavar="V_OR_NM", type=real("V or N m"),
                   help="largest command (default the drive's limit)")
    p.add_argument("--band", metavar="LO:HI", help="band [Hz] (default 0.2 f1 : 1.5 f_n)")
    p.add_argument("--modes", metavar="N", type=integer(),
                   help="modes to identify, which set the default band (default 2, or 1 when the second is past "
                        "the Nyquist frequency; not with --kind step)")
    p.add_argument("--max-tip", metavar="M", type=real("m"), help="largest predicted tip deflection [m] "
                   "(default 0.05 L)")
    p.add_argument("--max-hub", metavar="RAD", type=real("rad"), help="largest predicted hub travel [rad] "
                   "(default pi)")
    p.add_argument("--seed", metavar="N", type=integer(), help="PRBS seed (default 0; --kind prbs only)")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    add_verbose(p)


def _parse_band(text, option="--band"):
    """``"LO:HI"`` -> ``(lo, hi)`` [Hz], or None."""
    from hubbeam_ctrl.core.errors import ParameterError
    if text is None:
        return None
    try:
        lo, hi = (float(x) for x in str(text).split(":"))
    except ValueError:
        raise ParameterError(f"{option} must be LO:HI in Hz, got {text!r}") from None
    if not lo < hi:
        raise ParameterError(f"{option} must have lo < hi, got lo = {lo:g} > hi = {hi:g}")
    return lo, hi


def _run(args) -> int:
    """Write the record and print its summary."""
    from hubbeam_ctrl.calibrate.excitation import excitation
    from hubbeam_ctrl.calibrate.records import save_record
    from hubbeam_ctrl.cli.args import check_output, print_result, refuse_inapplicable
    from hubbeam_ctrl.plant.rig import load_rig

    refuse_inapplicable(args, f"--kind {args.kind}", {"--band": ("chirp", "prbs", "multisine"),
                                                        "--modes": ("chirp", "prbs", "multisine"), "--seed": ("prbs",)})
    check_output("--out", args.out, (".csv", ".npz"))
    rig = load_rig(args.rig)
    rec = excitation(rig, args.kind, args.duration, dt=args.dt, amplitude=args.amplitude,
                     band_hz=_parse_band(args.band), n_modes=args.modes,
                     max_tip_deflection=args.max_tip,
                     max_hub_travel=args.max_hub, seed=0 if args.seed is None else args.seed)
    signal = type(rec)(t=rec.t, columns={rec.input_name: rec.input}, source=rec.source)
    save_record(signal, args.out)
    import numpy as np
    summary = {"out": str(args.out), "kind": args.kind, "input": rec.input_name, "samples": len(rec.t),
               "duration_s": rec.duration, "peak_input": float(np.max(np.abs(rec.input))),
               "predicted_peak_tip_m": float(np.max(np.abs(rec.columns["v_tip"]))),
               "predicted_peak_hub_rad": float(np.max(np.abs(rec.columns["theta"])))}
    tip, hub = summary["predicted_peak_tip_m"], summary["predicted_peak_hub_rad"]
    summary["band"] = rec.source
    print_result(args, summary, f"wrote {args.out}: {rec.source}, {len(rec.t)} samples, peak {rec.input_name} "
                                f"{summary['peak_input']:.4g}; predicted peak tip {tip:.4g} m, hub {hub:.4g} rad")
    return 0


COMMAND = Command(
    "excite", _options, _run, beam=False, help="an input record for identification (chirp, PRBS, multisine, step)",
    description=("Writes an input record (t [s] and V [V] for a DC-motor rig, tau [N m] for a torque drive) whose "
                 "band runs from 0.2 x the first to 1.5 x the highest mode to identify, whose amplitude is within "
                 "the drive's limit and whose predicted tip deflection and hub travel (simulated on the rig's model) "
                 "stay within --max-tip and --max-hub."))
