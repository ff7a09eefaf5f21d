"""Closed-loop simulation: a sampled controller on a nonlinear plant.

The controller is called at the sample instants ``t_k = k dt`` with the measurement
``y(t_k)`` and returns a hub torque, which is held over ``[t_k, t_k + dt)`` (zero-order
hold); in between, the nonlinear plant (FOAM, CFOAM, TLAM or SFOAM with a free hub) is
integrated continuously by :class:`PlantStepper`.

:class:`PlantStepper` is a fixed-step implicit integrator compiled into one CasADi
function per sample, so a closed-loop step costs one Python call for the plant and one
for the controller. The method is the generalized-alpha scheme of Chung and Hulbert (1993)
in the form of Arnold and Bruls (2007) for ``M(q) a + c(q, v) = B tau``, with the new
accelerations as unknowns of ``model.inverse_dynamics_function(q, v, a) - B tau = 0``
(the mass matrix is never inverted symbolically). Its spectral radius at infinity
``rho_inf`` (default 0.9) damps the stiff axial modes (up to ~1.4 kHz) that a step of a few
milliseconds cannot resolve, while the bending modes (0.5-30 Hz) are integrated with
second-order accuracy and negligible numerical damping. Each step solves the implicit
equations by Newton iterations started from the previous acceleration, with the iteration
matrix evaluated once per step (for CFOAM it is FOAM's, which differs only by terms of
higher order in the deflection); a step whose last Newton correction is not small enough is
recomputed with CasADi's ``rootfinder('newton')`` on the model's exact Jacobian.

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
from dataclasses import dataclass, field
from functools import lru_cache

import casadi as ca
import numpy as np

from .errors import HubbeamError, ParameterError
from .validation import check_nonnegative as _check_nonnegative
from .validation import check_positive as _check_positive
from .models import HubBeamModel, resolve_model
from .params import Params
from .results import HubStateViews

__all__ = ["StepperSettings", "PlantStepper", "SensorSettings", "ClosedLoopSettings",
           "ClosedLoopResult", "simulate_closed_loop", "simulate_fixed_step",
           "sensor_matrix", "generalized_alpha_coefficients"]


def _check_int(name, value, lo, hi):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lo <= value <= hi:
        raise ParameterError(f"{name} must be an integer in {lo}..{hi}, got {value!r}")


def generalized_alpha_coefficients(rho_inf: float) -> tuple:
    """Chung-Hulbert parameters ``(alpha_m, alpha_f, gamma, beta)`` for ``rho_inf`` in [0, 1].

    Parameters
    ----------
    rho_inf : float
        Spectral radius of the amplification matrix at infinite frequency [-]; 1 keeps
        every mode undamped (trapezoidal rule), smaller values damp the high frequencies.

    Returns
    -------
    tuple of float
    """
    am = (2 * rho_inf - 1) / (rho_inf + 1)
    af = rho_inf / (rho_inf + 1)
    gamma = 0.5 + af - am
    beta = 0.25 * (gamma + 0.5) ** 2
    return am, af, gamma, beta


@dataclass(frozen=True)
class StepperSettings:
    """Settings of the fixed-step plant integrator :class:`PlantStepper`."""

    dt: float = 0.01
    """Sample period [s]: one call of the stepper advances the plant by ``dt``."""
    substeps: int = 2
    """Integration steps per sample (1..100); the step is ``dt / substeps``. Two steps of
    5 ms reproduce a tight IDAS run of the Eq. 44 slew to ~0.04 % of the peak deflection."""
    rho_inf: float = 0.9
    """Spectral radius at infinity of the generalized-alpha method, 0..1 [-]."""
    newton_iterations: int = 3
    """Newton iterations per step in the fast path (1..20)."""
    newton_tol: float = 1e-6
    """Largest accepted last Newton correction of the accelerations [m/s^2, rad/s^2];
    a step above it is recomputed by the exact rootfinder."""

    def __post_init__(self):
        _check_positive("dt", self.dt, "s")
        _check_int("substeps", self.substeps, 1, 100)
        if not (isinstance(self.rho_inf, (int, float)) and 0.0 <= self.rho_inf <= 1.0):
            raise ParameterError(f"rho_inf must be a number in [0, 1], got {self.rho_inf!r}")
        _check_int("newton_iterations", self.newton_iterations, 1, 20)
        _check_positive("newton_tol", self.newton_tol, "m/s^2")


class PlantStepper:
    """Fixed-step generalized-alpha integrator of a free-hub model, one call per sample.

    The integrator state is ``s = [q, v, a, a_alpha]`` (coordinates, velocities, true and
    algorithmic accelerations, ``4 n_q`` numbers); :meth:`initial_state` makes one from
    ``[q, v]``.

    Parameters
    ----------
    model : HubBeamModel
        The plant (free hub, torque input).
    settings : StepperSettings, optional

    Examples
    --------
    >>> from hubbeam_ctrl import build_model
    >>> stepper = PlantStepper(build_model("foam"))
    >>> s = stepper.initial_state(tau=100.0)
    >>> s = stepper.step(s, 100.0)          # 10 ms at 100 N m
    >>> round(float(s[stepper.model.n_q]), 4)   # hub rate [rad/s]
    0.005
    """

    def __init__(self, model: HubBeamModel, settings: StepperSettings | None = None):
        self.model = model
        self.settings = settings or StepperSettings()
        self.n_q = model.n_q
        self.n_s = 4 * model.n_q
        self.h = self.settings.dt / self.settings.substeps
        self.fallbacks = 0
        self.jacobian_updates = 0
        self._function = _fast_step_function(model, self.settings)
        self._jacobian = _iteration_matrix_function(model, self.settings)
        self._J = None
        self._robust = None

    # -- state helpers ---------------------------------------------------------
    def initial_state(self, x0=None, tau: float = 0.0) -> np.ndarray:
        """Integrator state from ``x0 = [q, v]`` (default: at rest) and the torque at t = 0.

        Parameters
        ----------
        x0 : array_like (2 n_q,), optional
            Coordinates [rad, m] and velocities [rad/s, m/s].
        tau : float
            Hub torque at t = 0 [N m] (sets the initial accelerations).

        Returns
        -------
        ndarray (4 n_q,)
        """
        n = self.n_q
        x0 = np.zeros(2 * n) if x0 is None else np.asarray(x0, dtype=float).ravel()
        if x0.shape != (2 * n,) or not np.all(np.isfinite(x0)):
            raise ParameterError(f"x0 must hold {2 * n} finite numbers [q, v], got shape {x0.shape}")
        a0 = self.model.accelerations(x0[:n], x0[n:], float(tau))
        return np.concatenate([x0, a0, a0])

    def step(self, state, tau) -> np.ndarray:
        """Advance the plant by one sample period.

        Parameters
        ----------
        state : ndarray (4 n_q,)
            Integrator state at the start of the sample.
        tau : float or array_like (substeps,)
            Hub torque [N m]: held over the sample (float), or its values at the end of
            each substep (for a torque that varies within the sample).

        Returns
        -------
        ndarray (4 n_q,)
            State at the end of the sample.

        Raises
        ------
        HubbeamError
            If neither the fast Newton iterations nor the exact rootfinder converge.
        """
        k = self.settings.substeps
        u = np.broadcast_to(np.asarray(tau, dtype=float), (k,)).reshape(1, k)
        tol = self.settings.newton_tol
        fresh = self._J is None
        if fresh:
            self._refresh(state, u)
        out, err = self._function(state, u, self._J)
        err = float(err)
        if not err <= tol and not fresh:          # stale iteration matrix: refresh, retry
            self._refresh(state, u)
            out, err = self._function(state, u, self._J)
            err = float(err)
        if err <= tol:                            # False for NaN
            out = np.asarray(out).ravel()
            if err > 0.1 * tol:                  # converging slowly: refresh next time
                self._J = None
            return out
        return self._robust_step(state, u)

    def _refresh(self, state, u):
        self._J = self._jacobian(state, u[0, 0])
        self.jacobian_updates += 1

    def _robust_step(self, state, u) -> np.ndarray:
        if self._robust is None:
            self._robust = _robust_step_function(self.model, self.settings)
        self.fallbacks += 1
        try:
            out = np.asarray(self._robust(state, u)).ravel()
        except RuntimeError as exc:
            raise HubbeamError(f"{self.model.name.upper()}: the implicit step did not converge "
                               f"({str(exc).splitlines()[0][:80]})") from None
        if not np.all(np.isfinite(out)):
            raise HubbeamError(f"{self.model.name.upper()}: the implicit step returned non-finite values")
        return out


def _substep_expressions(model: HubBeamModel, settings: StepperSettings):
    """Symbolic generalized-alpha update: residual and new state as functions of ``a``."""
    n = model.n_q
    h = settings.dt / settings.substeps
    am, af, gamma, beta = generalized_alpha_coefficients(settings.rho_inf)
    s = ca.SX.sym("s", 4 * n)
    tau = ca.SX.sym("tau")
    a = ca.SX.sym("a", n)
    q0, v0, a0, p0 = s[:n], s[n:2 * n], s[2 * n:3 * n], s[3 * n:]
    p1 = ((1 - af) * a + af * a0 - am * p0) / (1 - am)
    q1 = q0 + h * v0 + h * h * (0.5 - beta) * p0 + h * h * beta * p1
    v1 = v0 + h * (1 - gamma) * p0 + h * gamma * p1
    force = ca.vertcat(tau, ca.SX.zeros(n - 1))
    return s, tau, a, (q1, v1, p1), force


@lru_cache(maxsize=16)
def _iteration_matrix_function(model: HubBeamModel, settings: StepperSettings) -> ca.Function:
    """Jacobian of the step residual in the new accelerations, at the predictor ``a = a_n``."""
    n = model.n_q
    s, tau, a, (q1, v1, p1), force = _substep_expressions(model, settings)
    residual = model.inverse_dynamics_function(q1, v1, a) - force
    J = ca.substitute(ca.jacobian(residual, a), a, s[2 * n:3 * n])
    return ca.Function("iteration_matrix", [s, tau], [J], ["s", "tau"], ["J"], {"cse": True})


@lru_cache(maxsize=16)
def _fast_step_function(model: HubBeamModel, settings: StepperSettings) -> ca.Function:
    """One sample: ``substeps`` steps of modified Newton with a given iteration matrix."""
    n = model.n_q
    s, tau, a, (q1, v1, p1), force = _substep_expressions(model, settings)
    residual = model.inverse_dynamics_function(q1, v1, a) - force
    opts = {"cse": True}
    R = ca.Function("residual", [a, s, tau], [residual], opts)
    update = ca.Function("update", [a, s], [ca.vertcat(q1, v1, a, p1)], opts)
    S = ca.MX.sym("s", 4 * n)
    T = ca.MX.sym("tau")
    Jm = ca.MX.sym("J", n, n)
    A = S[2 * n:3 * n]
    delta = ca.MX.zeros(n)
    for _ in range(settings.newton_iterations):
        delta = ca.solve(Jm, R(A, S, T), "qr")
        A = A - delta
    sub = ca.Function("substep", [S, T, Jm], [update(A, S), ca.norm_inf(delta)])
    k = settings.substeps
    accum = sub.mapaccum("substeps", k)
    X = ca.MX.sym("x", 4 * n)
    U = ca.MX.sym("u", 1, k)
    xs, errs = accum(X, U, Jm)
    return ca.Function("plant_step", [X, U, Jm], [xs[:, -1], ca.mmax(errs)],
                       ["s", "tau", "J"], ["s_next", "err"])


@lru_cache(maxsize=16)
def _robust_step_function(model: HubBeamModel, settings: StepperSettings) -> ca.Function:
    n = model.n_q
    s, tau, a, (q1, v1, p1), force = _substep_expressions(model, settings)
    residual = model.inverse_dynamics_function(q1, v1, a) - force
    G = ca.Function("G", [a, ca.vertcat(s, tau)], [residual])
    rf = ca.rootfinder("rf", "newton", G, {"abstol": 1e-9, "abstolStep": 1e-13, "max_iter": 50,
                                          "line_search": False, "error_on_fail": True})
    update = ca.Function("update", [a, s], [ca.vertcat(q1, v1, a, p1)])
    S = ca.MX.sym("s", 4 * n)
    T = ca.MX.sym("tau")
    A = rf(S[2 * n:3 * n], ca.vertcat(S, T))
    sub = ca.Function("substep", [S, T], [update(A, S)])
    k = settings.substeps
    X = ca.MX.sym("x", 4 * n)
    U = ca.MX.sym("u", 1, k)
    xs = sub.mapaccum("substeps", k)(X, U)
    return ca.Function("plant_step_robust", [X, U], [xs[:, -1]])


# -- sensors --------------------------------------------------------------------------
@dataclass(frozen=True)
class SensorSettings:
    """Realistic hub sensors for output-feedback controllers (``measurement="sensors"``).

    The measurement is ``[theta, theta_dot, M_root]`` plus independent zero-mean Gaussian
    white noise of the standard deviations below, drawn afresh at each sample.
    """

    angle_noise_rad: float = 1e-4
    """Hub-angle encoder noise, standard deviation [rad] (about a 16-bit encoder)."""
    rate_noise_rad_s: float = 1e-3
    """Hub-rate (tachometer / gyro) noise, standard deviation [rad/s]."""
    moment_noise_nm: float = 0.02
    """Root bending-moment (strain gauge) noise, standard deviation [N m]."""
    seed: int = 0
    """Seed of the noise generator (runs are reproducible)."""

    def __post_init__(self):
        _check_nonnegative("angle_noise_rad", self.angle_noise_rad, "rad")
        _check_nonnegative("rate_noise_rad_s", self.rate_noise_rad_s, "rad/s")
        _check_nonnegative("moment_noise_nm", self.moment_noise_nm, "N m")

    @property
    def std(self) -> np.ndarray:
        """Noise standard deviations ``[rad, rad/s, N m]``."""
        return np.array([self.angle_noise_rad, self.rate_noise_rad_s, self.moment_noise_nm])


def sensor_matrix(params: Params, n_modes: int, n_axial: int = 0) -> np.ndarray:
    """Output matrix of the sensors ``[theta, theta_dot, M_root]`` on a state ``[q, v]``.

    ``M_root = EI f2''(0) q2`` is the bending moment at the beam root [N m].

    Parameters
    ----------
    params : Params
    n_modes : int
        Number of transverse modes in the state.
    n_axial : int
        Number of axial coordinates between ``theta`` and ``q2`` (0 for SFOAM).

    Returns
    -------
    ndarray (3, 2 (1 + n_axial + n_modes))
    """
    from .basis import modal_basis
    basis = modal_basis(params.replace(n_transverse=n_modes))
    n = 1 + n_axial + n_modes
    C = np.zeros((3, 2 * n))
    C[0, 0] = 1.0
    C[1, n] = 1.0
    C[2, 1 + n_axial:n] = params.EI * basis.f2pp_root
    return C


# -- closed loop ----------------------------------------------------------------------
@dataclass(frozen=True)
class ClosedLoopSettings:
    """Settings of :func:`simulate_closed_loop`."""

    dt: float = 0.01
    """Sample period of the controller and of the zero-order hold [s] (default 100 Hz)."""
    substeps: int = 2
    """Integration steps of the plant per sample (see :class:`StepperSettings`)."""
    rho_inf: float = 0.9
    """Numerical damping of the plant integrator, 0..1 (see :class:`StepperSettings`)."""
    newton_iterations: int = 3
    """Newton iterations per integration step (see :class:`StepperSettings`)."""
    sensors: SensorSettings = field(default_factory=SensorSettings)
    """Sensor noise for controllers that read ``"sensors"``."""
    divergence_limit: float = 0.3
    """The run stops when ``|v_tip| > divergence_limit * L`` [-]."""
    max_wall_s: float = 600.0
    """The run stops (flagged) when it has taken longer than this [s]."""

    def __post_init__(self):
        _check_positive("divergence_limit", self.divergence_limit, "-")
        _check_positive("max_wall_s", self.max_wall_s, "s")
        if not isinstance(self.sensors, SensorSettings):
            raise ParameterError("sensors must be a SensorSettings")
        self.stepper  # validates dt, substeps, rho_inf, newton_iterations

    @property
    def stepper(self) -> StepperSettings:
        """The plant integrator's settings."""
        return StepperSettings(dt=self.dt, substeps=self.substeps, rho_inf=self.rho_inf,
                               newton_iterations=self.newton_iterations)


