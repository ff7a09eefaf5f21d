"""Closed-loop comparison of the controllers on FOAM or CFOAM (``hubbeam compare``).

The top layer of the toolbox: it builds a scenario (reference, design model), designs
each controller on SFOAM, runs it on the nonlinear evaluation plant (more modes than the
design model, :func:`~hubbeam_ctrl.sim.evaluation.evaluation_plant`) with
:func:`~hubbeam_ctrl.sim.closedloop.simulate_closed_loop`, computes the metrics of
:mod:`hubbeam_ctrl.study.metrics` and writes ``metrics.csv``, ``metrics.json``, three PNG
plots and ``report.md``.

The controllers come from the registry :data:`controllers.CONTROLLERS` (each with its
default settings for a scenario, ``Settings.for_scenario``), the scenarios from
:data:`hubbeam_ctrl.study.scenarios.SCENARIOS`. ``shaping=`` filters the reference of the
controllers that track one through an input shaper; ``schedule=N`` runs the registered
gain-scheduled version of those that have one on ``N`` design spins
(:meth:`controllers.DesignSchedule.for_scenario`).

Examples
--------
>>> from hubbeam_ctrl.study import run_compare, print_table
>>> m = run_compare(None, "slew", "openloop,lqr", out_dir=None)              # doctest: +SKIP
>>> print_table(m)                                                           # doctest: +SKIP
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time
from dataclasses import dataclass, field

from controllers import CONTROLLERS, DesignModel, DesignSchedule, as_shaper, controller_names, make_controller
from controllers.analysis import loop_margins
from hubbeam_ctrl.core.budget import (
    CLOSED_LOOP_SECONDS_PER_SAMPLE,
    WallClock,
    check_budget,
    model_build_seconds,
    mpc_bytes,
    mpc_seconds,
)
from hubbeam_ctrl.core.compiled import resolve_backend
from hubbeam_ctrl.core.errors import HubbeamError, ParameterError
from hubbeam_ctrl.core.validation import check_in_range
from hubbeam_ctrl.exact import require_exudyn
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.plant.rig import Rig
from hubbeam_ctrl.sim.closedloop import ClosedLoopSettings, simulate_closed_loop
from hubbeam_ctrl.sim.evaluation import EvaluationPlant, default_design_modes, evaluation_plant
from hubbeam_ctrl.study.bands import with_task_bands
from hubbeam_ctrl.study.compare_values import DEFAULT_T_F, CompareSettings, as_rig, check_schedule
from hubbeam_ctrl.study.forked_runs import can_fork, side_by_side
from hubbeam_ctrl.study.judge import judge, name_causes, residual_modes_for, same_laws
from hubbeam_ctrl.study.references import tracked_reference
from hubbeam_ctrl.study.report import write_outputs
from hubbeam_ctrl.study.report_tables import against_openloop
from hubbeam_ctrl.study.rig_loop import (
    count_note,
    hub_damping_note,
    on_rig,
    rig_closed_loop,
    rig_design,
    rig_settings,
    task_noise,
)
from hubbeam_ctrl.study.scenarios import RANGES, Scenario, make_scenario
from hubbeam_ctrl.study.shaping import task_shaped_settings
from hubbeam_ctrl.study.tasks import Slew
from hubbeam_ctrl.study.worst_case import certify_set
from hubbeam_ctrl.study.yardstick import task_dt, task_limit, task_on_rig

__all__ = ["DEFAULT_CONTROLLERS", "TARGET_CONTROLLERS", "Comparison", "compare", "run_compare"]

#: Run a comparison's closed loops side by side (:mod:`hubbeam_ctrl.study.forked_runs`: a forked
#: child runs part of them) when nothing ties them together (no check plant, no uncertainty set, no
#: payload learning); False runs them here one after the other. The numbers are the same, but the
#: controllers that ran in the child keep their run's state there (``step_times_s``, a learnt
#: payload, counters): ``Comparison.controllers`` holds them as designed. Off by default for that
#: reason; it saved 15 % of an in-process ``compare()`` (2.54 s against 2.97 s, under load).
#: ``RunChoice(side_by_side=True)`` asks for it in one comparison (``hubbeam compare`` does).
SIDE_BY_SIDE = False

#: The controllers a comparison runs by default (the built-ins; see :func:`controllers.controller_names`).
DEFAULT_CONTROLLERS = controller_names(default=True)
#: The controllers held to the targets of the slew (the others, e.g. PD, are only reported).
TARGET_CONTROLLERS = controller_names(target=True)


def _shaped_durations(names, chosen, settings, design, sc) -> tuple:
    """The shaped slews' settings in the task's ``t_f`` (:func:`~hubbeam_ctrl.study.shaping.task_shaped_settings`)
    for the controllers whose settings the caller did not give, and the report's notes."""
    out, notes = dict(chosen), []
    for name in names:
        if name not in settings:
            out[name], note = task_shaped_settings(name, chosen[name], design, sc)
            notes += [note] if note else []
    return out, notes


