"""Closed-loop scenarios: the task (reference, torque budget, times) and its design point.

Scenarios are registered once in :data:`SCENARIOS` with :func:`register_scenario`; the
comparison and the CLI (``--scenario`` choices and help) read the registry. Built in:
``slew`` (rest-to-rest by ``slew_angle``, by default the Eq. 44 rigid angle) and ``spinup`` (the corrected Eq. 43
profile, then hold); their builders' docstrings say more.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from controllers import DesignModel, Reference, planned_slew_reference, slew_reference, spinup_reference
from controllers.scaling import (
    Tolerances,
    default_tolerances,
    first_mode,
    reference_shaping,
    scaled_defaults,
    sensor_noise,
    settling_bands,
    task_scales,
)
from hubbeam_ctrl.core.budget import T_END_MAX
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.stored import stored_arrays
from hubbeam_ctrl.core.validation import check_in_range
from hubbeam_ctrl.plant.params import Params, check_spin
from hubbeam_ctrl.plant.sensors import SensorSettings
from hubbeam_ctrl.sim.closedloop import ClosedLoopSettings
from hubbeam_ctrl.sim.evaluation import PLANT_MODELS
from hubbeam_ctrl.study.bands import default_band_sources
from hubbeam_ctrl.study.tasks import MAX_DURATION, Slew, SpinUp, check_target

__all__ = ["RANGES", "SCENARIOS", "PLANTS", "REFERENCES", "Scenario", "make_scenario", "register_scenario"]

#: Hub references a scenario can give its controllers (see :func:`make_scenario`).
REFERENCES = ("task", "rigid", "planned", "optimal")

#: Scenario name -> builder, in registration order (see :func:`register_scenario`).
SCENARIOS: dict = {}
#: The nonlinear plants a scenario runs on (the models with dynamic stiffening and axial modes).
PLANTS = PLANT_MODELS


def register_scenario(name: str):
    """Register a scenario builder under ``name`` (a decorator).

    The builder is called by :func:`make_scenario` with the validated keyword arguments
    ``params``, ``tau_max``, ``t_f``, ``dt``, ``t_ref_end`` (last reference sample [s]),
    ``w_f``, ``flatness`` and ``task`` (the task in physical terms,
    :mod:`hubbeam_ctrl.study.tasks`, already checked against ``tau_max``; None for a scenario
    without one), ``budget`` (how a message names ``tau_max``: ``"tau_max"`` when the caller
    gave it, else the motor's ``Params.tau_max``) (it takes those it needs and ``**_`` for the
    rest) and returns a dict with
    ``design_spin`` [rad/s], ``target``, ``target_key`` (its name with unit in summaries),
    ``baseline`` (the open-loop profile compared against: ``"eq44"`` or ``"feedforward"``),
    ``reference``, ``description`` and optionally ``baseline_tau_m`` (the Eq. 44 amplitude).

    Parameters
    ----------
    name : str
        Scenario name.

    Returns
    -------
    callable
        The decorator (returns the builder unchanged).
    """
    def register(builder):
        SCENARIOS[name] = builder
        return builder
    return register


#: Ranges of :func:`make_scenario`'s numbers: name as in messages -> (lo, hi, unit). Also
#: ``t_end > tf (1 + residual_delay)`` (the task's Tolerances), ``dt <= tf / 10``,
#: ``abs(wf) <= params.max_spin`` and, for the slew, ``tau_max tf / (pi J_total) <= params.max_spin``.
RANGES = {"tau_max": (1e-6, 1e9, "N m"), "tf": (1e-3, MAX_DURATION, "s"), "t_end": (1e-3, T_END_MAX, "s"),
          "dt": (1e-6, 10.0, "s")}


@dataclass(frozen=True, eq=False)
class Scenario:
    """A closed-loop task: reference, torque budget, times and design point.

    Attributes
    ----------
    name : str
        Registered scenario name (:data:`SCENARIOS`).
    plant : {"foam", "cfoam"}
    params : Params
        Parameters of the design model (the reference uses their rigid-body inertia).
    tau_max : float
        Torque budget [N m] (= Eq. 44's tau_m in the slew).
    t_f : float
        Maneuver time [s].
    t_end : float
        Simulated time [s].
    dt : float
        Controller sample time [s].
    design_spin : float
        Spin rate of the SFOAM linearisation [rad/s].
    target : float
        Slew angle Theta [rad] or final rate w_f [rad/s].
    reference : controllers.Reference
        Hub reference and feedforward torque of the feedback controllers.
    description : str
    target_key : str
        Name (with unit suffix) of ``target`` in :meth:`to_dict`.
    baseline : {"eq44", "feedforward"}
        The open-loop profile the scenario compares against
        (:class:`controllers.OpenLoopSettings`).
    baseline_tau_m : float or None
        Amplitude of the Eq. 44 baseline [N m]: ``2 pi J_total Theta / t_f^2`` for a slew
        (``tau_max`` itself for the Eq. 44 angle); None without an Eq. 44 baseline.
    task : Slew or SpinUp or None
        The task in physical terms (:mod:`hubbeam_ctrl.study.tasks`).
    tolerances : controllers.scaling.Tolerances
        The dimensionless tolerances that made the defaults below.
    scales : controllers.scaling.TaskScales or None
        The task's scales (angle, time, L, first mode, torque, signal ranges).
    defaults : dict
        Controller settings by field name from the scales (weights, Kalman noise, PD
        bandwidth; read by ``ControllerSettings.for_scenario``).
    sensors : dict
        Sensor noise levels of the evaluation (fields of
        :class:`~hubbeam_ctrl.plant.sensors.SensorSettings`).
    bands : dict
        ``settle_angle`` [rad], ``settle_tip`` [m] and ``residual_delay`` [s] of the metrics.
    band_sources : dict
        ``settle_angle`` and ``settle_tip`` -> where that band came from, one line (the task's
        default here; a rig's angle sensor or the user's own bands through
        :func:`hubbeam_ctrl.study.bands.with_task_bands`).
    """

    name: str
    plant: str
    params: Params
    tau_max: float
    t_f: float
    t_end: float
    dt: float
    design_spin: float
    target: float
    reference: object
    description: str
    target_key: str = "target"
    baseline: str = "feedforward"
    baseline_tau_m: float | None = None
    task: object = None
    tolerances: object = None
    scales: object = None
    defaults: dict = None
    sensors: dict = None
    bands: dict = None
    band_sources: dict = None

    def closed_loop_settings(self, seed: int | None = None):
        """The closed loop's default settings for this task: its sample time and the sensor
        noise scaled to its signals (:attr:`sensors`).

        Parameters
        ----------
        seed : int, optional
            Seed of the sensor noise (default: the sensors' default).

        Returns
        -------
        hubbeam_ctrl.sim.closedloop.ClosedLoopSettings
        """
        noise = dict(self.sensors or {})
        if seed is not None:
            noise["seed"] = int(seed)
        return ClosedLoopSettings(dt=self.dt, sensors=SensorSettings(**noise))

    def to_dict(self) -> dict:
        """Plain-data summary (JSON-ready)."""
        return {"scenario": self.name, "plant": self.plant, "tau_max_nm": self.tau_max,
                "tf_s": self.t_f, "t_end_s": self.t_end, "dt_s": self.dt,
                "design_spin_rad_s": self.design_spin,
                self.target_key: self.target,
                "reference": self.reference.description, "params": self.params.to_dict(),
                "baseline_tau_m_nm": self.baseline_tau_m, "description": self.description,
                "scales": self.scales.to_dict() if self.scales is not None else None,
                "tolerances": self.tolerances.to_dict() if self.tolerances is not None else None,
                "sensors": self.sensors, "bands": self.bands, "band_sources": self.band_sources}


def make_scenario(scenario="slew", *, plant: str = "foam", params: Params | None = None,
                  tau_max: float | None = None, t_f: float = 10.0, t_end: float | None = 30.0,
                  dt: float = 0.01, w_f: float = 3.0, slew_angle: float | None = None,
                  flatness: float | None = None, smoothing: float | None = None,
                  tolerances: Tolerances | None = None, preview_s: float = 2.0,
                  reference: str = "task") -> Scenario:
    """Build a :class:`Scenario` (validating every setting).

    Parameters
    ----------
    scenario : str or Slew or SpinUp
        A registered scenario (:data:`SCENARIOS`: ``slew``, ``spinup``), or a task in physical
        terms (:mod:`hubbeam_ctrl.study.tasks`) that gives the angle or rate and the duration
        (``t_f``, ``w_f`` and ``slew_angle`` are then not used).
    plant : {"foam", "cfoam"}
    params : Params, optional
        Default: Table 1 (m_t = 0.1 kg at the tip).
    tau_max : float, optional
        Torque budget [N m], in [1e-6, 1e9] and at most ``params.tau_max`` (default: the
        motor's ``params.tau_max``). Without ``slew_angle`` the slew turns by the rigid angle
        of Eq. 44 with amplitude ``tau_max``; the slew's peak rigid rate ``2 Theta / t_f``
        must not exceed ``params.max_spin``.
    t_f : float
        Maneuver time [s], in [1e-3, 1e6].
    t_end : float or None
        Simulated time [s], at most 1e9; must exceed the start of the residual window,
        ``t_f (1 + tolerances.residual_delay)`` (15 s for the default 10 s slew). None: the
        task's own (:func:`hubbeam_ctrl.study.yardstick.task_t_end`), for a task of any length.
    dt : float
        Controller sample time [s], in [1e-6, 10] and at most ``t_f / 10``.
    w_f : float
        Spin-up final rate [rad/s] (spinup only), ``|w_f| <= params.max_spin``.
    slew_angle : float, optional
        Slew angle [rad], finite and not 0 (slew only); default: the Eq. 44 angle
        ``tau_max t_f^2 / (2 pi J_total)``.
    flatness, smoothing : float, optional
        Shape [-] and acceleration smoothing [s] of the slew reference (see
        :func:`controllers.slew_reference`); default: from the beam and the task
        (:func:`controllers.scaling.reference_shaping`).
    tolerances : controllers.scaling.Tolerances, optional
        Dimensionless tolerances that scale the defaults (weights, noise levels, settling
        bands, residual window, reference shaping) to the beam and the task.
    preview_s : float
        Reference tabulated this long beyond ``t_end`` (MPC preview) [s].
    reference : {"task", "rigid", "planned", "optimal"}
        The hub reference of the controllers that track one (:data:`REFERENCES`). ``"task"``
        (default): for a slew given by its angle (a :class:`~hubbeam_ctrl.study.tasks.Slew`
        or ``slew_angle``) the slew planned on the design model so that the beam ends at
        rest (:func:`controllers.planning.planned_slew_reference`); for the paper's Eq. 44
        slew (no angle given) and for spin-ups the rigid body's smooth reference, as in the
        paper. ``"rigid"``: always the rigid body's smooth reference
        (:func:`controllers.slew_reference`). ``"planned"``: always the planned slew (a slew
        only). ``"optimal"``: the caller tracks the beam's nonlinear minimum-vibration slew
        (:func:`hubbeam_ctrl.limit.min_vibration_slew`, which decides whether the motor can do the
        task): the scenario holds the rigid reference, for the scales only, and skips the rigid
        Eq. 44 profile's torque check (a slew near the time-optimal one needs more peak torque
        on that profile than the motor has). The scales of the defaults (weights, bands, noise) come from the rigid
        reference in every case.

    Returns
    -------
    Scenario

    Raises
    ------
    ParameterError
        Among others when the task needs more torque than ``tau_max``: the message names
        the shortest feasible ``tf`` (``duration`` for a task object).
    """
    if isinstance(scenario, (Slew, SpinUp)):
        name, task, tf_name = scenario.name, scenario, "duration"
        t_f = task.duration
    elif isinstance(scenario, str) and scenario in SCENARIOS:
        name, task, tf_name = scenario, None, "tf"
    else:
        raise ParameterError(f"scenario must be one of {', '.join(SCENARIOS)} or a Slew or SpinUp "
                             f"task, got {scenario!r}")
    if plant not in PLANTS:
        raise ParameterError(f"plant must be one of {', '.join(PLANTS)}, got {plant!r}")
    if reference not in REFERENCES:
        raise ParameterError(f"reference must be one of {', '.join(REFERENCES)}, got {reference!r}")
    if reference in ("planned", "optimal") and name != "slew":
        raise ParameterError(f"reference = {reference!r} applies to a slew, not a {name}")
    params = params if params is not None else Params()
    if not isinstance(params, Params):
        raise ParameterError(f"params must be a Params, got {type(params).__name__}")
    budget = "tau_max" if tau_max is not None else "the motor's Params.tau_max (beam.tau_max of a rig)"
    tau_given, tau_max = tau_max, _budget(tau_max, params)
    derive = t_end is None
    t_f, dt = (check_in_range(key, value, RANGES[key][2], *RANGES[key][:2]) for key, value in (("tf", t_f), ("dt", dt)))
    tol = tolerances if tolerances is not None else default_tolerances(
        task.name if task is not None else name, params.J_h / params.total_inertia)
    if not isinstance(tol, Tolerances):
        raise ParameterError(f"tolerances must be a Tolerances, got {type(tol).__name__}")
    start = t_f * (1 + tol.residual_delay)
    # the task's own t_end is read from a scenario built first with one past the window's start
    t_end = check_in_range("t_end", max(3.0 * t_f, 2.0 * start) if derive else t_end, RANGES["t_end"][2],
                           *RANGES["t_end"][:2])
    if t_end <= start:
        raise ParameterError(f"t_end must exceed tf + {tol.residual_delay:g} tf = {start:g} s (the "
                             f"residual-vibration window starts there), got {t_end:g} s")
    if dt > t_f / 10:
        raise ParameterError(f"dt must be at most tf/10 = {t_f / 10:g} s, got {dt:g} s")
    J = params.total_inertia
    eq44 = task is None and name == "slew" and slew_angle is None
    if task is None:
        task = _task(name, tau_max, t_f, w_f, slew_angle, params)
    if task is not None and reference != "optimal":      # the optimal planner decides that one
        task.check_feasible(J, tau_max, tf_name)
    parts = SCENARIOS[name](params=params, tau_max=tau_max, t_f=t_f, dt=dt, t_ref_end=t_end + preview_s,
                            w_f=w_f, flatness=flatness, smoothing=smoothing, tolerances=tol, task=task,
                            eq44=eq44, reference=reference, budget=budget)
    scale_reference = parts.pop("scale_reference", parts["reference"])
    sc = Scenario(name, plant, params, tau_max, t_f, t_end, dt, task=task, tolerances=tol,
                  **parts, **_scaled(params, tau_max, t_f, dt, task, dict(parts, reference=scale_reference), tol))
    if derive:
        from hubbeam_ctrl.study.yardstick import task_t_end
        own = task_t_end(sc)
        if own != sc.t_end:
            return make_scenario(scenario, plant=plant, params=params, tau_max=tau_given, t_f=t_f, t_end=own, dt=dt,
                                 w_f=w_f, slew_angle=slew_angle, flatness=flatness, smoothing=smoothing,
                                 tolerances=tolerances, preview_s=preview_s, reference=reference)
    return sc


@functools.lru_cache(maxsize=8)
def _design_point(params: Params, spin: float, dt: float) -> DesignModel:
    """The design model the scales are read from (cached: the comparison builds it again)."""
    return DesignModel.build(params, spin, dt)


def _scaled(params: Params, tau_max: float, t_f: float, dt: float, task, parts: dict, tol: Tolerances) -> dict:
    """Scales, scaled controller defaults, sensor noise and metric bands of a scenario."""
    if task is None:                   # a registered scenario without a task: the paper's numbers
        bands = {"settle_angle": 1e-3, "settle_tip": 1e-3, "residual_delay": 5.0}
        return {"scales": None, "defaults": {}, "sensors": {}, "bands": bands,
                "band_sources": default_band_sources(bands)}
    angle = task.angle if task.name == "slew" else abs(task.rate) * t_f / 2
    design = _design_point(params, parts["design_spin"], dt)
    scales = task_scales(design, parts["reference"], angle, t_f, tau_max)
    bands = settling_bands(scales, tol)
    return {"scales": scales, "defaults": scaled_defaults(scales, tol), "sensors": sensor_noise(scales, tol),
            "bands": bands, "band_sources": default_band_sources(bands, scales, tol)}


def _budget(tau_max, params: Params) -> float:
    """The scenario's torque budget: ``tau_max`` or the motor's, never above the motor's [N m]."""
    if tau_max is None:
        return params.tau_max
    tau_max = check_in_range("tau_max", tau_max, RANGES["tau_max"][2], *RANGES["tau_max"][:2])
    if tau_max > params.tau_max:
        raise ParameterError(f"tau_max must be in (0, {params.tau_max:g}] N m (the motor's "
                             f"Params.tau_max), got {tau_max:g}")
    return tau_max


def _task(name: str, tau_max: float, t_f: float, w_f, slew_angle, params: Params):
    """The task of a built-in scenario from its options (None for other registered scenarios)."""
    if slew_angle is not None and name != "slew":
        raise ParameterError("slew_angle applies to the slew scenario only")
    if name == "spinup":
        return SpinUp(check_target("wf", check_spin("wf", w_f, params), "rad/s", "a spin-up to rest is no task"), t_f)
    if name != "slew":
        return None
    if slew_angle is None:
        return Slew.eq44(tau_max, t_f, params.total_inertia)
    angle = check_target("slew_angle", slew_angle, "rad", "a slew by 0 is no task")
    largest = params.max_spin * RANGES["tf"][1] / 2     # 2 |Theta| / tf <= max_spin in the longest tf
    if abs(angle) > largest:
        raise ParameterError(f"slew_angle must be a finite number with |slew_angle| <= {largest:.5g} [rad] (a slew "
                             f"in the longest tf, {RANGES['tf'][1]:g} s, within Params.max_spin), got {angle:g}")
    return Slew(angle, t_f)


@register_scenario("slew")
def _slew(*, params, tau_max, t_f, dt, t_ref_end, flatness=None, smoothing=None, tolerances=None, task=None,
          eq44=False, reference="task", budget="tau_max", **_) -> dict:
    """Rest-to-rest slew by ``task.angle`` in tf (default: the rigid-body angle of Eq. 44).

    Without an angle, ``Theta = tau_m t_f^2 / (2 pi J_total)`` with ``tau_m = tau_max``. The
    baseline is the open-loop Eq. 44 torque scaled to the angle and time,
    ``tau_m = 2 pi J_total Theta / t_f^2``; the feedback controllers follow a smooth
    reference (:func:`controllers.slew_reference`, shaped for the beam and the task by
    :func:`controllers.scaling.reference_shaping` unless ``flatness``/``smoothing`` are
    given) designed on SFOAM linearised at rest.
    """
    J = params.total_inertia
    if task is None:                       # called without a task: the Eq. 44 angle
        task, eq44 = Slew.eq44(tau_max, t_f, J), True
    theta = task.angle
    peak = 2 * abs(theta) / t_f            # the Eq. 44 profile's peak rigid rate for this angle
    if peak > params.max_spin:
        what = f"{budget} = {tau_max:g} N m over tf = {t_f:g} s" if eq44 else f"a slew by {theta:g} rad in {t_f:g} s"
        raise ParameterError(f"{what} spins the hub up to {peak:.4g} rad/s (2 Theta / tf), above "
                             f"Params.max_spin = {params.max_spin:.4g} rad/s (1 % centrifugal strain at the root)")
    shape = reference_shaping(theta, t_f, J, tau_max, first_mode(_design_point(params, 0.0, dt)),
                              tolerances or Tolerances())
    shape = {"flatness": shape["flatness"] if flatness is None else flatness,
             "smoothing": shape["smoothing"] if smoothing is None else smoothing}
    # with the nonlinear plan tracked, the rigid reference only gives the scales: its own torque
    # may exceed the motor's near the time-optimal slew
    shape_budget = tau_max
    if reference == "optimal":
        from controllers.reference import slew_shape_constant
        need = J * abs(theta) / (slew_shape_constant(shape["flatness"]) * (t_f - shape["smoothing"]) ** 2)
        shape_budget = max(tau_max, (1 + 1e-9) * need)
    ref = slew_reference(theta, t_f, J, shape_budget, dt, t_ref_end, **shape)
    text = (f"rest-to-rest slew by Theta = tau_m tf^2/(2 pi J_total) = {theta:.4f} rad "
            f"(tau_m = {tau_max:g} N m, tf = {t_f:g} s, J_total = {J:.4g} kg m^2)") if eq44 else task.describe(J)
    parts = dict(design_spin=0.0, target=theta, target_key="slew_angle_rad", baseline="eq44", reference=ref,
                 baseline_tau_m=tau_max if eq44 else task.baseline_torque(J), description=text)
    if reference == "planned" or (reference == "task" and not eq44):
        planned = _planned(params, theta, t_f, tau_max, dt, t_ref_end)
        parts.update(reference=planned, scale_reference=ref, description=f"{text}; {planned.description}")
    elif reference == "task":
        # the paper's Eq. 44 slew uses the whole torque limit at its peaks: the feedback designs
        # follow a slew planned within the reference's share of it, which leaves them room to act
        # without banging between the limits (issue 36)
        share = (tolerances or Tolerances()).feedforward_share
        try:
            planned = _planned(params, theta, t_f, share * tau_max, dt, t_ref_end)
        except ParameterError:          # the share cannot turn the hub in t_f: the rigid reference
            planned = None
        if planned is not None:
            parts.update(reference=planned, scale_reference=ref,
                         description=f"{text}; {planned.description} within {share:g} x tau_max")
    return parts


#: The sources of a planned slew (:func:`_planned`): the planner, the design model and the beam.
PLAN_SOURCES = ("controllers", "hubbeam_ctrl/core", "hubbeam_ctrl/linear", "hubbeam_ctrl/plant")


def _planned(params: Params, theta: float, t_f: float, tau_max: float, dt: float, t_end: float) -> Reference:
    """:func:`controllers.planning.planned_slew_reference`, kept in the build cache
    (:func:`~hubbeam_ctrl.core.stored.stored_arrays`): its two KKT solves took 0.2-1 s of every
    comparison's start; a later process reads the same reference bit for bit."""
    def compute():
        r = planned_slew_reference(params, theta, t_f, tau_max, dt, t_end)
        return {"theta": r.theta, "theta_dot": r.theta_dot, "theta_ddot": r.theta_ddot, "torque": r.torque,
                "elastic": r.elastic, "description": np.array(r.description),
                "plan": np.array([r.dt, *r.plan[:3]], dtype=float)}
    a = stored_arrays(("planned_slew", params, theta, t_f, tau_max, dt, t_end), compute, PLAN_SOURCES)
    step, angle, duration, budget = (float(x) for x in a["plan"])
    return Reference(step, *(np.array(a[k]) for k in ("theta", "theta_dot", "theta_ddot", "torque")),
                     str(a["description"]), elastic=np.array(a["elastic"]), planned_on_design=True,
                     plan=(angle, duration, budget, None))


@register_scenario("spinup")
def _spinup(*, params, tau_max, t_f, dt, t_ref_end, w_f=3.0, task=None, **_) -> dict:
    """Spin-up to ``task.rate`` (default wf) along the corrected Eq. 43 profile in tf, then hold.

    The default ``w_f`` (3 rad/s) is above TLAM's critical speed; the design model is
    linearised at ``w_f``. The baseline is the rigid-body feedforward torque alone.
    """
    w_f = check_spin("wf", task.rate if task is not None else w_f, params)
    ref = spinup_reference(w_f, t_f, params.total_inertia, dt, t_ref_end, tau_max=tau_max)
    return dict(design_spin=w_f, target=w_f, target_key="final_rate_rad_s", baseline="feedforward",
                reference=ref,
                description=f"spin-up to {w_f:g} rad/s in tf = {t_f:g} s (Eq. 43), then hold; "
                            f"design model linearised at {w_f:g} rad/s")
