"""``hubbeam optimal``: the time-optimal (or, with ``--duration``, minimum-vibration) slew.

Example::

    hubbeam optimal --slew-angle 1 --json
    hubbeam optimal --params arm.toml --slew-angle 1.5708 --tolerance 1e-3 --duration 1.2
"""

from __future__ import annotations

from hubbeam_ctrl.cli.args import Command

__all__ = []


def _options(p) -> None:
    """``hubbeam optimal``'s options on its parser ``p``."""
    from hubbeam_ctrl.cli.args import add_rig_option, add_verbose, integer, real

    p.add_argument("--slew-angle", metavar="RAD", type=real("rad"), required=True, help="slew angle [rad], not 0")
    add_rig_option(p, "a rig file or preset (servo_link, paper): its beam, and with a DC motor the voltage limit "
                      "through back-EMF, the current limit and the friction the drive must overcome; not with "
                      "--params")
    p.add_argument("--tolerance", metavar="M", type=real("m"),
                   help="allowed residual tip vibration [m], > 0 (default 1e-3 L)")
    p.add_argument("--duration", metavar="S", type=real("s"),
                   help="slew time [s]: minimum residual vibration in that time instead of minimum time")
    p.add_argument("--intervals", metavar="N", type=integer(), help="collocation intervals (default 40)")
    p.add_argument("--no-check", action="store_true", help="skip the check on the evaluation plant")
    p.add_argument("--json", action="store_true",
                   help="print the summary as JSON (duration_s, rigid_bound_s, residuals, converged, ...)")
    add_verbose(p)


def _run(args) -> int:
    """Solve the slew and print its summary; 1 when IPOPT did not converge."""
    from hubbeam_ctrl.cli.args import stdout
    from hubbeam_ctrl.core.jsonio import strict_json
    from hubbeam_ctrl.limit import min_vibration_slew, time_optimal_slew

    sink = stdout(args)
    plan = _plan(args)
    source, angle, tolerance, settings = (plan[k] for k in ("source", "slew_angle", "tolerance", "settings"))
    rig = source if plan["rig"] else None
    params = source.plant_params if rig is not None else source
    if args.duration is None:
        r = time_optimal_slew(source, angle, tolerance=tolerance, settings=settings, progress=not args.json)
    else:
        r = min_vibration_slew(source, angle, args.duration, tolerance=tolerance, settings=settings,
                               name="--duration", progress=not args.json)
    if args.json:
        print(strict_json(r.to_dict()), file=sink)
        return _not_converged(r) or _check_failed(r)
    plant = (f"{r.residual_plant:.4g} m on the evaluation plant ({r.plant})" if r.residual_plant is not None
             else r.plant if "FAILED" in r.plant else "not checked on an evaluation plant")
    drive = (" within the DC drive's voltage (back-EMF), current and friction" if rig is not None
             and not rig.drive.is_ideal else "")
    print(f"{r.kind} slew by {r.slew_angle:g} rad with tau_max = {params.tau_max:g} N m{drive}: "
          f"{r.duration_s:.4f} s = {r.ratio:.4f} x the rigid bang-bang bound {r.rigid_bound_s:.4f} s", file=sink)
    print(f"  residual tip vibration {r.residual_design:.4g} m on the design model ({r.design}); {plant}; "
          f"tolerance {r.tolerance:.4g} m", file=sink)
    state = "converged" if r.converged else "DID NOT CONVERGE"
    print(f"  IPOPT {state} ({r.message}) in {r.iterations} iterations, {r.solve_s:.1f} s", file=sink)
    return _not_converged(r) or _check_failed(r)


def _check_failed(r) -> int:
    """0, or 1 with one line on stderr when the slew's check on the evaluation plant failed to integrate
    (the slew is printed: it is the design model's; the plant could not confirm it)."""
    if "FAILED" not in r.plant:
        return 0
    import sys
    print(f"hubbeam: error: optimal: {r.plant}", file=sys.stderr)
    return 1


def _plan(args) -> dict:
    """``source`` (Params or Rig), ``rig`` (bool), ``slew_angle`` [rad], ``tolerance`` [m] (None: the default),
    ``duration`` [s] (None: time-optimal), ``settings`` (OptimalSettings), ``json``."""
    from hubbeam_ctrl.cli.args import source_from_args
    from hubbeam_ctrl.core.validation import check_finite, check_positive
    from hubbeam_ctrl.limit import OptimalSettings

    angle = check_finite("--slew-angle", args.slew_angle, "rad")
    tolerance = None if args.tolerance is None else check_positive("--tolerance", args.tolerance, "m")
    if args.duration is not None:
        check_positive("--duration", args.duration, "s")
    source = source_from_args(args)
    changes = {"check": not args.no_check}
    if args.intervals is not None:
        changes["intervals"] = args.intervals
    return {"source": source, "rig": args.rig is not None,
            "slew_angle": angle, "tolerance": tolerance, "duration": args.duration,
            "settings": OptimalSettings(**changes), "json": args.json}


def _not_converged(r) -> int:
    """0, or 1 with one line on stderr when IPOPT stopped before converging (the duration printed is
    then not the optimum: issue 36)."""
    if r.converged:
        return 0
    import sys
    status = r.message.split(";")[0]
    print(f"hubbeam: error: optimal: IPOPT did not converge ({status} after {r.iterations} iterations): "
          f"{r.duration_s:.4g} s is its last iterate, not the {r.kind} slew's duration", file=sys.stderr)
    return 1


COMMAND = Command(
    "optimal", _options, _run, plan=_plan, help="time-optimal rest-to-rest slew: the limit of the beam and drive",
    description=("The minimum-time rest-to-rest slew by --slew-angle within |tau| <= tau_max that ends with "
                 "residual tip vibration <= --tolerance, computed on FOAM (axial coordinates condensed) by Radau "
                 "collocation with IPOPT and checked on an evaluation plant with 3 more bending modes. With "
                 "--duration: the slew in that time with the smallest residual vibration. Prints the duration, "
                 "the rigid bang-bang bound 2 sqrt(Theta J / tau_max) (on a rig's DC drive: the bang-bang within "
                 "its voltage limit through back-EMF, current limit and friction) and the residuals. Exits 1 with "
                 "one line if IPOPT does not converge."))
