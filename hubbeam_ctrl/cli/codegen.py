"""``hubbeam codegen``: design a controller for a task and write it as portable C99.

Example::

    hubbeam codegen --controller lqg --rig rig.toml --slew-angle 1.0 --tf 8 --out lqg_c

The controller is designed like ``hubbeam design`` does (the task's scaled defaults,
:mod:`controllers.scaling`) and written by :func:`hubbeam_ctrl.deploy.to_c` into ``--out``:
``<kind>.h``, ``<kind>.c`` and ``<kind>.json`` (the sensors and units it reads). With a C
compiler the sources are compiled once with ``-std=c99 -Wall -Wextra -pedantic -Werror``
before the folder is put in place (a failed build leaves nothing); without one the sources
are written and one line says that the software-in-the-loop check needs one.
"""

from __future__ import annotations

import json

from hubbeam_ctrl.cli.args import Command

__all__ = []


def _options(p) -> None:
    """``hubbeam codegen``'s options on its parser ``p``."""
    from hubbeam_ctrl.cli.args import add_rig_option, add_task_options, add_verbose
    from hubbeam_ctrl.cli.main import positive_int

    p.add_argument("--controller", required=True, metavar="KIND",
                   help="controller kind: pd, lqr, lqg, zv, zvd, ei, mpc, msmpc, hinf, nmpc (nmpc: its real-time "
                        "iteration step, hubbeam_ctrl.deploy.nmpc_c)")
    p.add_argument("--payload-range", metavar="MIN,MAX",
                   help="tip payloads [kg] a robust design covers (msmpc: one scenario each at MIN, the nominal tip "
                        "mass and MAX; hinf: the spread weight of those plants); must hold the tip mass")
    add_rig_option(p, "rig file or preset: the beam (with the reflected rotor), its sensors and its sample time")
    add_task_options(p, "the rig's timing.dt, else 20 samples per period of the first flexible mode, at most 0.01")
    p.add_argument("--schedule", metavar="N", type=positive_int("schedule"), default=1,
                   help="lqg only: the gain-scheduled LQG designed at N spin rates from 0 to the top reference "
                        "rate, interpolated on the measured rate (default 1: one design point)")
    p.add_argument("--precision", choices=["double", "single"], default="double",
                   help="type of the data and the arithmetic (default double)")
    p.add_argument("--out", metavar="DIR", required=True, help="output folder (created; must be empty)")
    p.add_argument("--force", action="store_true", help="write into a non-empty --out")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    add_verbose(p)


def _run(args) -> int:
    """Design the controller for the task and write it as C."""
    import sys

    from controllers import CONTROLLERS, make_controller
    from hubbeam_ctrl.cli.args import beam_from_args, check_output_dir, design_task, refuse_inapplicable, stdout
    from hubbeam_ctrl.core.errors import ParameterError
    from hubbeam_ctrl.deploy import CODEGEN_KINDS, NO_COMPILER, compile_c, compiler, to_c
    from hubbeam_ctrl.study.shaping import task_shaped_settings

    sink = stdout(args)
    check_output_dir("--out", args.out)
    kinds = [k for k in CODEGEN_KINDS if k != "openloop"] + ["nmpc"]
    if args.controller not in kinds:
        raise ParameterError(f"controller must be one of {', '.join(kinds)} (the kinds that can be generated "
                             f"as C), got {args.controller!r}")
    refuse_inapplicable(args, f"--scenario {args.scenario}", {"--wf": ("spinup",), "--slew-angle": ("slew",)})
    rig, params = beam_from_args(args)
    if rig is not None and args.controller not in ("pd", "lqr", "lqg", "mpc", "nmpc") and not rig.drive.is_ideal:
        raise ParameterError(f"--controller {args.controller} does not apply with --rig {args.rig} (its DC motor, "
                             "motor.kind = 'dc_motor', takes a voltage command, generated as C for pd, lqr, "
                             "lqg, mpc and nmpc only)")
    if rig is not None and args.controller == "mpc" and not rig.drive.is_ideal and args.precision != "double":
        raise ParameterError(f"--precision {args.precision} does not apply with --controller mpc --rig {args.rig} "
                             "(its QP with the DC motor's voltage limit needs double)")
    if args.schedule > 1 and args.controller != "lqg":
        from hubbeam_ctrl.study.compare_values import check_schedule
        check_schedule(args.schedule)                 # its range first: --schedule=1e308 is not "for lqg only"
        raise ParameterError(f"--schedule {args.schedule} applies to --controller lqg only (the gain-scheduled LQG "
                             f"is the scheduled controller that can be generated as C), got {args.controller!r}")
    sc, design = design_task(args, rig, params)
    if args.controller == "nmpc":
        return _nmpc(args, sc, design, rig, sink)
    settings = task_shaped_settings(args.controller, CONTROLLERS[args.controller].settings.for_scenario(sc),
                                    design, sc)[0]
    schedule = None
    if args.schedule > 1:
        from controllers import DesignSchedule
        from hubbeam_ctrl.study.compare_values import check_schedule
        schedule = DesignSchedule.for_scenario(sc, check_schedule(args.schedule), design.n_modes)
    if args.payload_range is not None:
        settings = _payload_settings(args, settings, design)
    if rig is None:
        ctrl = make_controller(args.controller, design, settings, sc.reference, schedule=schedule)
    else:      # the controller that runs on the rig: integral action, observer, volts (as compare --rig)
        from hubbeam_ctrl.study.rig_loop import on_rig, rig_closed_loop, rig_design, rig_settings, task_noise
        # the rig's sensors and delay in the design, as compare --rig has them: the C reads what the rig gives
        design = rig_design(design, rig)
        ctrl = make_controller(args.controller, design, rig_settings(args.controller, settings, rig), sc.reference,
                               schedule=schedule)
        ctrl = on_rig(ctrl, rig, task_noise(sc, rig), rig_closed_loop(rig, sc.closed_loop_settings())[1])
    cc = compiler()

    def check(folder, name):
        if cc is not None:
            import tempfile
            with tempfile.TemporaryDirectory() as tmp:
                compile_c(folder, "-O2", tmp, name)

    code = to_c(ctrl, args.out, args.precision, force=args.force, check=check)
    meta = code.metadata()
    if args.json:
        print(json.dumps({**meta, "out": str(code.folder), "compiled": cc is not None}), file=sink)
    else:
        sensors = ", ".join(code.law.sensor_text()) or "none"
        print(f"{args.controller.upper()} for {sc.description}: wrote {code.header_path} and {code.source_path} "
              f"({args.precision}, {meta['data_bytes']} bytes of data); reads {sensors}; "
              f"commands {meta['command']['name']} [{meta['command']['unit']}] every {sc.dt:g} s", file=sink)
    if cc is None:
        print(NO_COMPILER, file=sys.stderr)
    elif not args.json:
        print("  compiled warning-free with -std=c99 -Wall -Wextra -pedantic -Werror -O2", file=sink)
    return 0


