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
* optionally ``name``, ``dt`` (its sample time, checked against the simulator's),
  ``n_modes`` (the transverse modes of its design model) and ``stats() -> dict``.

This module is plant side: it does not import the ``controllers`` package.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, fields

import numpy as np

from hubbeam_ctrl.core.budget import CLOSED_LOOP_SECONDS_PER_SAMPLE, T_END_MAX, check_budget
from hubbeam_ctrl.core.errors import HubbeamError, ParameterError
from hubbeam_ctrl.core.settings import setting
from hubbeam_ctrl.core.validation import check_in_range
from hubbeam_ctrl.plant.models import resolve_model
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.plant.sensors import SensorSettings, sensor_matrix
from hubbeam_ctrl.sim.results import Result
from hubbeam_ctrl.sim.stepper import PlantStepper, StepperSettings

__all__ = ["ClosedLoopSettings", "simulate_closed_loop"]


@dataclass(frozen=True)
class ClosedLoopSettings(StepperSettings):
    """Settings of :func:`simulate_closed_loop`: the plant integrator's (``dt`` is also the
    controller's sample period and the zero-order hold's), the sensors and when to stop."""

    sensors: SensorSettings = setting(factory=SensorSettings,
                                      doc='Sensor noise for controllers that read "sensors".')
    divergence_limit: float = setting(0.3, lo=0.0, lo_open=True, hi=10.0,
                                      doc="The run stops when abs(v_tip) > divergence_limit * L.")
    max_wall_s: float = setting(600.0, unit="s", lo=1e-3, hi=1e7,
                                doc="The run stops (flagged) when it has taken longer than this "
                                    "(checked at every sample).")
    max_memory_mb: float = setting(2048.0, unit="MB", lo=1.0, hi=1e9,
                                   doc="A run whose results would need more memory than this is "
                                       "refused before it starts.")

    @property
    def stepper(self) -> StepperSettings:
        """The plant integrator's settings."""
        return StepperSettings(**{f.name: getattr(self, f.name) for f in fields(StepperSettings)})


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


def simulate_closed_loop(plant, controller, t_end: float = 30.0, *, params: Params | None = None,
                         settings: ClosedLoopSettings | None = None, x0=None,
                         reference=None) -> Result:
    """Run a sampled controller on a nonlinear plant (zero-order hold).

    At each sample ``t_k = k dt`` (``k = 0..N``, ``N = round(t_end/dt)``) the controller gets
    the measurement and returns the torque held until ``t_{k+1}``. The measurement is, by
    the controller's ``measurement`` attribute:

    * ``"state"``: the plant's own coordinates in SFOAM order
      ``[theta, q2_1..q2_m, theta_dot, q2_dot_1..q2_dot_m]`` with ``m`` the controller's
      ``n_modes`` (default all the plant's transverse modes); the axial ``q1`` is not given;
    * ``"sensors"``: ``[theta, theta_dot, M_root]`` [rad, rad/s, N m] plus the noise of
      ``settings.sensors``.

    Parameters
    ----------
    plant : str or HubBeamModel
        ``"foam"``, ``"cfoam"``, ``"tlam"``, ``"sfoam"`` or a built model (free hub).
    controller : object
        See the module docstring. ``reset()`` is called before the run.
    t_end : float
        Final time [s], > 0.
    params : Params, optional
        Parameters when ``plant`` is a name.
    settings : ClosedLoopSettings, optional
    x0 : array_like (2 n_q,), optional
        Initial plant state ``[q, v]`` (default: at rest).
    reference : tuple of callables, optional
        ``(theta_ref(t), theta_dot_ref(t))`` of arrays, stored with the result for
        metrics and plots.

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
    A controller that returns a non-finite torque or raises, or a plant that leaves its range
    (``|v_tip| > divergence_limit * L``), stops the run: the result is cut there, with
    ``stopped = True`` and a message naming the cause. So does ``settings.max_wall_s``
    (checked at every sample); a run whose samples would need more than
    ``settings.max_memory_mb`` is refused before it starts.
    """
    settings = ClosedLoopSettings() if settings is None else settings
    if not isinstance(settings, ClosedLoopSettings):
        raise ParameterError(f"settings must be a ClosedLoopSettings, got {type(settings).__name__}")
    model = resolve_model(plant, params)
    t_end = check_in_range("t_end", t_end, "s", settings.dt, T_END_MAX, "at least two samples: t_end >= dt")
    if not callable(controller) or not hasattr(controller, "reset"):
        raise ParameterError("controller must be callable as controller(t, y) and have reset()")
    name = _controller_name(controller)
    dt = settings.dt
    cdt = getattr(controller, "dt", None)
    if cdt is not None and abs(float(cdt) - dt) > 1e-12 * dt:
        raise ParameterError(f"controller {name!r} is designed for dt = {cdt:g} s but the "
                             f"simulator samples at dt = {dt:g} s")
    kind = getattr(controller, "measurement", "state")
    if kind not in ("state", "sensors"):
        raise ParameterError(f"controller {name!r}: measurement must be 'state' or 'sensors', got {kind!r}")
    n = model.n_q
    n1, n2 = model.n_axial, model.n_transverse
    m = int(getattr(controller, "n_modes", None) or n2)
    if not 1 <= m <= n2:
        raise ParameterError(f"controller {name!r} reads {m} transverse modes but the plant has {n2}")
    # index map plant state [q, v] -> measurement
    idx_state = np.r_[0, 1 + n1:1 + n1 + m, n, n + 1 + n1:n + 1 + n1 + m]
    C_sens = sensor_matrix(model.params, n2, n1)
    stepper = PlantStepper(model, settings.stepper)
    N = int(round(t_end / dt))
    check_budget(f"t_end = {t_end:g} s at dt = {dt:g} s ({N + 1} samples)",
                 memory_bytes=16.0 * (N + 1) * (2 * n + 9),
                 seconds=N * CLOSED_LOOP_SECONDS_PER_SAMPLE * (n / 11.0) ** 2,
                 max_memory_mb=settings.max_memory_mb, max_wall_s=settings.max_wall_s)
    t = dt * np.arange(N + 1)
    rng = np.random.default_rng(settings.sensors.seed)
    noise = rng.standard_normal((N + 1, 3)) * settings.sensors.std if kind == "sensors" else None
    f2_tip = model.basis.f2_tip
    sl2 = model.transverse_slice
    limit = settings.divergence_limit * model.params.L

    states = np.empty((N + 1, 2 * n))
    taus = np.full(N + 1, np.nan)
    step_times = np.full(N + 1, np.nan)
    x = _initial_state(x0, 2 * n)
    controller.reset()
    stopped, message = False, "completed"
    start = time.perf_counter()
    s = None
    last = N
    perf = time.perf_counter
    for k in range(N + 1):
        states[k] = x
        y = x[idx_state] if noise is None else C_sens @ x + noise[k]
        t0 = perf()
        try:
            tau = _torque(controller(t[k], y))
        except Exception as exc:      # the controller's own code: stop, name it, keep the run
            stopped, last = True, k
            message = (f"controller {name!r} raised {type(exc).__name__}: {str(exc)[:200]} at "
                       f"t = {t[k]:.3f} s; run stopped")
            break
        step_times[k] = perf() - t0
        taus[k] = tau
        if not math.isfinite(tau):
            stopped = True
            message = (f"controller {name!r} returned a non-finite torque ({tau}) at "
                       f"t = {t[k]:.3f} s; run stopped")
            last = k
            break
        if k == N:
            break
        if s is None:
            s = stepper.initial_state(x, tau)
        try:
            s = stepper.step(s, tau)
        except HubbeamError as exc:
            stopped, message, last = True, f"{exc} at t = {t[k]:.3f} s; run stopped", k
            break
        x = s[:2 * n]
        if not abs(f2_tip @ x[sl2]) <= limit:
            stopped, last = True, k + 1
            states[k + 1] = x
            message = (f"{model.name.upper()} left its range at t = {t[k + 1]:.3f} s under "
                       f"controller {name!r}: |v_tip| > {settings.divergence_limit:g} L")
            break
        if perf() - start > settings.max_wall_s:
            stopped, last = True, k + 1
            states[k + 1] = x
            message = f"stopped after max_wall_s = {settings.max_wall_s:g} s at t = {t[k + 1]:.3f} s"
            break
    wall = time.perf_counter() - start
    keep = slice(0, last + 1)
    t, states, taus, step_times = t[keep], states[keep], taus[keep], step_times[keep]
    q, v = states[:, :n], states[:, n:]
    v_tip, u_tip = (np.array(o).ravel() for o in model.tip_function.map(len(t))(q.T))
    root_moment = states @ C_sens[2]
    theta_ref = theta_dot_ref = None
    if reference is not None:
        theta_ref = np.asarray(reference[0](t), dtype=float) * np.ones_like(t)
        theta_dot_ref = np.asarray(reference[1](t), dtype=float) * np.ones_like(t)
    stats = dict(controller.stats()) if hasattr(controller, "stats") else {}
    s_dict = dataclasses.asdict(settings)
    s_dict["t_end"] = float(t_end)
    s_dict["measurement"] = kind
    return Result(
        kind="closed_loop", model=model.name, controller=name, t=t, q=q, v=v, v_tip=v_tip,
        u_tip=u_tip, root_moment=root_moment, tau=taus, step_time_s=step_times,
        params=model.params, theta_ref=theta_ref, theta_dot_ref=theta_dot_ref, settings=s_dict,
        stats={"plant_fallbacks": stepper.fallbacks, "jacobian_updates": stepper.jacobian_updates},
        controller_stats=stats, stopped=stopped, message=message, wall_s=wall)
