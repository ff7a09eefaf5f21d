"""``hubbeam compare``: the controllers in closed loop on FOAM or CFOAM (see
:mod:`hubbeam_ctrl.study.compare`)."""

from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from controllers import CONTROLLERS, QP_SOLVERS, SHAPERS, controller_names
from hubbeam_ctrl.cli.args import (
    Command,
    add_rig_option,
    add_run_options,
    check_output_dir,
    check_rig_dt,
    integer,
    nonempty,
    params_from_args,
    real,
    refuse_inapplicable,
    rig_from_args,
    run_limits,
    stdout,
)
from hubbeam_ctrl.cli.main import RegistryChoices, add_backend_option, positive_int
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.jsonio import strict_json
from hubbeam_ctrl.core.native import stdout_to_stderr  # noqa: F401  (kept importable from here)

__all__ = ["add_compare_options", "ComparePlan", "stdout_to_stderr"]


def add_compare_options(p, controllers: bool = True) -> None:
    """The options of ``hubbeam compare`` on parser ``p`` (``hubbeam certify`` takes them too).

    Parameters
    ----------
    p : argparse.ArgumentParser
    controllers : bool
        Add ``--controllers`` (False: the command names its controller otherwise).
    """
    # explicit metavars: argparse would otherwise read the choices (importing the study layer)
    # when the parser is built, not only when --help is shown or a value is checked
    p.add_argument("--plant", metavar="PLANT", choices=RegistryChoices("hubbeam_ctrl.study.scenarios", "PLANTS"),
                   default="foam", help="nonlinear plant: %(choices)s (default %(default)s: closer to an "
                                        "exact beam than cfoam)")
    p.add_argument("--check-plant", metavar="PLANT", choices=RegistryChoices("hubbeam_ctrl.study.scenarios", "PLANTS"),
                   default=None, help="run every controller also on this plant (%(choices)s; same modes, step and "
                                      "sensors) and report both: e.g. --plant ancf --check-plant foam shows where FOAM "
                                      "leaves its validated range and the exact beam does not")
    p.add_argument("--plant-params", metavar="FILE.toml", type=nonempty("file"),
                   help="physical parameters of the plant when they differ from the design's")
    p.add_argument("--plant-tip-mass", metavar="KG", type=real("kg"), help="tip mass of the plant [kg], >= 0")
    p.add_argument("--design-modes", metavar="N", type=integer(),
                   help="transverse modes of the design model, 1..20 (default: --n-modes or 5)")
    p.add_argument("--plant-modes", metavar="N", type=integer(),
                   help="transverse modes of the plant, design modes..20 (default: every mode "
                        "below the sampling frequency and the first above it, >= design + 3)")
    p.add_argument("--range-limit", metavar="FRACTION", type=real("-"), default=0.3,
                   help="flag runs whose |v_tip| passes FRACTION * L (the models' validated "
                        "range; default 0.3); only L stops a run")
    p.add_argument("--scenario", metavar="NAME", choices=RegistryChoices("hubbeam_ctrl.study.scenarios",
                                                                         "SCENARIOS"),
                   default="slew", help="registered scenario: %(choices)s (default %(default)s; see "
                                        "hubbeam_ctrl.study.scenarios)")
    if controllers:
        default = ",".join(controller_names(default=True))
        p.add_argument("--controllers", metavar="LIST", default=default,
                       help="comma-separated subset of the registered controllers "
                            + ", ".join(f"{n} ({s.label})" for n, s in CONTROLLERS.items())
                            + f" (default: {default})")
    p.add_argument("--shaping", choices=list(SHAPERS), default=None,
                   help="filter the reference of the controllers that track one ("
                        + ",".join(n for n, s in CONTROLLERS.items() if s.tracks_reference)
                        + ") through this input shaper, designed on the first mode of the design model")
    p.add_argument("--tau-max", metavar="NM", type=real("N m"),
                   help="torque budget [N m], at most the motor's tau_max of the parameters "
                        "(default: that limit, 200 N m in Table 1)")
    p.add_argument("--slew-angle", metavar="RAD", type=real("rad"),
                   help="slew angle [rad], not 0 (default: the rigid angle of the Eq. 44 torque with "
                        "amplitude --tau-max in --tf); the open-loop baseline is Eq. 44 scaled to this "
                        "angle and --tf")
    p.add_argument("--tf", metavar="S", type=real("s"), default=None,
                   help="maneuver time [s] (default 10; with --rig and the slew, the rig's default slew: a quarter "
                        "turn, or --slew-angle, in 1.5 x an upper bound of its time-optimal slew; given, the rig's "
                        "slew turns that angle in it, not Eq. 44's); refused, naming "
                        "the shortest feasible one, if the task needs more torque than --tau-max")
    p.add_argument("--t-end", metavar="S", type=real("s"),
                   help="simulated time [s], past the residual window's start (tf + 5 s on the paper's slew; "
                        "default: the task's, the residual window lasts six first-mode periods, at least 3 tf: "
                        "30 s for the paper's slew)")
    p.add_argument("--wf", metavar="RAD_S", type=real("rad/s"),
                   help="spin-up final rate [rad/s] (default 3, above TLAM's critical speed; "
                        "--scenario spinup only)")
    p.add_argument("--dt", metavar="S", type=real("s"),
                   help="controller sample time [s] (default: the rig's, else 0.01)")
    add_rig_option(p, "the physical rig: a rig TOML file or a preset (servo_link, paper); its beam replaces --params, "
                      "and the plant carries its drive, friction, damping and sensors (docs/rig.md); the report gets "
                      "the rig ladder (the comparison with one part of the hardware added at a time)")
    p.add_argument("--integral", choices=("auto", "on", "off"), default="auto",
                   help="integral action of LQR, LQG and MPC on the rig (disturbance estimation; default auto: "
                        "on for rigs with friction or a DC motor); --rig only")
    p.add_argument("--no-ladder", action="store_true", help="skip the rig ladder (--rig only)")
    p.add_argument("--settle-angle", metavar="BAND",
                   help="settling band of the hub-angle error: a number [rad] or 1.5mrad, 0.05deg, 2counts (of the "
                        "--rig's encoder, or 2 sd of its angle sensor); default: 1e-3 of the slew angle, on a rig at "
                        "least 2 counts (the report says where each band came from)")
    p.add_argument("--settle-tip", metavar="BAND",
                   help="settling band of |v_tip|: a number [m] or 0.5mm, 1e-3L (a fraction of L); default 1.25e-4 L")
    p.add_argument("--reference", choices=("task", "rigid", "planned", "optimal"), default="task",
                   help="reference and feedforward of the tracking controllers: 'task' (default): a slew given by "
                        "--slew-angle planned on the design model to end with the beam at rest (the optimal one "
                        "instead when that plan cannot keep the tip within 0.3 L), the paper's Eq. 44 "
                        "slew and spin-ups the rigid body's smooth reference; 'rigid': always the smooth rigid "
                        "reference; 'planned': always the planned slew; 'optimal': the minimum-vibration slew of the "
                        "nonlinear beam in --tf within the drive's limits (seconds of optimisation). Planned and "
                        "optimal: slew only; the feedback then only corrects model error")
    p.add_argument("--limit", choices=("rigid", "optimal"), default="rigid",
                   help="yardstick of the settling times: the rigid body's shortest slew with --tau-max (default, "
                        "closed form) or the time-optimal slew of the nonlinear beam within the drive's limits "
                        "(hubbeam optimal; seconds to a minute)")
    p.add_argument("--horizon", metavar="N", type=integer(),
                   help="MPC horizon [samples] (default 50; only with mpc or msmpc among --controllers)")
    p.add_argument("--solver", choices=list(QP_SOLVERS),
                   help="MPC QP solver: %(choices)s (default daqp; only with mpc among --controllers)")
    p.add_argument("--schedule", metavar="N", type=positive_int("schedule"), default=1,
                   help="design the controllers with a scheduled version ("
                        + ",".join(n for n, s in CONTROLLERS.items() if s.scheduled)
                        + ") at N spin rates from 0 to the top reference rate and interpolate them on "
                          "the measured rate (default 1: one design point)")
    p.add_argument("--out", metavar="DIR", required=True,
                   help="output folder (created if missing; MANIFEST.json, written last, marks it complete)")
    p.add_argument("--payload-range", metavar="MIN,MAX",
                   help="tip payloads [kg] that LQR, LQG and MPC are designed for (must hold the tip mass "
                        "of the parameters; msmpc: one scenario each at MIN, the nominal tip mass and MAX); "
                        "runs the plant at MIN, the nominal tip mass and MAX and writes payload.json and "
                        "payload_report.md")
    p.add_argument("--learn-payload", action="store_true",
                   help="with --payload-range and --scenario slew: LQR, LQG and MPC keep the nominal design and "
                        "learn the payload during the slew (identified at 25 %% and 50 %% of it, the rest "
                        "re-planned on the nonlinear model within 1 s) instead of a design for the range; "
                        "the NMPC (--controllers nmpc) estimates it every sample from the hub's momentum "
                        "and predicts with it")
    add_backend_option(p)
    p.add_argument("--json", action="store_true", help="print the metrics as JSON instead of a table")
    add_run_options(p)


