"""``hubbeam simulate``: the Eq. 43 spin-up (prescribed hub) or the Eq. 44 torque pulse (free hub) on an
assumed-mode model, or on the exact beam (``--plant ancf``)."""

from __future__ import annotations

import sys

from hubbeam_ctrl.cli.args import (
    Command,
    add_run_options,
    check_output,
    integer,
    params_from_args,
    real,
    refuse_inapplicable,
    run_limits,
    stdout,
)
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.jsonio import strict_json
from hubbeam_ctrl.plant.models import AXIAL_TREATMENTS, MODEL_SPECS

__all__ = ["FIXED_STEP_DT"]


def _options(p) -> None:
    """``hubbeam simulate``'s options on its parser ``p``."""
    from hubbeam_ctrl.cli.main import add_backend_option
    p.add_argument("--model", choices=list(MODEL_SPECS), default=None,
                   help="the assumed-mode model (required unless --plant ancf)")
    p.add_argument("--plant", choices=["ancf"], default=None,
                   help="ancf: the geometrically exact beam of Exudyn (ANCF cable elements, optional extra: "
                        "pip install 'hubbeam-ctrl[exact]') instead of --model; the torque is applied at every "
                        "integration step, the step is FOAM's rule and the elements 3 per mode")
    p.add_argument("--substeps", metavar="K", type=integer(), default=None,
                   help="--plant ancf: integration steps per 10 ms sample (default: FOAM's rule, 0.5 %% on the "
                        "highest mode; at least 12 steps per period of the highest mode)")
    p.add_argument("--elements", metavar="N", type=integer(), default=None,
                   help="--plant ancf: ANCF elements (default: 3 per bending mode, a multiple of 8, at least 16)")
    p.add_argument("--maneuver", choices=["spinup", "torque"], required=True)
    p.add_argument("--wf", metavar="RAD_S", type=real("rad/s"),
                   help="spin-up final rate [rad/s] (default 3; --maneuver spinup only)")
    p.add_argument("--tf", metavar="S", type=real("s"),
                   help="maneuver time [s] (default 30 for spinup, 10 for torque)")
    p.add_argument("--tau-max", metavar="NM", type=real("N m"),
                   help="torque amplitude [N m], > 0 (default 200; --maneuver torque only)")
    p.add_argument("--t-end", metavar="S", type=real("s"), required=True,
                   help="final time [s], at least one sample (0.01 s)")
    p.add_argument("--out", metavar="FILE.csv|FILE.npz", help="save the time series")
    p.add_argument("--plot", metavar="FILE.png", help="save a plot")
    p.add_argument("--range-limit", metavar="FRACTION", type=real("-"), default=0.3,
                   help="flag the run when |v_tip| passes FRACTION * L (the models' validated range; "
                        "default 0.3); only L stops it")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.add_argument("--axial", choices=AXIAL_TREATMENTS, default="dynamic",
                   help="dynamic: integrate the axial modes (default); quasi-static: solve them from "
                        "their static balance at every instant (cfoam, foam, tlam; no stiff modes)")
    p.add_argument("--integrator", choices=["auto", "fixed-step", "idas"], default="auto",
                   help="fixed-step: the compiled generalized-alpha path run at 10 ms and 20 ms steps, the "
                        "step halved until the estimated error of the peak tip deflection is below 1e-4 "
                        "(torque only; about 10 times faster); idas: SUNDIALS IDAS with error control; "
                        "auto (default): fixed-step for --maneuver torque, idas for spinup")
    add_run_options(p)
    add_backend_option(p)


#: Output sample period of the fixed-step torque runs [s] (IDAS's default dt).
FIXED_STEP_DT = 0.01