def _parse_controllers(controllers) -> tuple:
    if controllers is None:
        return controller_names(default=True)
    if isinstance(controllers, str):
        names = [c.strip().lower() for c in controllers.split(",") if c.strip()]
    else:
        names = [str(c).strip().lower() for c in controllers]
    if not names:
        raise ParameterError(f"controllers must name at least one of {', '.join(CONTROLLERS)}")
    bad = [n for n in names if n not in CONTROLLERS]
    if bad:
        raise ParameterError(f"controllers: unknown {', '.join(map(repr, bad))}; allowed: "
                             f"{', '.join(CONTROLLERS)}")
    if len(set(names)) != len(names):
        raise ParameterError(f"controllers: each may appear once, got {','.join(names)}")
    return tuple(names)


def _design_schedule(sc: Scenario, points, design_modes):
    """The scenario's design schedule of ``points`` spins (None for a single design)."""
    check_schedule(points)
    return None if points == 1 else DesignSchedule.for_scenario(sc, points, design_modes)


@dataclass
class Comparison:
    """Everything one comparison produced.

    Attributes
    ----------
    scenario : Scenario
    results : dict
        Controller name -> :class:`~hubbeam_ctrl.sim.results.Result` (closed loop).
    metrics : dict
        Controller name -> metrics dictionary (see :data:`hubbeam_ctrl.study.metrics.METRIC_UNITS`).
    wall_s : float
        Wall time of the comparison (design and simulation, without writing) [s].
    paths : dict
        File kind -> Path, once :func:`~hubbeam_ctrl.study.report.write_outputs` wrote them.
    styles : dict
        Controller name -> plot style ``{"color", "label"}`` (from the registry).
    targets : tuple of str
        The controllers held to the slew's targets (the others are only reported).
    margins : dict
        Controller name -> :class:`controllers.analysis.LoopMargins` at the plant input on
        its design model, for the linear controllers (PD, LQR, LQG).
    controllers : dict
        Controller name -> the linear controllers themselves (PD, LQR, LQG), for the loop
        plots (:func:`hubbeam_ctrl.study.loops.comparison_loop_figures`).
    plant : EvaluationPlant
        The plant the controllers were judged on, and why it has its modes.
    certificates : dict
        Controller name -> :class:`~hubbeam_ctrl.study.certificate.Certificate`: the sampled
        linear loop on the evaluation plant's modes (empty for the open loop).
    rig : Rig or None
        The rig the controllers ran on (None: the beam alone).
    ladder : list of dict
        The rig ladder's rows (:func:`hubbeam_ctrl.study.ladder.rig_ladder`) when it was run.
    notes : list of str
        One line each for the report's notes (e.g. a shaped slew longer than ``t_f``).
    check_plant : EvaluationPlant or None
        The second plant of ``PlantChoice(check_plant=...)`` of ``compare`` (same parameters and modes).
    check_results, check_metrics : dict
        Controller name -> its result and metrics on ``check_plant`` (empty without one).
    robust : dict
        Controller name -> :class:`~hubbeam_ctrl.study.worst_case.WorstCase` over the rig's
        ``[uncertainty]`` (empty when the rig has none).
    settings : CompareSettings or None
        The settings the comparison ran with (the rig ladder takes this comparison as its last
        step when that step's rig and settings are these).
    """

    scenario: Scenario
    results: dict
    metrics: dict
    wall_s: float = 0.0
    paths: dict = field(default_factory=dict)
    styles: dict = field(default_factory=dict)
    targets: tuple = ()
    plant: EvaluationPlant | None = None
    margins: dict = field(default_factory=dict)
    certificates: dict = field(default_factory=dict)
    controllers: dict = field(default_factory=dict)
    rig: Rig | None = None
    ladder: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    check_plant: EvaluationPlant | None = None
    check_results: dict = field(default_factory=dict)
    check_metrics: dict = field(default_factory=dict)
    robust: dict = field(default_factory=dict)
    settings: CompareSettings | None = None