def parse_payload_range(text: str, nominal: float) -> tuple:
    """``"MIN,MAX"`` -> ``(m_min, m_max)`` [kg], validated (one-line error naming payload-range).

    Parameters
    ----------
    text : str
        ``MIN,MAX`` [kg] as typed.
    nominal : float
        Nominal tip mass [kg] (must lie in the range).
    """
    from controllers.robust import check_payload_range
    parts = [t.strip() for t in str(text).split(",")]
    try:
        values = tuple(float(t) for t in parts)
    except ValueError:
        values = None
    if values is None or len(values) != 2 or not all(math.isfinite(v) for v in values):
        raise ParameterError(f"payload-range must be two finite numbers MIN,MAX [kg], got {text!r}")
    return check_payload_range(values, nominal, "payload-range")


@dataclass
class ComparePlan:
    """What ``hubbeam compare`` runs: every option of its command line turned into a value
    (``COMMAND.plan``), before any work.

    Attributes
    ----------
    options : dict
        The options by name, as :func:`hubbeam_ctrl.study.compare_values.compare_arguments`
        routes them into :func:`hubbeam_ctrl.study.compare.compare`'s values or, with
        ``--payload-range``, of :func:`hubbeam_ctrl.study.payload.payload_comparison` (the same
        keywords, plus ``payload_range``).
    payload : bool
        The payload path (``--payload-range``).
    ladder : bool
        Run the rig ladder after the comparison.
    out : Path
        Output folder.
    json : bool
        Print JSON instead of a table.
    """

    options: dict
    payload: bool = False
    ladder: bool = False
    out: Path | None = None
    json: bool = False


