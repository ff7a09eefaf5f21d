"""Closed-loop simulation: a sampled controller on a nonlinear plant.

The controller is called at the sample instants ``t_k = k dt`` with the measurement
``y(t_k)`` and returns a hub torque, which is held over ``[t_k, t_k + dt)`` (zero-order
hold); in between, the nonlinear plant (FOAM, CFOAM, TLAM or SFOAM with a free hub) is
integrated continuously by :class:`PlantStepper`.

The plant is advanced by :class:`hubbeam_ctrl.sim.stepper.PlantStepper` (one compiled
CasADi call per sample), so a closed-loop step costs one Python call for the plant and one
for the controller.

The controller is any object with

* ``__call__(t, y) -> float``: hub torque [N m] at time ``t`` [s] from measurement ``y``;
* ``reset()``: prepare a new run;
* ``measurement``: ``"state"`` or ``"sensors"`` (see :func:`simulate_closed_loop`);
* optionally ``signals``: the names of the rig's signals a ``"sensors"`` controller reads, in
  order (:func:`~hubbeam_ctrl.plant.instruments.signal_names`; default
  :data:`~hubbeam_ctrl.sim.measurement.DEFAULT_SIGNALS`);
* optionally ``name``, ``dt`` (its sample time, checked against the simulator's),
  ``n_modes`` (the transverse modes of its design model), ``state_modes`` (those it reads
  with ``measurement="state"``, default ``n_modes``), ``design`` (with ``params`` and
  ``spin``: the design model's parameters and spin rate, used to choose the evaluation
  plant and its integration step) and ``stats() -> dict``.

This module is plant side: it does not import the ``controllers`` package.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, fields
from functools import lru_cache

import numpy as np

from hubbeam_ctrl.core.budget import CLOSED_LOOP_SECONDS_PER_SAMPLE, T_END_MAX, check_budget
from hubbeam_ctrl.core.errors import HubbeamError, ParameterError
from hubbeam_ctrl.core.settings import setting
from hubbeam_ctrl.core.validation import check_in_range
from hubbeam_ctrl.exact import ExactBeamPlant, element_rule, require_exudyn
from hubbeam_ctrl.plant.modal import modal_analysis
from hubbeam_ctrl.plant.models import HubBeamModel, build_model, resolve_model
from hubbeam_ctrl.plant.params import MAX_MODES, Params
from hubbeam_ctrl.plant.sensors import SensorSettings, sensor_matrix
from hubbeam_ctrl.sim.evaluation import EvaluationPlant, evaluation_plant
from hubbeam_ctrl.sim.hardware import Hardware
from hubbeam_ctrl.sim.measurement import rig_measurement
from hubbeam_ctrl.sim.results import Result
from hubbeam_ctrl.sim.step_rule import SUBSTEP_BUDGET
from hubbeam_ctrl.sim.stepper import MAX_SUBSTEPS, PlantStepper, StepperSettings, substep_rule

__all__ = ["ClosedLoopSettings", "simulate_closed_loop"]


@dataclass(frozen=True)
class ClosedLoopSettings(StepperSettings):
    """Settings of :func:`simulate_closed_loop`: the plant integrator's (``dt`` is also the
    controller's sample period and the zero-order hold's), the sensors and when to stop."""

    substeps: int | None = setting(None, kind=int, lo=1, hi=MAX_SUBSTEPS,
                                   doc="Integration steps of the plant per sample; None (default): the "
                                       "fewest that keep every bending mode of the plant within "
                                       "frequency_tolerance of its modal-analysis frequency "
                                       "(hubbeam_ctrl.sim.stepper.substep_rule).")
    frequency_tolerance: float = setting(0.01, lo=0.0, lo_open=True, hi=0.1,
                                         doc="Largest relative frequency error of any bending mode in "
                                             "the integrator (1 %: the residuals of the default slew stay "
                                             "within 2 % of a 30-substep run on Table 1's beam and the lab "
                                             "arm, and the servo_link rig's verdict equals a converged "
                                             "run's, where 2 % moved its settling by 40 %; "
                                             "benchmarks/bench_substeps.py, tests/test_substep_rule.py).")
    sensors: SensorSettings = setting(factory=SensorSettings,
                                      doc='Sensor noise for controllers that read "sensors"; the hub '
                                          "encoder's resolution for every controller.")
    range_limit: float = setting(0.3, lo=0.0, lo_open=True, hi=10.0,
                                 doc="Validated range of the models: a run with abs(v_tip) > range_limit * L "
                                     "is flagged (outside_validated_range, with the time) and goes on.")
    divergence_limit: float = setting(1.0, lo=0.0, lo_open=True, hi=10.0,
                                      doc="The run stops (diverged) when abs(v_tip) > divergence_limit * L.")
    max_wall_s: float = setting(600.0, unit="s", lo=1e-3, hi=1e7,
                                doc="The run stops (flagged) when it has taken longer than this "
                                    "(checked at every sample).")
    max_memory_mb: float = setting(2048.0, unit="MB", lo=1.0, hi=1e9,
                                   doc="A run whose results would need more memory than this is "
                                       "refused before it starts.")

    @property
    def stepper(self) -> StepperSettings:
        """The plant integrator's settings (``substeps`` must be given; else see :meth:`stepper_settings`)."""
        if self.substeps is None:
            raise ParameterError("substeps is None (chosen per plant by substep_rule); "
                                 "use stepper_settings(substeps)")
        return self.stepper_settings(self.substeps)

    def stepper_settings(self, substeps: int) -> StepperSettings:
        """The plant integrator's settings with ``substeps`` steps per sample (1..200).

        Parameters
        ----------
        substeps : int
            Integration steps per sample, 1..200.
        """
        values = {f.name: getattr(self, f.name) for f in fields(StepperSettings)}
        return StepperSettings(**{**values, "substeps": substeps})