def _payload_settings(args, settings, design):
    """``settings`` with the payloads of ``--payload-range`` (the range's ends and the nominal tip mass,
    :func:`controllers.robust.payload_grid`): the multi-stage MPC's scenarios, the H-infinity spread weight's."""
    from controllers.robust import payload_grid
    from hubbeam_ctrl.cli.compare import parse_payload_range
    from hubbeam_ctrl.core.errors import ParameterError
    if args.controller not in ("msmpc", "hinf"):
        raise ParameterError(f"--payload-range does not apply with --controller {args.controller} (it sets the "
                             "payloads of msmpc and hinf)")
    m_t = design.params.m_t
    return settings.replace(payloads=payload_grid(parse_payload_range(args.payload_range, m_t), m_t))


def _nmpc(args, sc, design, rig, sink) -> int:
    """``hubbeam codegen --controller nmpc``: the NMPC's step as C (:func:`hubbeam_ctrl.deploy.nmpc_c.nmpc_to_c`)."""
    from controllers import CONTROLLERS, make_controller
    from hubbeam_ctrl.core.errors import ParameterError
    from hubbeam_ctrl.deploy.nmpc_c import nmpc_to_c
    if args.precision != "double":
        raise ParameterError("--precision single does not apply with --controller nmpc (CasADi generates double)")
    settings = CONTROLLERS["nmpc"].settings.for_scenario(sc)
    if rig is None:
        ctrl = make_controller("nmpc", design, settings, sc.reference)
    elif rig.drive.is_ideal:
        raise ParameterError(f"--controller nmpc with --rig {args.rig} needs a DC motor (motor.kind = 'dc_motor'): "
                             "its C is the step with the drive in the prediction, commanding volts")
    else:      # the step with the rig's drive, friction and delay in its prediction, commanding volts
        from controllers import NMPC
        from hubbeam_ctrl.sim.hardware import Hardware
        from hubbeam_ctrl.study.rig_loop import rig_design
        ctrl = NMPC(rig_design(design, rig), settings, sc.reference, hardware=Hardware.from_rig(rig))
    info = nmpc_to_c(ctrl, args.out, force=args.force)
    if args.json:
        print(json.dumps({**info, "out": str(args.out)}), file=sink)
    else:
        print(f"NMPC for {sc.description}: wrote {args.out}/{info['function']}.c, .h and .json (horizon "
              f"{info['horizon']} samples, every {sc.dt:g} s; the step with its QP solver, no CasADi at run time; "
              f"commands {info['command']['unit']}, limit {info['command']['limit']:g})", file=sink)
    return 0


COMMAND = Command(
    "codegen", _options, _run, help="write a controller as portable C99 (header + source)",
    description=("Design a controller for a slew or spin-up on the sampled SFOAM model and write it as C99: an "
                 "instance struct, <kind>_init, <kind>_reset and <kind>_step(inst, measurements, reference, "
                 "command); no dynamic memory, no I/O, only math.h. LQR and MPC are written with their Kalman "
                 "observer; with --rig every observer reads the rig's own sensors (its header names them in "
                 "order, with units)."))