def _sim_settings(sim_settings, sc: Scenario) -> ClosedLoopSettings:
    """The closed loop's settings: the caller's, or the scenario's default with overrides."""
    default = sc.closed_loop_settings()
    if sim_settings is None:
        return default
    if isinstance(sim_settings, dict):                # fields checked by RunChoice
        return dataclasses.replace(default, **sim_settings)
    return sim_settings


def _check_runs_fit(t_end, dt, names, params: Params, sim_settings, what: str | None = None) -> None:
    """Refuse, before the scenario's reference is tabulated (which alone takes gigabytes for a
    ``t_end`` of 1e6 s) or planned, a comparison whose runs' arrays alone exceed the memory limit: a
    lower bound of :func:`_check_budget`'s estimate, with its message (``what``: how the runs' length
    came about, default the ``t_end`` given)."""
    if t_end is None or not isinstance(dt, (int, float)) or not isinstance(t_end, (int, float)):
        return
    if not (math.isfinite(t_end) and math.isfinite(dt) and t_end > 0 and dt > 0):
        return                                  # make_scenario names the bad value
    t_end, dt = (check_in_range(key, value, RANGES[key][2], *RANGES[key][:2])    # before t_end / dt
                 for key, value in (("t_end", t_end), ("dt", dt)))
    limit = ClosedLoopSettings().max_memory_mb
    if isinstance(sim_settings, ClosedLoopSettings):
        limit = sim_settings.max_memory_mb
    elif isinstance(sim_settings, dict) and "max_memory_mb" in sim_settings:
        limit = sim_settings["max_memory_mb"]
    steps = int(round(t_end / dt))
    memory = len(names) * _run_bytes(steps, params)
    check_budget(f"{what or f't_end = {t_end:g} s'} at dt = {dt:g} s ({len(names)} runs of {steps + 1} samples)",
                 memory_bytes=memory, seconds=0.0, max_memory_mb=limit, max_wall_s=math.inf)


def _run_bytes(steps: int, params: Params) -> float:
    """Memory estimate of one closed-loop run's arrays [bytes]: ``steps + 1`` samples of the
    coordinates, their rates and nine signals, at 16 bytes per number (the budget's margin)."""
    n_q = 1 + params.n_axial + params.n_transverse
    return 16.0 * (steps + 1) * (2 * n_q + 9)


def _design_modes(design_modes, design: Params, dt: float | None = None) -> tuple:
    """``(modes, note)`` of the design model: DesignChoice's (checked there), else the design parameters',
    fewer when the default plant could not be integrated at ``dt`` (:func:`default_design_modes`, its
    note); ``dt`` None: the parameters' as they are."""
    if design_modes is not None or dt is None:
        return (design.n_transverse if design_modes is None else design_modes), ""
    return default_design_modes(design, dt, tolerance=ClosedLoopSettings().frequency_tolerance)


