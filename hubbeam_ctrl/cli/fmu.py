"""``hubbeam fmu``: the nonlinear plant with the rig's hardware as an FMI 2.0 co-simulation FMU.

Example::

    hubbeam fmu --rig servo_link --model foam --n-modes 3 --out plant.fmu
"""

from __future__ import annotations

from hubbeam_ctrl.cli.args import Command

__all__ = []


def _options(p) -> None:
    """``hubbeam fmu``'s options on its parser ``p``."""
    from hubbeam_ctrl.cli.args import add_rig_option, add_verbose, integer, real

    add_rig_option(p, "rig file or preset (servo_link, paper); not with --params")
    p.add_argument("--model", choices=["foam", "cfoam"], default="foam", help="plant model (default foam)")
    p.add_argument("--dt", metavar="S", type=real("s"),
                   help="sample time [s]: each communication step is a whole number of samples "
                        "(default: the rig's timing.dt, else 0.01)")
    p.add_argument("--substeps", metavar="K", type=integer(),
                   help="integration steps per sample, 1..200 (default: the closed loop's substep rule)")
    p.add_argument("--spin", metavar="RAD_S", type=real("rad/s"),
                   help="spin rate of the modal analysis behind the substep rule [rad/s] (default 0, a slew; "
                        "not with --substeps)")
    p.add_argument("--certificate", metavar="CERT.json",
                   help="a robust certificate over the rig's [uncertainty] set (hubbeam certify CONTROLLER --rig RIG "
                        "--json): its verdict, worst radius and worst plant go into the model description "
                        "(VendorAnnotations and description); one over another set is refused")
    p.add_argument("--out", metavar="FILE.fmu", required=True, help="the FMU to write")
    p.add_argument("--force", action="store_true", help="replace an existing FILE.fmu")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    add_verbose(p)


def _plan(args) -> dict:
    """The keywords of :func:`~hubbeam_ctrl.fmu.build_fmu`."""
    from hubbeam_ctrl.cli.args import source_from_args
    from hubbeam_ctrl.core.errors import ParameterError

    source = source_from_args(args)
    if not str(args.out).endswith(".fmu"):
        raise ParameterError(f"--out must name a .fmu file, got {str(args.out)[:80]!r}")
    if args.spin is not None and args.substeps is not None:
        raise ParameterError("--spin does not apply with --substeps (the spin sets the substep rule's modal "
                             "analysis only)")
    certificate = None
    if args.certificate is not None:
        from hubbeam_ctrl.plant.rig import Rig
        from hubbeam_ctrl.plant.robust_certificate import Certificate
        from hubbeam_ctrl.plant.uncertainty import Uncertainty
        certificate = Certificate.read(args.certificate, "--certificate")
        certificate.check(source.uncertainty if isinstance(source, Rig) else Uncertainty(), "--certificate")
    return {"rig_or_params": source, "model": args.model, "out": args.out, "dt": args.dt, "substeps": args.substeps,
            "spin": 0.0 if args.spin is None else args.spin, "force": args.force, "certificate": certificate}


def _run(args) -> int:
    """Build the FMU and print its summary."""
    import sys

    from hubbeam_ctrl.cli.args import print_result
    from hubbeam_ctrl.fmu import build_fmu

    info = build_fmu(**_plan(args))
    summary = {"out": str(info.path), "fmi_version": info.fmi_version, "model": info.model, "n_q": info.n_q,
               "dt_s": info.dt, "substeps": info.substeps, "command": info.command, "outputs": list(info.outputs),
               "parameters": len(info.parameters), "binary": info.binary, "build_s": round(info.build_s, 3),
               "parameters_with_set_range": len(info.ranges),
               "certificate": None if info.certificate is None else
               {name: {"robust_verdict": c.get("robust_verdict"), "robust_radius": c.get("robust_radius")}
                for name, c in info.certificate.controllers}}
    text = (f"wrote {info.path}: FMI {info.fmi_version} co-simulation, {info.model.upper()} with {info.n_q} "
            f"coordinates, input {info.command}, dt = {info.dt:g} s x {info.substeps} steps, "
            f"{len(info.parameters)} parameters")
    if info.ranges:
        text += f" ({len(info.ranges)} with the [uncertainty] set's range as min/max)"
    if info.certificate is not None:
        text += "; certificate: " + ", ".join(f"{n} {str(c.get('robust_verdict')).upper()}"
                                              for n, c in info.certificate.controllers)
    print_result(args, summary, text)
    if info.binary is None and not args.json:
        print("note: no binary in the FMU (no C compiler); it holds the sources", file=sys.stderr)
    return 0


COMMAND = Command(
    "fmu", _options, _run, plan=_plan, help="the nonlinear plant as an FMI 2.0 co-simulation FMU",
    description=("Write the FOAM or CFOAM plant with the rig's drive, friction and sensors as an FMI 2.0 "
                 "co-simulation FMU (generated C, the closed loop's fixed-step integrator; no Python at run time). "
                 "Input: torque [N m] or, with a DC motor, voltage [V]; outputs: the sensors and the tip "
                 "deflection. Needs FMPy (the FMI headers) and a C compiler for the binary (without one: the "
                 "sources only). See docs/fmu.md."))