#: Options of the plain comparison that the payload path refuses, with the reason.
PAYLOAD_REFUSES = {"--plant-tip-mass": "the payload range sets the plant's tip masses",
                   "--rig": "a rig's drive and sensors are not modelled over a payload range yet; give the "
                            "rig's beam with --params"}
#: Options that ``--learn-payload`` refuses: the re-planned controllers are built without them.
LEARNING_REFUSES = {"--shaping": "the re-planned controllers follow the re-plan's reference unshaped",
                    "--schedule": "the re-planned controllers are single design points"}


def _refuse_with(args, mode: str, refused: dict) -> None:
    """One line naming the first option of ``refused`` given and the option it conflicts with."""
    for option, why in refused.items():
        value = getattr(args, option.lstrip("-").replace("-", "_"), None)
        if value is not None and value is not False and not (option == "--schedule" and value == 1):
            raise ParameterError(f"{option} does not apply with {mode} ({why})")


def _plan(args) -> ComparePlan:
    """The :class:`ComparePlan`: the plain comparison and the payload path take the same values."""
    from hubbeam_ctrl.plant.params import MAX_MODES
    from hubbeam_ctrl.study.compare import _parse_controllers
    out = check_output_dir("--out", args.out)
    names = _parse_controllers(args.controllers)
    refuse_inapplicable(args, f"--scenario {args.scenario}", {"--wf": ("spinup",)})
    if "mpc" not in names and "msmpc" not in names:
        refuse_inapplicable(args, "--controllers " + ",".join(names), {"--horizon": ("mpc", "msmpc"),
                                                                       "--solver": ("mpc",)})
    if args.learn_payload and (args.payload_range is None or args.scenario != "slew"):
        raise ParameterError("--learn-payload needs --payload-range MIN,MAX and --scenario slew")
    if args.payload_range is not None:
        _refuse_with(args, "--payload-range", PAYLOAD_REFUSES)
    if args.learn_payload:
        _refuse_with(args, "--learn-payload", LEARNING_REFUSES)
    rig = _rig(args)
    check_rig_dt(args, rig)
    if rig is not None and not rig.sensors.rate and "pd" in names \
            and args.controllers == ",".join(controller_names(default=True)):
        names = tuple(n for n in names if n != "pd")   # the default list on a rig without a rate sensor
        print("hubbeam: pd left out: it reads the hub rate and the rig has no sensors.rate", file=sys.stderr)
    params = rig.plant_params if rig is not None else params_from_args(args)
    if args.tau_max is not None and args.tau_max > params.tau_max:
        raise ParameterError(f"--tau-max must be in (0, {params.tau_max:g}] N m (the motor's tau_max of "
                             f"the parameters), got {args.tau_max:g}")
    if args.slew_angle is not None and args.slew_angle == 0:
        raise ParameterError("--slew-angle must be a finite number != 0 [rad], got 0")
    if args.slew_angle is not None and args.scenario != "slew":
        raise ParameterError("--slew-angle applies to --scenario slew only")
    for option, value in (("--reference", args.reference), ("--limit", args.limit)):
        if args.scenario != "slew" and value in ("planned", "optimal"):   # a spin-up: the rigid reference and bound
            raise ParameterError(f"{option} {value} applies to --scenario slew only, not --scenario {args.scenario}")
    plant_params = _plant_params(args, params)
    if args.check_plant is not None and args.check_plant == args.plant:
        raise ParameterError(f"--check-plant must be a plant other than --plant {args.plant}, got {args.check_plant}")
    for option in ("plant", "check_plant"):
        if getattr(args, option) == "ancf":
            from hubbeam_ctrl.exact import require_exudyn
            require_exudyn(f"--{option.replace('_', '-')} ancf")
    design_modes = args.design_modes if args.design_modes is not None else params.n_transverse
    if not 1 <= design_modes <= MAX_MODES:
        raise ParameterError(f"--design-modes must be an integer in 1..{MAX_MODES}, got {design_modes}")
    if args.plant_modes is not None and not design_modes <= args.plant_modes <= MAX_MODES:
        raise ParameterError(f"--plant-modes must be an integer in {design_modes}..{MAX_MODES} (at least "
                             f"the design model's {design_modes}), got {args.plant_modes}")
    options = dict(plant=args.plant, scenario=args.scenario, controllers=names, params=params,
                   limit=args.limit, reference=args.reference, plant_params=plant_params,
                   # not given: compare's default (the beam's, fewer when its plant cannot be integrated)
                   design_modes=args.design_modes, plant_modes=args.plant_modes, tau_max=args.tau_max, t_f=args.tf,
                   t_end=args.t_end, dt=args.dt, w_f=3.0 if args.wf is None else args.wf,
                   slew_angle=args.slew_angle, horizon=50 if args.horizon is None else args.horizon,
                   solver=args.solver or "daqp", shaping=args.shaping, schedule=args.schedule,
                   sim_settings={"range_limit": args.range_limit, **run_limits(args)},
                   progress=not args.json, backend=args.backend, check_plant=args.check_plant)
    bands = _bands(args, rig)
    if bands and args.payload_range is not None:
        raise ParameterError("--settle-angle and --settle-tip do not take --payload-range yet")
    options.update(bands)
    if rig is not None:
        options.update(params=None, rig=rig, integral={"auto": None, "on": True, "off": False}[args.integral])
    if args.payload_range is not None:
        options["payload_range"] = parse_payload_range(args.payload_range, params.m_t)
        if args.learn_payload:
            from controllers.payload_learning import PayloadLearningSettings
            lo, hi = options["payload_range"]
            options["payload_learning"] = PayloadLearningSettings(payload_min_kg=lo, payload_max_kg=hi)
    return ComparePlan(options, payload=args.payload_range is not None,
                       ladder=rig is not None and not rig.is_ideal and not args.no_ladder, out=out, json=args.json)