@dataclass
class ClosedLoopResult(HubStateViews):
    """Time series of one closed-loop run, sampled at the controller's instants.

    Attributes
    ----------
    plant : str
        Plant model name.
    controller : str
        Controller name.
    t : ndarray (N,)
        Sample instants [s].
    q, v : ndarray (N, n_q)
        Plant coordinates ``[theta, q1, q2]`` [rad, m] and rates.
    v_tip, u_tip : ndarray (N,)
        Transverse and axial tip displacement in the hub frame [m].
    root_moment : ndarray (N,)
        Root bending moment ``EI f2''(0) q2`` [N m] (noise-free).
    tau : ndarray (N,)
        Torque commanded at ``t_k`` and held until ``t_{k+1}`` [N m] (the last one is
        computed but not applied).
    step_time_s : ndarray (N,)
        Wall time of each controller call [s].
    theta_ref, theta_dot_ref : ndarray (N,) or None
        The task's hub reference [rad, rad/s], when the caller gave one.
    params : Params
    settings : dict
    controller_stats : dict
        What the controller's ``stats()`` returned at the end (e.g. QP fallbacks).
    stopped : bool
        True when the run ended early; ``message`` says why.
    message : str
    wall_s : float
        Wall time of the whole run [s].
    plant_fallbacks : int
        Integration steps that needed the exact rootfinder.
    """

    plant: str
    controller: str
    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    v_tip: np.ndarray
    u_tip: np.ndarray
    root_moment: np.ndarray
    tau: np.ndarray
    step_time_s: np.ndarray
    params: Params
    theta_ref: np.ndarray | None = None
    theta_dot_ref: np.ndarray | None = None
    settings: dict = field(default_factory=dict)
    controller_stats: dict = field(default_factory=dict)
    stopped: bool = False
    message: str = "completed"
    wall_s: float = 0.0
    plant_fallbacks: int = 0

    def save(self, path):
        """Save all arrays and metadata to a ``.npz`` file (atomically).

        Parameters
        ----------
        path : str or Path
        """
        import json
        from pathlib import Path

        from .fileio import atomic_write
        path = Path(path)
        if path.suffix.lower() != ".npz":
            raise ParameterError(f"path must end in .npz, got {path.name!r}")
        arrays = {k: getattr(self, k) for k in ("t", "q", "v", "v_tip", "u_tip", "root_moment",
                                                "tau", "step_time_s")}
        for k in ("theta_ref", "theta_dot_ref"):
            if getattr(self, k) is not None:
                arrays[k] = getattr(self, k)
        meta = {"plant": self.plant, "controller": self.controller,
                "params": self.params.to_dict(), "settings": self.settings,
                "controller_stats": self.controller_stats, "stopped": self.stopped,
                "message": self.message, "wall_s": self.wall_s}

        def write(tmp):
            with open(tmp, "wb") as fh:
                np.savez(fh, metadata=json.dumps(meta, default=str), **arrays)
        return atomic_write(path, write)