def compare(rig=None, task="slew", controllers=None, settings: CompareSettings | None = None, *,
            designs: dict | None = None, progress: bool = False, designed=None) -> Comparison:
    """Design the controllers on SFOAM and run them on the nonlinear evaluation plant.

    The design model is SFOAM with the rig's beam (or ``settings.design.design_params``) and
    ``design_modes``; the plant is ``settings.plant.plant`` (FOAM by default) with
    ``plant_params`` (default: the design's) and, unless ``plant_modes`` says otherwise, every
    bending mode below the sampling frequency and at least three more than the design
    (:func:`~hubbeam_ctrl.sim.evaluation.evaluation_plant`).

    Parameters
    ----------
    rig : Rig or Params, optional
        The physical rig (:func:`hubbeam_ctrl.plant.rig.load_rig`): its beam is the parameters
        (with the reflected rotor inertia and the rig's damping), its sample time ``dt``
        (unless ``settings.run.dt``), and the evaluation plant carries its drive, friction and
        sensors; the controllers run as :func:`hubbeam_ctrl.study.rig_loop.on_rig` makes them
        (observer, integral action, voltage). A rig with ideal hardware gives the beam alone's
        numbers bit for bit. A :class:`~hubbeam_ctrl.plant.params.Params`: the beam alone
        (SI units); None: Table 1.
    task : str or Slew or SpinUp
        A registered scenario (``slew``, ``spinup``..., shaped by ``settings.scenario``) or a
        task in physical terms (:mod:`hubbeam_ctrl.study.tasks`; see :func:`make_scenario`).
    controllers : str or sequence of str, optional
        Registered controllers (``openloop, pd, lqr, lqg, mpc``...; a comma-separated string
        is accepted). Default: those registered as default.
    settings : CompareSettings, optional
        The plant, the design, the run, the scenario's shape and the payload
        (:mod:`hubbeam_ctrl.study.compare_values`; each field documented there with its units).
        ``design.reference`` ``"task"`` (default) is the scenario's reference: for a slew given by
        its angle, the slew planned on the design model so that the beam ends at rest
        (:func:`controllers.planning.planned_slew_reference`); for the paper's Eq. 44 slew and
        spin-ups, the rigid body's smooth reference. ``"optimal"``: the minimum-vibration slew of
        the nonlinear beam in ``t_f`` within the drive's limits
        (:func:`hubbeam_ctrl.limit.min_vibration_slew`; a ``t_f`` shorter than the time-optimal
        slew is refused naming the shortest). ``plant.check_plant``: every controller also runs
        on that plant; its results are in :attr:`Comparison.check_results` and
        :attr:`Comparison.check_metrics`, and each controller's metrics get ``check_plant``,
        ``check_verdict``, ``check_peak_tip_m``, ``check_residual_tip_max_m`` and
        ``check_outside_range_time_s``.
    designs : dict, optional
        Controller name -> :class:`controllers.robust.RangeDesign` (design model and
        settings) chosen beforehand.
    progress : bool
        Print one line per controller on stderr.
    designed : callable, optional
        Called once, with every controller designed and before the first closed-loop run, with
        a :class:`Comparison` holding the scenario, the styles, the evaluation plant and the
        linear controllers (no results yet): what a caller can start early, e.g. ``hubbeam
        compare``'s loop figure (:func:`hubbeam_ctrl.study.report.loop_png`), drawn by the
        figure worker while the controllers run. Given, the designs all come first (else each
        just before its run); the numbers are the same.

    Returns
    -------
    Comparison
    """
    start = time.perf_counter()
    settings = CompareSettings() if settings is None else settings
    if not isinstance(settings, CompareSettings):
        raise ParameterError(f"settings must be a CompareSettings (hubbeam_ctrl.study.compare_values), "
                             f"got {type(settings).__name__}")
    given = settings
    rig, params = as_rig(rig)
    pc, dc, rc, scn, pay = settings.plant, settings.design, settings.run, settings.scenario, settings.payload
    plant, plant_params, plant_modes, check_plant = pc.plant, pc.plant_params, pc.plant_modes, pc.check_plant
    design_params, design_modes, horizon, solver = dc.design_params, dc.design_modes, dc.horizon, dc.solver
    integral, limit, reference, shaping, schedule = dc.integral, dc.limit, dc.reference, dc.shaping, dc.schedule
    dt, t_end, sim_settings = rc.dt, rc.t_end, rc.sim_settings
    payload_range, payload_learning = pay.payload_range, pay.payload_learning
    backend = resolve_backend(pc.backend)
    names = _parse_controllers(controllers)
    rate_notes = []
    if rig is not None and not rig.sensors.rate and "pd" in names:
        if controllers is not None:         # refused before any run, naming the rig key
            raise ParameterError("controllers: pd reads the hub rate, and the rig has no rate sensor "
                                 "(sensors.rate = false); leave pd out")
        names = tuple(n for n in names if n != "pd")
        rate_notes = ["pd left out: it reads the hub rate, and the rig has no rate sensor (sensors.rate = false)"]
    if rig is not None:
        params = params if params is not None else rig.plant_params
        dt = dt if dt is not None else rig.timing.dt
    base = params if params is not None else Params()
    if dt is None:
        dt = task_dt(design_params if design_params is not None else base)
    design_p = design_params if design_params is not None else base
    task, scn, task_notes = task_on_rig(rig, task, scn)      # an ideal rig: the beam alone's task
    t_f = DEFAULT_T_F if scn.t_f is None else scn.t_f
    options = dict(plant=plant, params=design_p, tau_max=scn.tau_max, t_f=t_f, dt=dt, w_f=scn.w_f,
                   slew_angle=scn.slew_angle, tolerances=dc.tolerances,
                   reference=reference)
    least = 3.0 * (getattr(task, "duration", None) or t_f)      # without t_end the runs last at least 3 tf
    _check_runs_fit(least if t_end is None else t_end, dt, names, plant_params if plant_params is not None else base,
                    sim_settings, f"the task's runs (at least 3 tf = {least:.6g} s)" if t_end is None else None)
    sc = make_scenario(task, t_end=t_end, **options)    # None: the task's own
    sc = with_task_bands(sc, rig, scn.settle_angle, scn.settle_tip)
    m, modes_note = _design_modes(design_modes, sc.params, sc.dt if plant_modes is None else None)
    rate_notes += [modes_note] if modes_note else []
    ev = evaluation_plant(sc.plant, sc.params, sc.dt, m, sc.design_spin,
                          plant_params=plant_params if plant_params is not None else params,
                          plant_modes=plant_modes)
    ev_check = _check_plant(check_plant, sc, ev, m)
    settings = dict(dc.settings or {})
    unknown = sorted(set(settings) - set(names))
    if unknown:
        raise ParameterError(f"settings given for controllers not run: {', '.join(unknown)}")
    sim = _sim_settings(sim_settings, sc)
    if sim.dt != sc.dt:
        sim = dataclasses.replace(sim, dt=sc.dt)
    hardware = None
    if rig is not None:
        sim, hardware = rig_closed_loop(rig, sim)
    chosen = {name: settings.get(name) or CONTROLLERS[name].settings.for_scenario(sc, horizon=horizon,
                                                                                   solver=solver)
              for name in names}
    if rig is not None:
        chosen = {name: st if name in settings else rig_settings(name, st, rig, integral)
                  for name, st in chosen.items()}
        noise = task_noise(sc, rig)
    chosen = {name: residual_modes_for(st, ev.modes) for name, st in chosen.items()}
    _check_budget(sc, ev, chosen, m, sim, schedule)
    design = DesignModel.build(sc.params, sc.design_spin, sc.dt, m)
    if rig is not None:
        design = rig_design(design, rig)
        rate_notes += [hub_damping_note(design, rig)] if design.hub_damping else []
    shaper = None if shaping is None else as_shaper(design, shaping)
    sched = _design_schedule(sc, schedule, m)
    ref, ref_notes = tracked_reference(sc, reference, rig)
    if ref is not sc.reference:
        sc = dataclasses.replace(sc, reference=ref)
    chosen, notes = _shaped_durations(names, chosen, settings, design, dataclasses.replace(sc, reference=ref))
    if any(CONTROLLERS[n].tracks_reference for n in names):       # the reference's notes: for who tracks it
        notes = ref_notes + notes
    designs = dict(designs or {})
    if payload_range is not None:
        from hubbeam_ctrl.study.range_design import range_designs
        designs = {**range_designs(names, sc, design, payload_range, settings, horizon=horizon,
                                   solver=solver, sim=sim, plant_modes=plant_modes), **designs}
    elif rig is not None and rig.uncertainty.is_set:     # a scenario tree over the set's payloads
        from hubbeam_ctrl.study.range_design import set_scenario_designs
        trees = set_scenario_designs([n for n in names if n not in designs], sc, design, rig.uncertainty, chosen,
                                     sim=sim, plant_modes=plant_modes)
        notes = notes + [f"{n}: the scenario tree over the set's payload range ({d.choice})" for n, d in trees.items()]
        designs = {**trees, **designs}
    results, metrics, margins, certificates, linear = {}, {}, {}, {}, {}
    check_results, check_metrics, robust = {}, {}, {}
    yardstick = task_limit(sc, limit, rig)
    clock = WallClock(sim.max_wall_s)        # the whole comparison's wall-time limit
    budget = {}                              # each run's settings with the wall time left at its start

    def build(name):
        """The controller ``name`` as it runs (design, payload learning, the rig's hardware)."""
        spec = CONTROLLERS[name]
        d = designs[name].design if name in designs else design
        st = designs[name].settings if name in designs else chosen[name]
        own = sched
        if name in designs and sched is not None:    # a payload range's design: its schedule at its payload
            own = _design_schedule(dataclasses.replace(sc, params=d.params), schedule, m)
        if payload_learning is not None and hasattr(st, "learn_payload"):    # learns it itself (NMPC)
            st = _learning(st, payload_learning, sc, rig)
        ctrl = make_controller(name, d, st, ref, shaping=shaper if spec.tracks_reference else None,
                               schedule=own if spec.scheduled else None)
        if payload_learning is not None and name in LEARNING_CONTROLLERS:
            ctrl = _learning(ctrl, payload_learning, sc, rig)
        if rig is not None:
            ctrl = on_rig(ctrl, rig, noise, hardware, integral)
            rate_notes.extend(count_note(name, ctrl))
        linear[name] = ctrl

    def designs_done():
        """Every design's margins, then ``designed``: side by side, here while the child runs its share."""
        for name in names:
            margins[name] = _margins(linear[name])
        if designed is not None:
            designed(Comparison(sc, {}, {}, styles={n: CONTROLLERS[n].style for n in names}, plant=ev, rig=rig,
                                controllers={n: c for n, c in linear.items() if margins[n] is not None}))

    def run(name):
        """``(result, metrics, certificate)`` of controller ``name`` in closed loop (None: out of time)."""
        if clock.expired():
            return None
        run_sim = budget[name] = dataclasses.replace(sim, max_wall_s=max(1e-3, sim.max_wall_s - clock.elapsed()))
        res = simulate_closed_loop(ev, linear[name], sc.t_end, settings=run_sim,
                                   reference=(ref.theta_at, ref.theta_dot_at), backend=backend, hardware=hardware)
        mm, cert = judge(res, linear[name], sc, ev.params, name, limit=yardstick)
        mm["scenario"] = sc.name
        return res, mm, cert

    # the runs side by side (a forked child runs part of them) when nothing ties them together
    together = ((SIDE_BY_SIDE or rc.side_by_side) and can_fork() and len(names) > 1 and ev_check is None
                and payload_learning is None and not (rig is not None and rig.uncertainty.is_set))
    first = together or designed is not None     # every design before the first run
    if first:
        for name in names:
            build(name)
    if together:
        runs = side_by_side(names, run, here=designs_done)
    elif first:
        designs_done()
    for name in names:
        if not together:
            if clock.expired():
                break
            if not first:
                build(name)
                margins[name] = _margins(linear[name])
            runs = {name: run(name)}
        if runs[name] is None:
            break
        res, metrics[name], certificates[name] = runs[name]
        results[name] = res
        ctrl = linear[name]
        if rig is not None and rig.uncertainty.is_set and margins[name] is not None:
            robust[name] = certify_set(ctrl, rig, plant_modes=ev.modes, name=name,
                                       spins=(float(ref.theta_dot[0]), float(ref.theta_dot[-1])))
            metrics[name].update(robust[name].metrics())
        if ev_check is not None:
            res_c = simulate_closed_loop(ev_check, ctrl, sc.t_end, settings=budget[name],   # as the plant's run
                                         reference=(ref.theta_at, ref.theta_dot_at), backend=backend,
                                         hardware=hardware)
            check_results[name] = res_c
            check_metrics[name], _ = judge(res_c, ctrl, sc, ev_check.params, name, limit=yardstick)
            mc = check_metrics[name]
            metrics[name].update(check_plant=ev_check.model, check_verdict=mc["verdict"],
                                 check_peak_tip_m=mc["peak_tip_m"], check_residual_tip_max_m=mc["residual_tip_max_m"],
                                 check_outside_range_time_s=mc["outside_range_time_s"])
        name_causes(metrics[name], res, ctrl, margins[name], sc, ev, float(ref.theta_dot[-1]), rig)
        if progress:
            mm = metrics[name]
            print(f"compare {sc.plant}/{sc.name}: {name:8s} {mm['verdict']:11s} residual "
                  f"{mm['residual_tip_max_m']:.3e} m, run {res.wall_s:.1f} s"
                  + ("" if mm["completed"] else f"  [{res.message}]"), file=sys.stderr)
    notes += against_openloop(metrics, sc.bands["settle_tip"])
    notes = task_notes + rate_notes + notes + same_laws(linear, metrics)
    return Comparison(sc, results, metrics, time.perf_counter() - start,
                      styles={n: CONTROLLERS[n].style for n in names},
                      targets=tuple(n for n in names if CONTROLLERS[n].target), plant=ev,
                      margins={n: lm for n, lm in margins.items() if lm is not None},
                      certificates=certificates,
                      controllers={n: c for n, c in linear.items() if margins[n] is not None}, rig=rig,
                      notes=notes, check_plant=ev_check, check_results=check_results, check_metrics=check_metrics,
                      robust=robust, settings=None if designs else given)