def _run_payload(plan: ComparePlan, sink) -> int:
    from hubbeam_ctrl.study.compare_values import compare_arguments
    from hubbeam_ctrl.study.payload import payload_comparison, payload_table, write_payload_outputs
    pc = payload_comparison(**compare_arguments(**plan.options))
    write_payload_outputs(pc, plan.out)
    if plan.json:
        print(strict_json(json.loads((plan.out / "payload.json").read_text())), file=sink)
    else:
        print(payload_table(pc), file=sink)
        print(f"wrote {plan.out}/payload.json, payload_report.md", file=sink)
    return 0


def _run(args) -> int:
    """Run the comparison (or the payload range), write its outputs, print its table (status 0)."""
    sink = stdout(args)
    plan = _plan(args)
    if plan.payload:
        return _run_payload(plan, sink)
    from hubbeam_ctrl.plots import worker
    worker.start()                  # imports Matplotlib while the controllers run; draws the report's PNGs
    try:
        return _run_plain(args, plan, sink)
    finally:
        worker.stop()


def _run_plain(args, plan, sink) -> int:
    """The plain comparison of :func:`_run` (the figure worker started)."""
    from hubbeam_ctrl.study.compare import compare
    from hubbeam_ctrl.study.compare_values import compare_arguments
    from hubbeam_ctrl.study.report import _json_metrics, format_table, loop_png, write_outputs
    t0 = time.perf_counter()
    opts = plan.options
    names, out = opts["controllers"], plan.out
    early = []              # loops.png: its data and figure need only the designs (drawn while the runs go)
    ladder = []             # the rig ladder: started in forked workers as soon as the designs are made

    def designed(designed):
        if plan.ladder:     # the ladder's steps run while this comparison runs (its last step is this one)
            ladder.append(_start_ladder(opts, designed.scenario))
        early.append(loop_png(designed))

    try:
        # the closed loops side by side (a forked child runs part of them): the report reads only their results
        comparison = compare(**compare_arguments(**opts, side_by_side=True), designed=designed)
        if plan.ladder:
            t_ladder = time.perf_counter()
            if not ladder:
                ladder.append(_start_ladder(opts, comparison.scenario))
            comparison.ladder = ladder[0].rows(done=comparison, progress=None if args.json else (
                lambda step: print(f"ladder: {step}", file=sys.stderr)))    # its last step: the comparison's runs
            # the report's wall time covers the ladder too (said apart in the report: the time waited for it)
            comparison.ladder_wall_s = time.perf_counter() - t_ladder
            comparison.wall_s = time.perf_counter() - t0
    finally:
        for run in ladder:
            run.stop()
    paths = write_outputs(comparison, out, loops=early[0] if early else None)
    wall = time.perf_counter() - t0
    if args.json:
        print(strict_json(_json_metrics(comparison.metrics)), file=sink)
    else:
        sc, ev = comparison.scenario, comparison.plant
        print(f"{sc.plant.upper()}, {sc.name}: {sc.description}", file=sink)
        print(f"plant: {ev.model.upper()} with {ev.modes} transverse modes ({ev.reason})", file=sink)
        print(format_table(comparison.metrics), file=sink)
        print(f"wrote {out}/{', '.join(p.name for p in paths.values())}, MANIFEST.json ({wall:.1f} s)", file=sink)
    for name, m in comparison.metrics.items():
        if not m["completed"] or m.get("outside_validated_range"):
            print(f"warning: {name}: {m['message']}", file=sys.stderr)
        if m.get("check_outside_range_time_s") is not None:
            print(f"warning: {name}: on the check plant {m['check_plant'].upper()}: "
                  f"{comparison.check_metrics[name]['message']}", file=sys.stderr)
    skipped = [n for n in names if n not in comparison.metrics]
    if skipped:
        print(f"warning: not run (the wall-time limit was reached): {', '.join(skipped)}", file=sys.stderr)
    return 0