def _torque(value) -> float:
    """A controller's output as one float (NaN and infinity pass: the loop reports them)."""
    arr = np.asarray(value, dtype=float)
    if arr.size != 1:
        raise ParameterError(f"the torque must be one number, got {arr.size} values")
    return float(arr.reshape(()))


def _initial_state(x0, n_x: int) -> np.ndarray:
    """``x0`` as ``n_x`` finite floats (zeros when ``None``), or a one-line error."""
    if x0 is None:
        return np.zeros(n_x)
    try:
        x = np.asarray(x0, dtype=float).ravel()
    except (TypeError, ValueError, OverflowError):
        x = None
    if x is None or x.shape != (n_x,) or not np.all(np.isfinite(x)):
        raise ParameterError(f"x0 must hold {n_x} finite numbers [q, v] of the plant, got "
                             + (f"shape {x.shape}" + ("" if x.shape != (n_x,) else " with NaN or infinity")
                                if x is not None else type(x0).__name__))
    return x


def _controller_name(controller) -> str:
    return str(getattr(controller, "name", type(controller).__name__))


@lru_cache(maxsize=64)
def _substep_info(model: str, params: Params, spin: float, dt: float, tolerance: float, rho_inf: float) -> dict:
    """The substep rule of a plant (its free-hub modal analysis), once per plant and settings."""
    f = modal_analysis(build_model(model, params), spin, "free").bending_hz
    return substep_rule(f, dt, tolerance=tolerance, rho_inf=rho_inf).to_dict()


def _basis_model(name):
    """The assumed-mode model behind a plant name: the exact beam (``"ancf"``) is projected on FOAM's
    modes and integrated with FOAM's step rule."""
    if name == "ancf":
        require_exudyn("plant='ancf'")
        return "foam"
    return name


def _exact_plant(model: HubBeamModel, settings, substeps: int, hardware, n_elements):
    """The exact-beam plant on the evaluation plant's modes and step (:mod:`hubbeam_ctrl.exact`)."""
    n2 = model.n_transverse
    ne = element_rule(n2) if n_elements is None else n_elements
    return ExactBeamPlant(model.params, n_elements=ne, dt=settings.dt, substeps=substeps, n_modes=n2,
                          n_axial=model.n_axial, rho_inf=settings.rho_inf, hardware=hardware)