def _check_plant(check_plant, sc: Scenario, ev: EvaluationPlant, design_modes: int):
    """The second plant of ``check_plant=`` (None without one): the evaluation plant's
    parameters and modes on another model."""
    if check_plant is None:                  # its name is checked by PlantChoice
        return None
    if check_plant == "ancf":
        require_exudyn("check_plant='ancf'")
    return evaluation_plant(check_plant, sc.params, sc.dt, design_modes, sc.design_spin,
                            plant_params=ev.params, plant_modes=ev.modes)


#: Controllers that learn the payload with ``PayloadChoice(payload_learning=...)`` of ``compare`` by
#: re-planning (state feedback, and the LQG from its filter's estimate); a controller whose settings
#: have a ``learn_payload`` field (the NMPC) learns it itself over the same range.
LEARNING_CONTROLLERS = ("lqr", "mpc", "lqg")


def _learning(ctrl_or_settings, settings, sc, rig):
    """``ctrl`` wrapped in :class:`controllers.payload_learning.PayloadLearning` for the slew ``sc``,
    or a self-learning controller's settings with the range of ``settings``."""
    from controllers.payload_learning import PayloadLearning
    if rig is not None or not isinstance(sc.task, Slew):
        raise ParameterError("payload_learning works on slew tasks without a rig (a rig's drive and sensors: not yet)")
    if hasattr(ctrl_or_settings, "learn_payload"):
        return ctrl_or_settings.replace(learn_payload=True, payload_min_kg=settings.payload_min_kg,
                                        payload_max_kg=settings.payload_max_kg)
    return PayloadLearning(ctrl_or_settings, settings, float(sc.reference.theta[-1]), sc.t_f, make_controller)