def _ladder_settings(opts: dict, sc):
    """The ladder's values: the comparison's plant, task shape, step, MPC and integral action, its
    simulated time and bands (the rest at their defaults, so each step is the rig's plain comparison)."""
    from hubbeam_ctrl.study.compare_values import (
        CompareSettings,
        DesignChoice,
        PlantChoice,
        RunChoice,
        ScenarioChoice,
    )
    return CompareSettings(
        plant=PlantChoice(opts["plant"]),
        design=DesignChoice(horizon=opts["horizon"], solver=opts["solver"], integral=opts["integral"]),
        run=RunChoice(dt=opts["dt"], t_end=sc.t_end),
        scenario=ScenarioChoice(t_f=opts["t_f"], w_f=opts["w_f"], slew_angle=opts["slew_angle"],
                                tau_max=opts["tau_max"], settle_angle=sc.bands["settle_angle"],
                                settle_tip=sc.bands["settle_tip"]))


def _start_ladder(opts: dict, sc):
    """The rig ladder of the comparison ``opts`` on the scenario ``sc``, started in as many forked
    workers as this process may use processors (:class:`hubbeam_ctrl.study.ladder.LadderRun`)."""
    from hubbeam_ctrl.study.ladder import LadderRun
    from hubbeam_ctrl.study.sweep import available_processors
    return LadderRun(opts["rig"], opts["scenario"], opts["controllers"], _ladder_settings(opts, sc),
                     workers=available_processors())