def _plant_and_rule(plant, controller, params, design_params, plant_params, plant_modes, settings):
    """The plant model, its description and the integration step of the run."""
    spin = float(getattr(getattr(controller, "design", None), "spin", 0.0) or 0.0)
    explicit = isinstance(plant, HubBeamModel) or params is not None
    if isinstance(plant, EvaluationPlant):
        if any(v is not None for v in (params, design_params, plant_params, plant_modes)):
            raise ParameterError("an EvaluationPlant carries its parameters: give no params, "
                                 "design_params, plant_params or plant_modes with it")
        model = build_model(_basis_model(plant.model), plant.params)
        info = {k: v for k, v in plant.to_dict().items() if k != "plant_params"}
    elif explicit:
        if any(v is not None for v in (design_params, plant_params, plant_modes)):
            raise ParameterError("give either params (the exact plant) or design_params / plant_params / "
                                 "plant_modes (the evaluation-plant rule), not both")
        model = resolve_model(_basis_model(plant), params)
        info = {"plant_model": model.name, "plant_modes": model.n_transverse,
                "plant_axial_modes": model.n_axial, "plant_modes_reason": "as given"}
    else:
        design = design_params if design_params is not None else \
            getattr(getattr(controller, "design", None), "params", None) or Params()
        n_design = int(getattr(controller, "n_modes", None) or design.n_transverse)
        ev = evaluation_plant(plant, design, settings.dt, min(n_design, MAX_MODES), spin,
                              plant_params=plant_params, plant_modes=plant_modes)
        model = build_model(_basis_model(ev.model), ev.params)
        info = {k: v for k, v in ev.to_dict().items() if k != "plant_params"}
    if plant == "ancf" or getattr(plant, "model", None) == "ancf":
        info["plant_model"] = "ancf"
    if settings.substeps is None:
        info.update(_substep_info(model.name, model.params, spin, settings.dt, settings.frequency_tolerance,
                                  settings.rho_inf))
    else:
        info.update({"substeps": settings.substeps, "step_s": settings.dt / settings.substeps,
                     "step_reason": f"{settings.substeps} steps per sample as requested"})
    info["modal_spin_rad_s"] = spin
    return model, info


def _delay_substeps(n: int, delay: float, dt: float) -> dict:
    """The rule's substeps raised (by at most half) to a count on which the delay falls on a substep.

    The command changes at the end of a substep, so the delay acts rounded to ``dt / n``; the
    controllers on a rig compensate the exact delay (:meth:`controllers.DesignModel.on_rig`), so
    the plant should apply it. Among ``n .. 1.5 n`` the first count that holds the delay exactly
    (within 1e-9 of a substep), else the one that holds it best.

    Parameters
    ----------
    n : int
        The rule's substeps.
    delay : float
        Fraction of the sample [-].
    dt : float
        Sample time [s].

    Returns
    -------
    dict
        ``substeps``, ``step_s`` and, when raised, a note on ``step_reason``'s key ``delay_substeps_reason``.
    """
    cap = SUBSTEP_BUDGET if n <= SUBSTEP_BUDGET else MAX_SUBSTEPS
    candidates = range(n, min(cap, int(math.ceil(1.5 * n))) + 1)
    def error(k):                      # the applied delay's error as a fraction of the sample
        return abs(delay * k - round(delay * k)) / k
    exact = [k for k in candidates if error(k) * k <= 1e-9]
    best = exact[0] if exact else min(candidates, key=error)
    out = {"substeps": best, "step_s": dt / best}
    if best != n:
        out["delay_substeps_reason"] = f"{best} substeps instead of the rule's {n} so that the delay falls on a substep"
    return out


