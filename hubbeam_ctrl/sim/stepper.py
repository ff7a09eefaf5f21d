"""Fixed-step plant integrator: generalized-alpha, one compiled CasADi call per sample.

:class:`PlantStepper` is a fixed-step implicit integrator compiled into one CasADi
function per sample, so a closed-loop step costs one Python call for the plant. The method
is the generalized-alpha scheme of Chung and Hulbert (1993) in the form of Arnold and Bruls
(2007) for ``M(q) a + c(q, v) = B tau``, with the new accelerations as unknowns of
``model.inverse_dynamics_function(q, v, a) - B tau = 0`` (the mass matrix is never inverted
symbolically). Its spectral radius at infinity ``rho_inf`` (default 0.9) damps the stiff
axial modes (up to ~1.4 kHz) that a step of a few milliseconds cannot resolve, while the
bending modes are integrated with second-order accuracy. Each step solves the implicit
equations by modified Newton iterations started from the previous acceleration, with the
iteration matrix (the exact Jacobian of the plant's own residual, evaluated at the
predictor) refreshed whenever the iterations converge slowly; a step whose last Newton
correction is not small enough is recomputed with CasADi's ``rootfinder('newton')``.
"""


from __future__ import annotations

import time
from dataclasses import dataclass
from functools import lru_cache

import casadi as ca
import numpy as np

from hubbeam_ctrl.core.compiled import OPT_COLD, OPT_HOT, compile_function
from hubbeam_ctrl.core.errors import HubbeamError, ParameterError
from hubbeam_ctrl.core.validation import check_positive as _check_positive
from hubbeam_ctrl.plant.models import HubBeamModel, ParametricModel, resolve_model
from hubbeam_ctrl.plant.params import Params