def _margins(ctrl):
    """Loop margins of a linear controller on its design model (None for the others)."""
    try:
        ctrl.feedback_matrices()
    except HubbeamError:
        return None
    return loop_margins(ctrl)


def _check_budget(sc: Scenario, ev, chosen: dict, design_modes: int, sim: ClosedLoopSettings,
                  schedule=1) -> None:
    """Refuse a comparison whose memory or time estimate exceeds ``sim``'s limits, before any
    design work (see :mod:`hubbeam_ctrl.core.budget`); a scheduled MPC holds one set of
    matrices per design point."""
    points = schedule if isinstance(schedule, int) and not isinstance(schedule, bool) and schedule > 1 else 1
    p = ev.params                            # the evaluation plant's
    n_q = 1 + p.n_axial + p.n_transverse
    steps = int(round(sc.t_end / sc.dt))
    n_x = 2 * (1 + design_modes)
    run_bytes = _run_bytes(steps, p)
    run_seconds = steps * CLOSED_LOOP_SECONDS_PER_SAMPLE * (n_q / 11.0) ** 2
    memory = len(chosen) * run_bytes
    seconds = len(chosen) * run_seconds + model_build_seconds(ev.model, p.n_transverse)
    what = f"t_end = {sc.t_end:g} s at dt = {sc.dt:g} s ({len(chosen)} runs of {steps + 1} samples)"
    horizons = [getattr(st, "horizon", None) for st in chosen.values()]
    horizons = [h for h in horizons if h]
    if horizons:
        N = max(horizons)
        copies = points if any(CONTROLLERS[n].scheduled for n, st in chosen.items() if getattr(st, "horizon", None)) \
            else 1
        memory += copies * mpc_bytes(N, n_x)
        seconds += mpc_seconds(N, n_x, steps) + (copies - 1) * mpc_seconds(N, n_x, 0)
        what += f" with horizon = {N}" + (f" at {copies} design points" if copies > 1 else "")
    elif points > 1:
        what += f" at {points} design points"
    seconds += 0.002 * (points - 1) * sum(bool(CONTROLLERS[n].scheduled) for n in chosen)
    check_budget(what, memory_bytes=memory, seconds=seconds, max_memory_mb=sim.max_memory_mb,
                 max_wall_s=sim.max_wall_s)