def simulate_closed_loop(plant, controller, t_end: float = 30.0, *, params: Params | None = None,
                         design_params: Params | None = None, plant_params: Params | None = None,
                         plant_modes: int | None = None, settings: ClosedLoopSettings | None = None,
                         x0=None, reference=None, backend=None, hardware: Hardware | None = None,
                         n_elements: int | None = None) -> Result:
    """Run a sampled controller on a nonlinear plant (zero-order hold).

    At each sample ``t_k = k dt`` (``k = 0..N``, ``N = round(t_end/dt)``) the controller gets
    the measurement and returns the torque held until ``t_{k+1}``. The measurement is, by
    the controller's ``measurement`` attribute:

    * ``"state"``: the plant's own coordinates in SFOAM order
      ``[theta, q2_1..q2_m, theta_dot, q2_dot_1..q2_dot_m]`` with ``m`` the controller's
      ``state_modes`` (or ``n_modes``; default all the plant's transverse modes); the axial
      ``q1`` is not given;
    * ``"sensors"``: ``[theta, theta_dot, M_root]`` [rad, rad/s, N m] plus the noise of
      ``settings.sensors``.

    With ``settings.sensors.encoder_counts`` the measured hub angle is rounded to the
    nearest encoder count, in both cases.

    The plant is, in this order: ``plant`` itself when it is a built model; the model named
    ``plant`` with exactly ``params`` when they are given; otherwise the **evaluation plant**
    of :func:`~hubbeam_ctrl.sim.evaluation.evaluation_plant`: the physical parameters of
    ``plant_params`` (default ``design_params``, default the controller's design model's, default
    Table 1) with every bending mode below the sampling frequency and at least three more
    than the controller's design model (or ``plant_modes``). The integration step follows from
    the plant's highest bending frequency (``settings.substeps = None``, see
    :func:`~hubbeam_ctrl.sim.stepper.substep_rule`). ``result.settings`` says which plant and
    which step were used, and why.

    Parameters
    ----------
    plant : str, HubBeamModel or EvaluationPlant
        ``"foam"``, ``"cfoam"`` or ``"ancf"`` (the geometrically exact beam of
        :class:`~hubbeam_ctrl.exact.ExactBeamPlant`, needs Exudyn; its state for controllers is
        projected on the evaluation plant's modes and its step is that plant's; its tip and root
        moment are its own) (also ``"tlam"``, ``"sfoam"`` with ``params``), a built
        model (free hub), or the result of :func:`~hubbeam_ctrl.sim.evaluation.evaluation_plant`.
    controller : object
        See the module docstring. ``reset()`` is called before the run.
    t_end : float
        Final time [s], > 0.
    params : Params, optional
        The exact plant parameters (no evaluation-plant rule).
    design_params : Params, optional
        Parameters of the controller's design model (default: ``controller.design.params``).
    plant_params : Params, optional
        Physical parameters of the evaluation plant when they differ from the design's.
    plant_modes : int, optional
        Transverse modes of the evaluation plant (design modes..20).
    settings : ClosedLoopSettings, optional
    x0 : array_like (2 n_q,), optional
        Initial plant state ``[q, v]`` (default: at rest).
    reference : tuple of callables, optional
        ``(theta_ref(t), theta_dot_ref(t))`` of arrays, stored with the result for
        metrics and plots.
    backend : {"auto", "compiled", "vm"}, optional
        How the plant step is evaluated (see :class:`PlantStepper`); default
        ``$HUBBEAM_BACKEND`` or ``"auto"``.
    hardware : Hardware, optional
        The rig's drive and friction (:class:`~hubbeam_ctrl.sim.hardware.Hardware`, e.g.
        ``Hardware.from_rig(rig)``; give the plant ``rig.plant_params``, whose hub inertia holds the
        reflected rotor): the controller's output is then the command (a voltage for a DC motor,
        stored as ``tau``). With the rig's ``sensors`` (``Hardware.from_rig`` gives them) the
        measurement comes from :class:`~hubbeam_ctrl.sim.measurement.MeasurementChain`: a
        ``"sensors"`` controller reads the signals it names in its ``signals`` attribute (names of
        :func:`~hubbeam_ctrl.plant.instruments.signal_names`, default
        :data:`~hubbeam_ctrl.sim.measurement.DEFAULT_SIGNALS`), a
        ``"state"`` controller gets the measured hub angle and rate in place of the exact ones;
        the accelerometer reads the accelerations before the sample's new command acts. Ideal
        rig sensors with the root gauge only and no ``signals`` keep the closed loop's own
        sensors (``settings.sensors``). With the rig's ``timing.delay`` ``d`` the command
        computed at ``t_k`` acts from ``t_k + d dt`` (the previous one before; zero before the
        first), rounded to the nearest integration substep (``result.settings["timing"]`` gives
        the delay applied); a rig's ``timing.dt``, when set, must be ``settings.dt``. None or
        ideal hardware: the beam alone, bit for bit.
    n_elements : int, optional
        ANCF elements of the exact-beam plant (``plant="ancf"``); default
        :func:`~hubbeam_ctrl.exact.element_rule` of the evaluation plant's modes.

    Returns
    -------
    Result
        Of kind ``"closed_loop"``, sampled at the controller's instants: the plant's
        ``q``, ``v``, ``v_tip``, ``u_tip``, ``root_moment``, the commanded ``tau``, the
        controller's ``step_time_s`` and ``controller_stats``, the reference (when given),
        and ``stats`` with the plant integrator's ``plant_fallbacks`` and
        ``jacobian_updates``.

    Notes
    -----
    A plant that passes ``range_limit * L`` (default 0.3 L, the models' validated range) is
    flagged (``outside_validated_range``, ``outside_range_time_s``) and the run goes on. A
    controller that returns a non-finite torque or raises, an integrator failure, or a plant
    that passes ``divergence_limit * L`` (default L) or whose mass matrix is no longer positive
    definite (a large deflection, past what the model's kinetic energy holds: the implicit step
    cannot converge there, and the cause is the model's range, ``"diverged"``, not the
    integrator) stops the run: the result is cut there,
    with ``stopped = True``, a message naming the cause and ``stats["stop_cause"]`` (one of
    ``"controller"``, ``"integrator"``, ``"diverged"``, ``"wall_clock"``; None for a run that
    completed). So does ``settings.max_wall_s``
    (checked at every sample); a run whose samples would need more than
    ``settings.max_memory_mb`` is refused before it starts.
    """
    settings = ClosedLoopSettings() if settings is None else settings
    if not isinstance(settings, ClosedLoopSettings):
        raise ParameterError(f"settings must be a ClosedLoopSettings, got {type(settings).__name__}")
    t_end = check_in_range("t_end", t_end, "s", settings.dt, T_END_MAX, "at least two samples: t_end >= dt")
    if not callable(controller) or not hasattr(controller, "reset"):
        raise ParameterError("controller must be callable as controller(t, y) and have reset()")
    name = _controller_name(controller)
    dt = settings.dt
    cdt = getattr(controller, "dt", None)
    if cdt is not None and abs(float(cdt) - dt) > 1e-12 * dt:
        raise ParameterError(f"controller {name!r} is designed for dt = {cdt:g} s but the "
                             f"simulator samples at dt = {dt:g} s")
    rig_dt = None if hardware is None or hardware.timing is None else hardware.timing.dt
    if rig_dt is not None and abs(rig_dt - dt) > 1e-12 * dt:
        raise ParameterError(f"timing.dt = {rig_dt:g} s of the rig but the closed loop samples at dt = {dt:g} s "
                             "(give settings with the rig's dt)")
    kind = getattr(controller, "measurement", "state")
    if kind not in ("state", "sensors"):
        raise ParameterError(f"controller {name!r}: measurement must be 'state' or 'sensors', got {kind!r}")
    model, plant_info = _plant_and_rule(plant, controller, params, design_params, plant_params,
                                        plant_modes, settings)
    if settings.substeps is None and hardware is not None and hardware.delay:
        plant_info.update(_delay_substeps(plant_info["substeps"], hardware.delay, settings.dt))
    n = model.n_q
    n1, n2 = model.n_axial, model.n_transverse
    m = int(getattr(controller, "state_modes", None) or getattr(controller, "n_modes", None) or n2)
    if kind == "state" and not 1 <= m <= n2:
        raise ParameterError(f"controller {name!r} reads {m} transverse modes but the plant has {n2}")
    # index map plant state [q, v] -> measurement
    idx_state = np.r_[0, 1 + n1:1 + n1 + m, n, n + 1 + n1:n + 1 + n1 + m]
    C_sens = sensor_matrix(model.params, n2, n1)
    N = int(round(t_end / dt))
    check_budget(f"t_end = {t_end:g} s at dt = {dt:g} s ({N + 1} samples)",
                 memory_bytes=16.0 * (N + 1) * (2 * n + 9),
                 seconds=N * CLOSED_LOOP_SECONDS_PER_SAMPLE * (n / 11.0) ** 2,
                 max_memory_mb=settings.max_memory_mb, max_wall_s=settings.max_wall_s)
    x = _initial_state(x0, 2 * n)
    exact = plant_info.get("plant_model") == "ancf"
    if exact:
        stepper = _exact_plant(model, settings, plant_info["substeps"], hardware, n_elements)
        plant_info.update(plant_elements=stepper.n_elements, plant_element_reason=(
            f"{stepper.n_elements} ANCF cable elements (3 per bending mode of the {model.n_transverse}-mode "
            "evaluation plant, a multiple of 8, at least 16)" if n_elements is None else
            f"{stepper.n_elements} ANCF cable elements (as asked)"),
            root_moment_from="clamp reaction (the joint's Lagrange multiplier)")
        exact_out = np.full((N + 1, 3), np.nan)      # v_tip, u_tip, root moment
        exact_out[0] = 0.0
    elif n_elements is not None:
        raise ParameterError("n_elements is for plant='ancf' (the exact-beam plant) only")
    else:
        stepper = PlantStepper(model, settings.stepper_settings(plant_info["substeps"]), backend,
                               hardware=hardware)
    t = dt * np.arange(N + 1)
    chain, state_pick = rig_measurement(hardware, controller, kind, model, m, dt, N + 1,
                                         settings.sensors.seed, backend if exact else stepper.backend)
    rng = np.random.default_rng(settings.sensors.seed)
    noise = rng.standard_normal((N + 1, 3)) * settings.sensors.std if kind == "sensors" and chain is None \
        else None
    delay = 0.0 if hardware is None else hardware.delay
    slew_step = None if hardware is None or hardware.drive.slew_rate is None else hardware.drive.slew_rate * settings.dt
    last_command = 0.0                            # the amplifier's output before t = 0
    n_sub = plant_info["substeps"]
    n_late = int(round(delay * n_sub))            # substeps still under the previous command
    u_sub = np.empty(n_sub)
    u_prev = 0.0                                  # nothing was commanded before t = 0
    f2_tip = model.basis.f2_tip
    sl2 = model.transverse_slice
    L = model.params.L
    flag_at, stop_at = settings.range_limit * L, settings.divergence_limit * L
    outside_time = past_range_time = None
    encoder = settings.sensors.encoder_step

    states = np.empty((N + 1, 2 * n))
    taus = np.full(N + 1, np.nan)
    step_times = np.full(N + 1, np.nan)
    controller.reset()
    stopped, message, cause = False, "completed", None
    start = time.perf_counter()
    s = None
    last = N
    perf = time.perf_counter
    plain = None
    if chain is not None:
        chain.reset()
        if state_pick is not None and chain.offsets is not None:      # hub angle and rate: inline
            plain = chain.offsets
            encoder = chain.encoder
    for k in range(N + 1):
        states[k] = x
        if plain is not None:           # the rig's encoder, biases and noise on the state feedback's hub
            y = x[idx_state]
            theta = y[0] + plain[0][k]
            y[0] = encoder * math.floor(theta / encoder + 0.5) if encoder else theta
            y[state_pick] += plain[1][k]
        elif chain is not None:         # the rig's sensors (the accelerometer reads s's accelerations)
            if s is None:
                s = stepper.initial_state(x, u_prev)
            if state_pick is None:
                y = chain.measure(k, s)
            else:
                y = x[idx_state]
                y[0], y[state_pick] = chain.measure(k, s)
        else:
            if noise is None:
                y = x[idx_state]
            elif exact:
                y = np.array([x[0], x[n], exact_out[k, 2]]) + noise[k]
            else:
                y = C_sens @ x + noise[k]
            if encoder:                     # the encoder's count (nearest): y is a new array
                y[0] = encoder * round(y[0] / encoder)
        t0 = perf()
        try:
            tau = _torque(controller(t[k], y))
        except Exception as exc:      # the controller's own code: stop, name it, keep the run
            stopped, last, cause = True, k, "controller"
            message = (f"controller {name!r} raised {type(exc).__name__}: {str(exc)[:200]} at "
                       f"t = {t[k]:.3f} s; run stopped")
            break
        step_times[k] = perf() - t0
        taus[k] = tau
        if not math.isfinite(tau):
            stopped, cause = True, "controller"
            message = (f"controller {name!r} returned a non-finite torque ({tau}) at "
                       f"t = {t[k]:.3f} s; run stopped")
            last = k
            break
        if slew_step is not None:       # the amplifier's slew-rate limit: the filters predict with what it gives
            limited = min(max(tau, last_command - slew_step), last_command + slew_step)
            if limited != tau:
                tau = taus[k] = limited
                if hasattr(controller, "applied"):
                    controller.applied(tau)
            last_command = tau
        if k == N:
            break
        if n_late:                      # computation delay: the command acts delay * dt after the sample
            u_sub[:n_late] = u_prev
            u_sub[n_late:] = tau
            if s is None or k == 0:
                s = stepper.initial_state(x, u_prev)
            u_prev = tau
            applied = u_sub
        else:
            if s is None or (k == 0 and chain is not None):
                s = stepper.initial_state(x, tau)
            applied = tau
        try:
            s = stepper.step(s, applied)
            if not math.isfinite(float(np.sum(s))):      # a NaN that the step's error norm passed
                raise HubbeamError(f"{model.name.upper()}: the implicit step returned non-finite values")
        except HubbeamError as exc:
            stopped, last, cause = True, k, "integrator"
            message = f"{exc} at t = {t[k]:.3f} s; run stopped"
            # not the integrator but the model when its mass matrix is singular within the sample
            # (at its start or where the sample's velocities take it)
            if not exact and not (stepper.mass_positive(x[:n], x[n:])
                                  and stepper.mass_positive(x[:n] + dt * x[n:], x[n:])):
                cause = "diverged"
                message = (f"{model.name.upper()} left its range at t = {t[k]:.3f} s under controller {name!r}: "
                           f"its mass matrix is no longer positive definite within the sample from |v_tip| = "
                           f"{abs(f2_tip @ x[sl2]) / L:.3g} L (the model's kinetic energy holds no further); "
                           "run stopped")
            break
        x = s[:2 * n]
        if exact:
            o = stepper.outputs
            exact_out[k + 1] = o["v_tip"], o["u_tip"], o["root_moment"]
            tip = abs(o["v_tip"])
        else:
            tip = abs(f2_tip @ x[sl2])
        if not tip <= flag_at:
            if exact:                   # the exact beam has no such range: recorded (the first time), not flagged
                if past_range_time is None:
                    past_range_time = float(t[k + 1])
            elif outside_time is None:
                outside_time = float(t[k + 1])
        if not tip <= stop_at:
            stopped, last, cause = True, k + 1, "diverged"
            states[k + 1] = x
            message = (f"{'ANCF' if exact else model.name.upper()} left its range at t = {t[k + 1]:.3f} s under "
                       f"controller {name!r}: |v_tip| > {settings.divergence_limit:g} L; run stopped")
            break
        if perf() - start > settings.max_wall_s:
            stopped, last, cause = True, k + 1, "wall_clock"
            states[k + 1] = x
            message = f"stopped after max_wall_s = {settings.max_wall_s:g} s at t = {t[k + 1]:.3f} s"
            break
    wall = time.perf_counter() - start
    keep = slice(0, last + 1)
    t, states, taus, step_times = t[keep], states[keep], taus[keep], step_times[keep]
    q, v = states[:, :n], states[:, n:]
    if exact:
        v_tip, u_tip, root_moment = (exact_out[keep, j].copy() for j in range(3))
    else:
        v_tip, u_tip = model.tip_series(q, v)
        root_moment = states @ C_sens[2]
    theta_ref = theta_dot_ref = None
    if reference is not None:
        theta_ref = np.asarray(reference[0](t), dtype=float) * np.ones_like(t)
        theta_dot_ref = np.asarray(reference[1](t), dtype=float) * np.ones_like(t)
    stats = dict(controller.stats()) if hasattr(controller, "stats") else {}
    s_dict = dataclasses.asdict(settings)
    s_dict.update(plant_info)
    s_dict["t_end"] = float(t_end)
    s_dict["measurement"] = kind
    if outside_time is not None and not stopped:
        message = (f"completed; |v_tip| passed {settings.range_limit:g} L (outside the models' validated "
                   f"range) at t = {outside_time:.3f} s")
    if exact and past_range_time is not None and not stopped:
        message = (f"completed; |v_tip| passed {settings.range_limit:g} L at t = {past_range_time:.3f} s, "
                   "outside the assumed-mode models' validated range; the exact beam has no such limit")
    s_dict["backend"] = stepper.backend
    if chain is not None:
        s_dict["rig_sensors"] = {"sensors": hardware.sensors.to_dict(), "signals": list(chain.names),
                                 "read": list(chain.read)}
    if n_late:
        s_dict["timing"] = {"delay": delay, "delay_substeps": n_late, "applied_delay": n_late / n_sub}
    if stepper.hardware is not None:
        hw = stepper.hardware
        s_dict["hardware"] = {"drive": hw.drive.to_dict(), "friction": hw.friction.to_dict(),
                              "command": hw.command, "stick_events": stepper.stick_events}
    return Result(
        kind="closed_loop", model="ancf" if exact else model.name, controller=name, t=t, q=q, v=v, v_tip=v_tip,
        u_tip=u_tip, root_moment=root_moment, tau=taus, step_time_s=step_times,
        params=model.params, theta_ref=theta_ref, theta_dot_ref=theta_dot_ref, settings=s_dict,
        stats={"plant_fallbacks": stepper.fallbacks, "jacobian_updates": stepper.jacobian_updates,
               "outside_range_time_s": outside_time, "stop_cause": cause,
               **({"past_assumed_mode_range_time_s": past_range_time} if exact else {})},
        controller_stats=stats, stopped=stopped, message=message, wall_s=wall)