def _controller_name(controller) -> str:
    return str(getattr(controller, "name", type(controller).__name__))


def simulate_closed_loop(plant, controller, t_end: float = 30.0, *, params: Params | None = None,
                         settings: ClosedLoopSettings | None = None, x0=None,
                         reference=None) -> ClosedLoopResult:
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
    ClosedLoopResult

    Notes
    -----
    A controller that returns a non-finite torque, or a plant that leaves its range
    (``|v_tip| > divergence_limit * L``), stops the run: the result is cut there, with
    ``stopped = True`` and a message naming the cause.
    """
    settings = settings or ClosedLoopSettings()
    model = resolve_model(plant, params)
    _check_positive("t_end", t_end, "s")
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
    t = dt * np.arange(N + 1)
    rng = np.random.default_rng(settings.sensors.seed)
    noise = rng.standard_normal((N + 1, 3)) * settings.sensors.std if kind == "sensors" else None
    f2_tip = model.basis.f2_tip
    sl2 = model.transverse_slice
    limit = settings.divergence_limit * model.params.L

    states = np.empty((N + 1, 2 * n))
    taus = np.full(N + 1, np.nan)
    step_times = np.full(N + 1, np.nan)
    x = np.zeros(2 * n) if x0 is None else np.asarray(x0, dtype=float).ravel()
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
        tau = controller(t[k], y)
        step_times[k] = perf() - t0
        tau = float(tau)
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
        if (k & 255) == 0 and perf() - start > settings.max_wall_s:
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
    return ClosedLoopResult(
        plant=model.name, controller=name, t=t, q=q, v=v, v_tip=v_tip, u_tip=u_tip,
        root_moment=root_moment, tau=taus, step_time_s=step_times, params=model.params,
        theta_ref=theta_ref, theta_dot_ref=theta_dot_ref, settings=s_dict,
        controller_stats=stats, stopped=stopped, message=message, wall_s=wall,
        plant_fallbacks=stepper.fallbacks)


def simulate_fixed_step(plant, torque, t_end: float, *, params: Params | None = None,
                        settings: StepperSettings | None = None, x0=None) -> dict:
    """Integrate a free-hub model under a torque profile with :class:`PlantStepper`.

    The torque is evaluated at the end of every substep (no zero-order hold), so the
    result can be compared with :func:`hubbeam_ctrl.simulate.simulate` directly.

    Parameters
    ----------
    plant : str or HubBeamModel
    torque : callable
        ``torque(t)`` [N m] of an array of times [s] (e.g. a ``TorquePulse``).
    t_end : float
        Final time [s].
    params : Params, optional
    settings : StepperSettings, optional
    x0 : array_like (2 n_q,), optional

    Returns
    -------
    dict
        ``t`` (N+1,) [s], ``q``, ``v`` (N+1, n_q), ``v_tip`` (N+1,) [m], ``wall_s``,
        ``ms_per_step`` (wall time per sample) and ``fallbacks``.
    """
    model = resolve_model(plant, params)
    settings = settings or StepperSettings()
    _check_positive("t_end", t_end, "s")
    stepper = PlantStepper(model, settings)
    dt, k = settings.dt, settings.substeps
    N = int(round(t_end / dt))
    t = dt * np.arange(N + 1)
    sub = (t[:-1, None] + dt * np.arange(1, k + 1)[None, :] / k)
    u = np.asarray(torque(sub), dtype=float) * np.ones_like(sub)
    n = model.n_q
    s = stepper.initial_state(x0, float(np.asarray(torque(np.array(0.0)))))
    out = np.empty((N + 1, 2 * n))
    out[0] = s[:2 * n]
    start = time.perf_counter()
    for i in range(N):
        s = stepper.step(s, u[i])
        out[i + 1] = s[:2 * n]
    wall = time.perf_counter() - start
    q, v = out[:, :n], out[:, n:]
    v_tip = np.array(model.tip_function.map(N + 1)(q.T)[0]).ravel()
    return {"t": t, "q": q, "v": v, "v_tip": v_tip, "wall_s": wall,
            "ms_per_step": 1e3 * wall / max(N, 1), "fallbacks": stepper.fallbacks,
            "jacobian_updates": stepper.jacobian_updates}