def run_compare(rig=None, task="slew", controllers=None, settings: CompareSettings | None = None, *,
                out_dir=None, designs: dict | None = None, progress: bool = False) -> dict:
    """Run :func:`compare` and write its outputs to ``out_dir`` (if given).

    Parameters
    ----------
    rig : Rig or Params, optional
        The rig, the beam alone, or None (Table 1).
    task : str or Slew or SpinUp
        A registered scenario or a task.
    controllers : str or sequence of str, optional
        Registered controllers (default: those registered as default).
    settings : CompareSettings, optional
        The plant, design, run, scenario and payload values (:mod:`hubbeam_ctrl.study.compare_values`).
    out_dir : str or Path, optional
        Folder for metrics.csv, metrics.json, the PNG plots and report.md.
    designs : dict, optional
        Controller name -> :class:`controllers.robust.RangeDesign` chosen beforehand.
    progress : bool
        Print one line per controller on stderr.

    Returns
    -------
    dict
        Controller name -> metrics (see :data:`hubbeam_ctrl.study.metrics.METRIC_UNITS`), in the
        order run; pass it to :func:`print_table`.
    """
    comparison = compare(rig, task, controllers, settings, designs=designs, progress=progress)
    if out_dir is not None:
        write_outputs(comparison, out_dir)
    return comparison.metrics