__all__ = ["StepperSettings", "PlantStepper", "simulate_fixed_step", "generalized_alpha_coefficients",
           "step_functions"]


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
    backend : {"auto", "compiled", "vm"}, optional
        How the step and its iteration matrix are evaluated (see
        :mod:`hubbeam_ctrl.core.compiled`); default ``$HUBBEAM_BACKEND`` or ``"auto"``.
        :attr:`backend` holds the one in use (``"compiled"`` or ``"vm"``).

    Examples
    --------
    >>> from hubbeam_ctrl import build_model
    >>> stepper = PlantStepper(build_model("foam"))
    >>> s = stepper.initial_state(tau=100.0)
    >>> s = stepper.step(s, 100.0)          # 10 ms at 100 N m
    >>> round(float(s[stepper.model.n_q]), 4)   # hub rate [rad/s]
    0.005
    """

    def __init__(self, model: HubBeamModel, settings: StepperSettings | None = None, backend=None):
        self.model = model
        self.settings = settings or StepperSettings()
        self.n_q = model.n_q
        self.n_s = 4 * model.n_q
        self.h = self.settings.dt / self.settings.substeps
        self.fallbacks = 0
        self.jacobian_updates = 0
        self._function, self._jacobian, self.backend = step_functions(model, self.settings, backend)
        self._setup_buffers()
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
        self._s_in[:] = state
        self._u[:] = tau
        tol = self.settings.newton_tol
        fresh = not self._J_valid
        if fresh:
            self._refresh()
        self._eval_step()
        err = self._err[0]
        if not err <= tol and not fresh:          # stale iteration matrix: refresh, retry
            self._refresh()
            self._eval_step()
            err = self._err[0]
        if err <= tol:                            # False for NaN
            if err > 0.1 * tol:                  # converging slowly: refresh next time
                self._J_valid = False
            return self._s_out.copy()
        return self._robust_step(self._s_in.copy(), self._u.reshape(1, -1).copy())

    def _setup_buffers(self):
        """Preallocated arrays bound to ``Function.buffer()`` calls (no argument conversion)."""
        n, k = self.n_q, self.settings.substeps
        self._s_in, self._u, self._Jbuf = np.zeros(4 * n), np.zeros(k), np.zeros(n * n)
        self._Jinv = np.zeros((n, n), order="F")
        self._s_out, self._err, self._tau0 = np.zeros(4 * n), np.zeros(1), np.zeros(1)
        self._p = np.array(self.model.p, dtype=float)
        self._J_valid = False
        self._buffers = []
        self._eval_step = self._bind(self._function,
                                     (self._s_in, self._u, self._Jinv.reshape(-1, order="F"), self._p),
                                     (self._s_out, self._err))
        self._eval_jacobian = self._bind(self._jacobian, (self._s_in, self._tau0, self._p), (self._Jbuf,))

    def _bind(self, function, args, results):
        buf, evaluate = function.buffer()
        for i, a in enumerate(args):
            buf.set_arg(i, memoryview(a))
        for i, r in enumerate(results):
            buf.set_res(i, memoryview(r))
        self._buffers.append(buf)                 # keep the buffer alive with its arrays
        return evaluate

    def _refresh(self):
        self._tau0[0] = self._u[0]
        self._eval_jacobian()
        try:
            self._Jinv[:] = np.linalg.inv(self._Jbuf.reshape(self.n_q, self.n_q, order="F"))
        except np.linalg.LinAlgError:          # singular: the fast step fails, the rootfinder takes over
            self._Jinv[:] = np.nan
        self._J_valid = True
        self.jacobian_updates += 1

    def _robust_step(self, state, u) -> np.ndarray:
        if self._robust is None:
            self._robust = _robust_step_function(self.model.parametric, self.settings)
        self.fallbacks += 1
        try:
            out = np.asarray(self._robust(state, u, self._p)).ravel()
        except RuntimeError as exc:
            raise HubbeamError(f"{self.model.name.upper()}: the implicit step did not converge "
                               f"({str(exc).splitlines()[0][:80]})") from None
        if not np.all(np.isfinite(out)):
            raise HubbeamError(f"{self.model.name.upper()}: the implicit step returned non-finite values")
        return out


def _substep_expressions(model: ParametricModel, settings: StepperSettings):
    """Symbolic generalized-alpha update: residual and new state as functions of ``a``."""
    n = model.n_q
    h = settings.dt / settings.substeps
    am, af, gamma, beta = generalized_alpha_coefficients(settings.rho_inf)
    s = ca.SX.sym("s", 4 * n)
    tau = ca.SX.sym("tau")
    a = ca.SX.sym("a", n)
    p = ca.SX.sym("p", model.n_p)
    q0, v0, a0, p0 = s[:n], s[n:2 * n], s[2 * n:3 * n], s[3 * n:]
    p1 = ((1 - af) * a + af * a0 - am * p0) / (1 - am)
    q1 = q0 + h * v0 + h * h * (0.5 - beta) * p0 + h * h * beta * p1
    v1 = v0 + h * (1 - gamma) * p0 + h * gamma * p1
    force = ca.vertcat(tau, ca.SX.zeros(n - 1))
    residual = model.inverse_dynamics(q1, v1, a, p) - force
    return s, tau, a, p, (q1, v1, p1), residual


@lru_cache(maxsize=16)
def _iteration_matrix_function(model: ParametricModel, settings: StepperSettings) -> ca.Function:
    """Jacobian of the step residual in the new accelerations, at the predictor ``a = a_n``."""
    n = model.n_q
    s, tau, a, p, _, residual = _substep_expressions(model, settings)
    J = ca.densify(ca.substitute(ca.jacobian(residual, a), a, s[2 * n:3 * n]))
    return ca.Function("iteration_matrix", [s, tau, p], [J], ["s", "tau", "p"], ["J"], {"cse": True})


def step_functions(model: HubBeamModel, settings: StepperSettings, backend=None) -> tuple:
    """The plant step and its iteration matrix on a backend.

    Both take the model's parameter vector ``p`` (:attr:`HubBeamModel.p`) as their last
    input, so they are built (and compiled) once per model family, mode counts and
    settings, whatever the tip mass, tip position, material or geometry.

    Parameters
    ----------
    model : HubBeamModel
    settings : StepperSettings
    backend : {"auto", "compiled", "vm"}, optional

    Returns
    -------
    step : casadi.Function
        ``(s, tau (1, substeps), J_inv, p) -> (s_next, err)``, compiled at -O1 when compiled.
    iteration_matrix : casadi.Function
        ``(s, tau, p) -> J`` (dense), compiled at -O0 (refreshed only now and then).
    backend : str
        ``"compiled"`` or ``"vm"``: the backend the step runs on.
    """
    vm_step = _fast_step_function(model.parametric, settings)
    step = compile_function(vm_step, backend, opt=OPT_HOT)
    jac = compile_function(_iteration_matrix_function(model.parametric, settings), backend, opt=OPT_COLD)
    return step, jac, "vm" if step is vm_step else "compiled"


@lru_cache(maxsize=16)
def _fast_step_function(model: ParametricModel, settings: StepperSettings) -> ca.Function:
    """One sample: ``substeps`` steps of modified Newton with the inverse iteration matrix given."""
    n = model.n_q
    s, tau, a, p, (q1, v1, p1), residual = _substep_expressions(model, settings)
    opts = {"cse": True}
    R = ca.Function("residual", [a, s, tau, p], [residual], opts)
    update = ca.Function("update", [a, s], [ca.vertcat(q1, v1, a, p1)], opts)
    S = ca.MX.sym("s", 4 * n)
    T = ca.MX.sym("tau")
    P = ca.MX.sym("p", model.n_p)
    Jm = ca.MX.sym("J_inv", n, n)           # inverse of the iteration matrix: no factorisation per step
    A = S[2 * n:3 * n]
    delta = ca.MX.zeros(n)
    for _ in range(settings.newton_iterations):
        delta = ca.mtimes(Jm, R(A, S, T, P))
        A = A - delta
    sub = ca.Function("substep", [S, T, Jm, P], [update(A, S), ca.norm_inf(delta)])
    k = settings.substeps
    accum = sub.mapaccum("substeps", k)
    X = ca.MX.sym("x", 4 * n)
    U = ca.MX.sym("u", 1, k)
    xs, errs = accum(X, U, Jm, P)
    return ca.Function("plant_step", [X, U, Jm, P], [xs[:, -1], ca.mmax(errs)],
                       ["s", "tau", "J_inv", "p"], ["s_next", "err"])


@lru_cache(maxsize=16)
def _robust_step_function(model: ParametricModel, settings: StepperSettings) -> ca.Function:
    n = model.n_q
    s, tau, a, p, (q1, v1, p1), residual = _substep_expressions(model, settings)
    G = ca.Function("G", [a, ca.vertcat(s, tau, p)], [residual])
    rf = ca.rootfinder("rf", "newton", G, {"abstol": 1e-9, "abstolStep": 1e-13, "max_iter": 50,
                                          "line_search": False, "error_on_fail": True})
    update = ca.Function("update", [a, s], [ca.vertcat(q1, v1, a, p1)])
    S = ca.MX.sym("s", 4 * n)
    T = ca.MX.sym("tau")
    P = ca.MX.sym("p", model.n_p)
    A = rf(S[2 * n:3 * n], ca.vertcat(S, T, P))
    sub = ca.Function("substep", [S, T, P], [update(A, S)])
    k = settings.substeps
    X = ca.MX.sym("x", 4 * n)
    U = ca.MX.sym("u", 1, k)
    xs = sub.mapaccum("substeps", k)(X, U, P)
    return ca.Function("plant_step_robust", [X, U, P], [xs[:, -1]])


def simulate_fixed_step(plant, torque, t_end: float, *, params: Params | None = None,
                        settings: StepperSettings | None = None, x0=None, backend=None) -> dict:
    """Integrate a free-hub model under a torque profile with :class:`PlantStepper`.

    The torque is evaluated at the end of every substep (no zero-order hold), so the
    result can be compared with :func:`hubbeam_ctrl.sim.simulate.simulate` directly.

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
    backend : {"auto", "compiled", "vm"}, optional
        See :class:`PlantStepper`.

    Returns
    -------
    dict
        ``t`` (N+1,) [s], ``q``, ``v`` (N+1, n_q), ``v_tip`` (N+1,) [m], ``wall_s``,
        ``ms_per_step`` (wall time per sample) and ``fallbacks``.
    """
    model = resolve_model(plant, params)
    settings = settings or StepperSettings()
    _check_positive("t_end", t_end, "s")
    stepper = PlantStepper(model, settings, backend)
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
            "jacobian_updates": stepper.jacobian_updates, "backend": stepper.backend}