def _run(args) -> int:
    """Simulate the maneuver, save, plot and print its summary (status 0)."""
    sink = stdout(args)
    from hubbeam_ctrl.plant.maneuvers import SpinUp, TorquePulse
    from hubbeam_ctrl.sim.simulate import simulate
    check_output("--out", args.out, (".csv", ".npz"))
    check_output("--plot", args.plot, (".png",))
    refuse_inapplicable(args, f"--maneuver {args.maneuver}", {"--wf": ("spinup",), "--tau-max": ("torque",)})
    params = params_from_args(args)
    if args.maneuver == "spinup":
        maneuver = SpinUp(args.wf if args.wf is not None else 3.0, args.tf if args.tf is not None else 30.0)
    else:
        maneuver = TorquePulse(args.tau_max if args.tau_max is not None else 200.0,
                               args.tf if args.tf is not None else 10.0)
    if args.plant == "ancf":
        return _simulate_exact(args, maneuver, params, sink)
    refuse_inapplicable(args, "an assumed-mode model", {"--substeps": ("--plant ancf",),
                                                        "--elements": ("--plant ancf",)})
    if args.model is None:
        raise ParameterError("--model is required (cfoam, foam, tlam, sfoam), or --plant ancf for the exact beam")
    integrator = args.integrator
    if integrator == "auto":
        integrator = "fixed-step" if args.maneuver == "torque" and args.t_end >= 2 * FIXED_STEP_DT else "idas"
    if integrator == "fixed-step":
        if args.maneuver != "torque":
            raise ParameterError("--integrator fixed-step needs --maneuver torque (a spin-up prescribes the "
                                 "hub: use --integrator idas)")
        from hubbeam_ctrl.sim.estimated import simulate_estimated
        res = simulate_estimated(args.model, maneuver, args.t_end, params=params, dt=FIXED_STEP_DT,
                                 range_limit=args.range_limit, backend=args.backend, axial=args.axial,
                                 outputs=bool(args.out), **run_limits(args))
    else:
        res = simulate(args.model, maneuver, args.t_end, params=params, progress=not args.json,
                       range_limit=args.range_limit, **run_limits(args), backend=args.backend, axial=args.axial)
    _print_simulation(args, res, integrator, sink)
    return 0


def _simulate_exact(args, maneuver, params, sink) -> int:
    """``hubbeam simulate --plant ancf``: the maneuver on the exact beam (Exudyn ANCF)."""
    for option, value, default in (("--model", args.model, None), ("--axial", args.axial, "dynamic"),
                                   ("--integrator", args.integrator, "auto"), ("--backend", args.backend, None)):
        if value != default:
            raise ParameterError(f"{option} does not apply to --plant ancf (the exact beam: Exudyn's ANCF "
                                 "elements and generalized-alpha; FOAM's modes for the projected state)")
    from hubbeam_ctrl.sim.exactbeam import simulate_exact
    res = simulate_exact(maneuver, args.t_end, params=params, dt=FIXED_STEP_DT, substeps=args.substeps,
                         n_elements=args.elements, range_limit=args.range_limit, progress=not args.json,
                         option_names={"substeps": "--substeps", "dt": "dt", "plant": "--plant ancf",
                                       "n_elements": "--elements"},
                         **run_limits(args))
    _print_simulation(args, res, "exudyn-ancf", sink)
    return 0


def _print_simulation(args, res, integrator: str, sink) -> None:
    """Save, plot and print the summary of a ``hubbeam simulate`` run."""
    if args.out:
        res.save(args.out)
    if args.plot:
        from hubbeam_ctrl.plots.plant import plot_result, save_figure
        save_figure(plot_result(res), args.plot, option="plot")
    s = res.summary()
    out = {k: s[k] for k in ("peak_tip_m", "residual_tip_m", "peak_axial_m", "final_theta_rad",
                             "final_theta_dot_rad_s", "diverged", "wall_s")}
    out["integrator"] = integrator
    out["peak_error_estimate"] = res.stats.get("peak_error_estimate")     # None: IDAS's error control
    if res.model == "ancf":
        out.update(plant="ancf", plant_elements=res.settings["plant_elements"], substeps=res.settings["substeps"],
                   past_assumed_mode_range_time_s=res.stats.get("past_assumed_mode_range_time_s"))
    if args.json:
        print(strict_json(out), file=sink)
    else:
        for k, v in out.items():
            print(f"{k:>22}: {v}", file=sink)
        print(f"{'message':>22}: {res.message}", file=sink)
    if res.diverged or res.outside_validated_range or res.stats.get("past_assumed_mode_range_time_s") is not None:
        print(f"warning: {res.message}", file=sys.stderr)


COMMAND = Command("simulate", _options, _run, help="simulate a maneuver",
                  description="Simulate the Eq. 43 spin-up (prescribed hub) or the Eq. 44 torque pulse (free hub).")