def _bands(args, rig) -> dict:
    """``--settle-angle`` and ``--settle-tip`` as keywords of ``compare`` (refused in one line, before
    any work, naming the option, its accepted forms and ``--rig`` for counts)."""
    from hubbeam_ctrl.study.bands import angle_count, parse_band
    bands = {key: parse_band(f"--{key.replace('_', '-')}", getattr(args, key), kind)
             for key, kind in (("settle_angle", "angle"), ("settle_tip", "tip")) if getattr(args, key) is not None}
    if "settle_angle" in bands:
        count = angle_count(rig)
        bands["settle_angle"].si(count[0] if count else None, 1.0)      # counts need the rig's angle sensor
    return bands


def _rig(args):
    """The rig of ``--rig`` (None without it); ``--no-ladder`` and ``--integral`` need one."""
    if args.rig is None:
        if args.no_ladder:
            raise ParameterError("--no-ladder applies with --rig only")
        if args.integral != "auto":
            raise ParameterError("--integral applies with --rig only")
    return rig_from_args(args)


def _plant_params(args, params):
    """The plant's parameters from ``--plant-params`` and ``--plant-tip-mass`` (None: the design's);
    errors name those options, not the design's."""
    from hubbeam_ctrl.plant.params import load_params
    try:
        plant_params = load_params(args.plant_params) if args.plant_params is not None else None
    except ParameterError as exc:
        raise ParameterError(f"--plant-{exc}") from None   # "params file X ..." -> "--plant-params file X ..."
    if args.plant_tip_mass is None:
        return plant_params
    try:
        return (plant_params or params).replace(m_t=args.plant_tip_mass)
    except ParameterError as exc:
        raise ParameterError(f"--plant-tip-mass: {exc}") from None


def _compare_options(p) -> None:
    """``hubbeam compare``'s options on its parser ``p``."""
    add_compare_options(p)


def _description() -> str:
    labels = ", ".join(spec.label for spec in CONTROLLERS.values())
    return (f"Design the registered controllers ({labels}) on SFOAM and compare them in closed loop (zero-order hold "
            "at --dt) on the nonlinear FOAM or CFOAM evaluation plant, which has every bending mode below the "
            "sampling frequency and at least three more than the design model. --params and the common options set "
            "both the design and the plant; --plant-params and --plant-tip-mass make the plant differ. Writes "
            "metrics.csv, metrics.json, tip_deflection.png, hub_angle.png, torque.png and report.md to --out.")


COMMAND = Command("compare", _compare_options, _run, plan=_plan, help="compare controllers in closed loop",
                  description=_description())
