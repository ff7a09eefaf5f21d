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

import contextlib
import dataclasses
import io
import math
import time

import numpy as np
from numpy.linalg import _umath_linalg

from hubbeam_ctrl.core.budget import T_END_MAX, check_budget
from hubbeam_ctrl.core.compiled import OPT_COLD, OPT_HOT, compile_function
from hubbeam_ctrl.core.errors import HubbeamError, ParameterError
from hubbeam_ctrl.core.recipes import compile_recipe
from hubbeam_ctrl.core.validation import check_in_range
from hubbeam_ctrl.plant.models import HubBeamModel, resolve_model
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.sim.hardware import Hardware, drive_torque
from hubbeam_ctrl.sim.results import Result, describe_input

# the compiled step (settings, CasADi functions) and the scheme's accuracy with the substep rule;
# their names stay importable from here
from hubbeam_ctrl.sim.step_functions import (  # noqa: F401
    StepperSettings,
    _fast_step_function,
    _hold_function,
    _iteration_matrix_function,
    _robust_step_function,
    _substep_expressions,
    model_recipe,
    step_functions,
)
from hubbeam_ctrl.sim.step_rule import (  # noqa: F401
    MAX_SUBSTEPS,
    SubstepRule,
    generalized_alpha_coefficients,
    max_step_for_frequency,
    period_error,
    substep_rule,
)

__all__ = ["StepperSettings", "PlantStepper", "simulate_fixed_step", "generalized_alpha_coefficients",
           "period_error", "max_step_for_frequency", "SubstepRule", "substep_rule", "MAX_SUBSTEPS",
           "step_functions"]

#: A fast step that does not converge is tried again with this many times its Newton iterations
#: (at most 20) before the rootfinder: measured on the 1 m lab arm's LQR slew, the fast step
#: missed its tolerance by 1-20x on 55 of 600 samples, each costing the rootfinder ~30 ms.
PATIENCE = 3
#: The patient step is kept only when its last Newton increment is this fraction of ``newton_tol``
#: (a slowly converging step is not trusted: the rootfinder takes those).
PATIENT_TOLERANCE = 1e-3


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
    hardware : Hardware, optional
        The drive and friction between the command and the hub
        (:class:`~hubbeam_ctrl.sim.hardware.Hardware`): the input of :meth:`step` is then the
        command (a voltage for a DC motor) and the hub torque ``drive - friction`` is applied
        inside the implicit step at the end of every substep. With friction the hub sticks
        (Karnopp): a hub that slows into ``friction.stick_velocity`` or reverses within a
        sample is recomputed held at rest (its rate set to zero at the end of the substep),
        and stays held while the torque needed to hold it (:attr:`hold_torque`) is within
        the breakaway torque; :attr:`stuck` says whether it is. None or ideal hardware (torque
        drive, no friction): today's step, bit for bit.

    Examples
    --------
    >>> from hubbeam_ctrl import build_model
    >>> stepper = PlantStepper(build_model("foam"))
    >>> s = stepper.initial_state(tau=100.0)
    >>> s = stepper.step(s, 100.0)          # 10 ms at 100 N m
    >>> round(float(s[stepper.model.n_q]), 4)   # hub rate [rad/s]
    0.005
    """

    def __init__(self, model: HubBeamModel, settings: StepperSettings | None = None, backend=None,
                 hardware: Hardware | None = None):
        self.model = model
        self.settings = settings or StepperSettings()
        self.n_q = model.n_q
        self.h = self.settings.dt / self.settings.substeps
        self.fallbacks = 0
        self.jacobian_updates = 0
        #: Samples the fast step needed its patient version for (more Newton iterations) instead of
        #: the rootfinder.
        self.patient_steps = 0
        if hardware is not None and not isinstance(hardware, Hardware):
            raise ParameterError(f"hardware must be a Hardware (hubbeam_ctrl.sim.hardware), got "
                                 f"{type(hardware).__name__}")
        self.hardware = None if hardware is None or hardware.mechanics_ideal else hardware
        #: True when the armature inductance makes the current a state (the last entry of ``s``).
        self.inductive = self.hardware is not None and self.hardware.inductive
        self.n_s = 4 * model.n_q + (1 if self.inductive else 0)
        #: True while friction holds the hub at rest (only with hardware that has friction).
        self.stuck = False
        #: Torque the friction exerts to hold the hub at the last held sample [N m].
        self.hold_torque = 0.0
        self.stick_events = 0
        if self.hardware is not None:
            self._F_s, self._v_stick = self.hardware.friction.static, self.hardware.friction.stick_velocity
        self._function, self._jacobian, self.backend = step_functions(model, self.settings, backend,
                                                                      hardware=self._hardware_kind)
        self._setup_buffers()
        self._robust = None

    @property
    def _hardware_kind(self):
        """The hardware variant of the compiled functions: False, True or ``"inductive"``."""
        return "inductive" if self.inductive else self.hardware is not None

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
        if self.inductive:      # the circuit settled at the initial command and rate (di/dt = 0): L = 0's start
            d, thd = self.hardware.drive, x0[n]
            i0 = min(max((min(max(float(tau), -d.V_max), d.V_max) - d.k_e * d.N * thd) / d.R, -d.I_max), d.I_max)
            return np.concatenate([self._hardware_initial_state(x0, float(tau)), [i0]])
        if self.hardware is None:
            a0 = self._accelerations(x0[:n], x0[n:], float(tau))
            return np.concatenate([x0, a0, a0])
        return self._hardware_initial_state(x0, float(tau))

    def _hardware_initial_state(self, x0, u: float) -> np.ndarray:
        """Initial state with the hardware: the hub held at rest when friction can hold it."""
        n, hw = self.n_q, self.hardware
        q, v = x0[:n], x0[n:]
        f = hw.friction
        self.stuck = False
        if f.static > 0 and abs(v[0]) <= f.stick_velocity:
            M, c = self._mass_bias(q, v)
            a = np.zeros(n)
            a[1:] = np.linalg.solve(M[1:, 1:], -c[1:])          # the hub clamped
            hold = float(drive_torque(u, 0.0, hw.values())) - (M[0] @ a + c[0])
            if abs(hold) <= f.static:
                self.stuck, self.hold_torque = True, hold
                x = x0.copy()
                x[n] = 0.0
                return np.concatenate([x, a, a])
        a0 = self._accelerations(q, v, float(hw.hub_torque(u, v[0])))
        return np.concatenate([x0, a0, a0])

    def _mass_bias(self, q, v) -> tuple:
        """``(M(q), c(q, v))`` as the model gives them, evaluated by the compiled functions of their
        recipes (the same numbers bit for bit; a process then builds no VM function for them)."""
        pm = self.model.parametric
        if self.backend == "vm" or pm.axial != "dynamic":
            return self.model.mass_matrix(q, v), self.model.bias(q, v)
        M = compile_recipe(model_recipe(pm, "mass_matrix"), lambda: pm.mass_matrix, self.backend, opt=OPT_COLD)
        c = compile_recipe(model_recipe(pm, "bias"), lambda: pm.bias, self.backend, opt=OPT_COLD)
        return np.array(M(q, self._p)), np.array(c(q, v, self._p)).ravel()

    def mass_positive(self, q, v) -> bool:
        """Whether the model's mass matrix ``M(q)`` is positive definite (a Cholesky factor exists).

        Past a large deflection a first-order model's kinetic energy is no longer positive: its
        mass matrix loses definiteness and the equations of motion have no meaningful solution.
        Measured on ``servo_payload``'s 12-mode FOAM (issue 36): the hub's effective inertia (the
        Schur complement of ``M`` on the hub) falls from 2.0e-3 kg m^2 at 0.14 L to 2.1e-5 at
        0.579 L and is -4.3e-5 at 0.588 L, where the implicit step stops converging.

        Parameters
        ----------
        q, v : array_like (n_q,)
            Coordinates [rad, m] and velocities [rad/s, m/s].

        Returns
        -------
        bool
        """
        M, _ = self._mass_bias(np.asarray(q, dtype=float), np.asarray(v, dtype=float))
        try:
            np.linalg.cholesky(0.5 * (M + M.T))
        except np.linalg.LinAlgError:
            return False
        return True

    def _accelerations(self, q, v, tau: float) -> np.ndarray:
        """Free-hub accelerations ``M^-1 (B tau - c)``, as :meth:`HubBeamModel.accelerations`."""
        M, c = self._mass_bias(q, v)
        rhs = -c
        rhs[0] += tau
        return np.linalg.solve(M, rhs)

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
        return self._advance().copy()

    def run(self, state, taus) -> np.ndarray:
        """Advance over many samples of known torques (an open-loop run), in one loop.

        Each sample is exactly :meth:`step`; the loop only saves the per-call copies.

        Parameters
        ----------
        state : ndarray (4 n_q,)
            Integrator state at the start [see :meth:`initial_state`].
        taus : array_like (N, substeps)
            Hub torque [N m] at the end of each substep of each sample.

        Returns
        -------
        ndarray (N, 4 n_q)
            State at the end of every sample.
        """
        taus = np.asarray(taus, dtype=float).reshape(-1, self.settings.substeps)
        out = np.empty((len(taus), self.n_s))
        s_in, u = self._s_in, self._u
        s_in[:] = state
        for i in range(len(taus)):
            u[:] = taus[i]
            out[i] = self._advance()
            s_in[:] = out[i]
        return out

    def _advance(self) -> np.ndarray:
        """One sample from the state and torques in the input buffers (a buffer: copy to keep)."""
        if self.hardware is None:
            return self._advance_one()
        return self._advance_hardware()

    def _set_stick(self, stick: bool):
        if bool(self._hw[-1]) != stick:
            self._hw[-1] = 1.0 if stick else 0.0
            self._J_valid = False              # the hub row of the iteration matrix changes

    def _advance_hardware(self) -> np.ndarray:
        """One sample with the hardware: slip, or stick while friction holds the hub (Karnopp)."""
        n, F_s, v_stick = self.n_q, self._F_s, self._v_stick
        if F_s == 0.0:
            return self._advance_one()
        # the input buffer _s_in is not written by a step: each trial starts from it
        if self.stuck:
            self._set_stick(True)
            out = self._advance_one()
            if self._holds(out):
                return out
            self.stuck = False                  # breakaway: the sample again, sliding
        self._set_stick(False)
        out = self._advance_one()
        thd0, thd1 = float(self._s_in[n]), float(out[n])
        if abs(thd1) <= v_stick and (abs(thd1) < abs(thd0) or thd0 == 0.0) or thd0 * thd1 < 0:
            slip = out.copy()
            self._set_stick(True)
            held = self._advance_one()
            if self._holds(held):
                self.stuck = True
                self.stick_events += 1
                return held
            self._set_stick(False)
            self._s_out[:] = slip
            return self._s_out
        return out

    def _holds(self, out) -> bool:
        """Whether friction can hold the hub at the end of a held sample (updates :attr:`hold_torque`)."""
        self._s_hold[:] = out
        self._eval_hold()
        self.hold_torque = float(self._hold[0])
        return abs(self.hold_torque) <= self._F_s

    def _advance_one(self) -> np.ndarray:
        """One sample as the buffers say (slip or stick), with the iteration-matrix refreshes."""
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
            return self._s_out
        if self._eval_patient is None:
            self._eval_patient = self._bind_step(self._patient_function())
        self._eval_patient()                      # the fresh matrix, PATIENCE times the iterations
        if self._err[0] <= PATIENT_TOLERANCE * tol:      # converged well past the fast step's tolerance
            self.patient_steps += 1
            self._J_valid = False
            return self._s_out
        return self._robust_step(self._s_in.copy(), self._u.reshape(1, -1).copy())

    def _patient_function(self):
        """The fast step with :data:`PATIENCE` times the Newton iterations (compiled once, on first need),
        for the same hardware variant as the fast step (ideal, hardware or inductive)."""
        patient = dataclasses.replace(self.settings,
                                      newton_iterations=min(20, PATIENCE * self.settings.newton_iterations))
        kind = self._hardware_kind
        vm = _fast_step_function(self.model.parametric, patient, *((kind,) if kind else ()))
        return vm if self.backend == "vm" else compile_function(vm, self.backend, opt=OPT_HOT)

    def _bind_step(self, function):
        """``function`` (a plant step) bound to the stepper's buffers."""
        extra = (self._hw,) if self.hardware is not None else ()
        return self._bind(function, (self._s_in, self._u, self._Jinv.reshape(-1, order="F"), self._p) + extra,
                          (self._s_out, self._err))

    def _setup_buffers(self):
        """Preallocated arrays bound to ``Function.buffer()`` calls (no argument conversion)."""
        n, k = self.n_q, self.settings.substeps
        self._s_in, self._u, self._Jbuf = np.zeros(self.n_s), np.zeros(k), np.zeros(n * n)
        self._Jinv = np.zeros((n, n), order="F")
        self._Jmat = self._Jbuf.reshape(n, n, order="F")      # a view of the iteration matrix's buffer
        self._s_out, self._err, self._tau0 = np.zeros(self.n_s), np.zeros(1), np.zeros(1)
        self._p = np.array(self.model.p, dtype=float)
        self._J_valid = False
        self._buffers = []
        extra = ()
        if self.hardware is not None:
            self._hw = self.hardware.values()
            self._s_hold, self._hold = np.zeros(self.n_s), np.zeros(1)
            extra = (self._hw,)
            pm, inductive = self.model.parametric, (True,) if self.inductive else ()
            hold = compile_recipe(model_recipe(pm, "hub_hold", *inductive), lambda: _hold_function(pm, *inductive),
                                  self.backend, opt=OPT_HOT)
            self._eval_hold = self._bind(hold, (self._s_hold, self._u[-1:], self._p, self._hw), (self._hold,))
        self._eval_step = self._bind_step(self._function)
        self._eval_patient = None
        self._eval_jacobian = self._bind(self._jacobian, (self._s_in, self._tau0, self._p) + extra, (self._Jbuf,))

    def _bind(self, function, args, results):
        buf, evaluate = function.buffer()
        for i, a in enumerate(args):
            buf.set_arg(i, memoryview(a))
        for i, r in enumerate(results):
            buf.set_res(i, memoryview(r))
        self._buffers.append(buf)                 # keep the buffer alive with its arrays
        return evaluate

    def _refresh(self):
        """The iteration matrix at the input state and its inverse, into ``_Jinv``.

        The inverse is ``numpy.linalg.inv``'s own LAPACK routine (``gesv`` on the identity) called
        without its Python checks and copies, into the bound buffer: the same numbers bit for bit
        at half the cost (issue 38: 4.6 -> 2.6 us for 5 coordinates). A singular matrix gives NaN
        (no warning): the fast step fails and the rootfinder takes over.
        """
        self._tau0[0] = self._u[0]
        self._eval_jacobian()
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            _umath_linalg.inv(self._Jmat, signature="d->d", out=self._Jinv)
        self._J_valid = True
        self.jacobian_updates += 1

    def _robust_step(self, state, u) -> np.ndarray:
        if self._robust is None:
            self._robust = _robust_step_function(self.model.parametric, self.settings, self._hardware_kind)
        self.fallbacks += 1
        extra = () if self.hardware is None else (self._hw,)
        try:
            # a failed rootfinder prints its inputs (through sys.stderr): kept off the terminal
            with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
                out = np.asarray(self._robust(state, u, self._p, *extra)).ravel()
        except RuntimeError as exc:
            raise HubbeamError(f"{self.model.name.upper()}: the implicit step did not converge "
                               f"({str(exc).splitlines()[0][:80]})") from None
        if not np.all(np.isfinite(out)):
            raise HubbeamError(f"{self.model.name.upper()}: the implicit step returned non-finite values")
        return out


def simulate_fixed_step(plant, torque, t_end: float, *, params: Params | None = None,
                        settings: StepperSettings | None = None, x0=None, backend=None,
                        axial: str | None = None, hardware: Hardware | None = None,
                        max_memory_mb: float = 2048.0) -> Result:
    """Integrate a free-hub model under a torque profile with :class:`PlantStepper`.

    The torque is evaluated at the end of every substep (no zero-order hold), so the
    result can be compared with :func:`hubbeam_ctrl.sim.simulate.simulate` directly.

    Parameters
    ----------
    plant : str or HubBeamModel
        ``"foam"``, ``"cfoam"``, ``"tlam"``, ``"sfoam"`` or a built model (free hub).
    torque : callable
        ``torque(t)`` [N m] of an array of times [s] (e.g. a ``TorquePulse``).
    t_end : float
        Final time [s], > 0.
    params : Params, optional
        Parameters when ``plant`` is a name.
    settings : StepperSettings, optional
    x0 : array_like (2 n_q,), optional
        Initial state ``[q, v]`` (default: at rest).
    backend : {"auto", "compiled", "vm"}, optional
        See :class:`PlantStepper`.
    axial : {"dynamic", "quasi-static"}, optional
        With a model name: how the axial coordinates move (see
        :func:`~hubbeam_ctrl.plant.models.build_model`).
    hardware : Hardware, optional
        Drive and friction (see :class:`PlantStepper`): ``torque`` is then the command
        (a voltage [V] for a DC motor) and is stored as ``tau``.
    max_memory_mb : float
        A run whose results would need more memory than this [MB] is refused before it starts.

    Returns
    -------
    Result
        Of kind ``"fixed_step"``: ``t`` (N+1,) [s] on the sample grid, ``q``, ``v``, ``a``
        (N+1, n_q), ``v_tip``, ``u_tip`` [m], the applied ``tau`` [N m], ``wall_s`` and
        ``stats`` with ``ms_per_step`` (wall time per sample), ``fallbacks`` and
        ``jacobian_updates``.
    """
    model = resolve_model(plant, params, axial)
    settings = settings or StepperSettings()
    t_end = check_in_range("t_end", t_end, "s", settings.dt, T_END_MAX, "at least two samples: t_end >= dt")
    dt, k = settings.dt, settings.substeps
    N = int(round(t_end / dt))
    check_budget(f"t_end = {t_end:g} s at dt = {dt:g} s ({N + 1} samples)",
                 memory_bytes=8.0 * (N + 1) * (k + 4 * model.n_q + 4), seconds=0.0,
                 max_memory_mb=max_memory_mb, max_wall_s=math.inf)
    stepper = PlantStepper(model, settings, backend, hardware=hardware)
    t = dt * np.arange(N + 1)
    sub = (t[:-1, None] + dt * np.arange(1, k + 1)[None, :] / k)
    u = np.asarray(torque(sub), dtype=float) * np.ones_like(sub)
    n = model.n_q
    tau0 = float(np.asarray(torque(np.array(0.0))))
    s = stepper.initial_state(x0, tau0)
    out = np.empty((N + 1, 3 * n))
    out[0] = s[:3 * n]
    start = time.perf_counter()
    out[1:] = stepper.run(s, u)[:, :3 * n]
    wall = time.perf_counter() - start
    q, v, a = out[:, :n], out[:, n:2 * n], out[:, 2 * n:]
    v_tip, u_tip = model.tip_series(q, v)
    tau = np.concatenate([[tau0], u[:, -1]])
    stats = {"ms_per_step": 1e3 * wall / max(N, 1), "fallbacks": stepper.fallbacks,
             "jacobian_updates": stepper.jacobian_updates, "backend": stepper.backend}
    return Result(kind="fixed_step", model=model.name, t=t, q=q, v=v, a=a, v_tip=v_tip,
                  u_tip=u_tip, tau=tau, params=model.params,
                  settings={"torque": describe_input(torque), "t_end": float(t_end),
                            **dataclasses.asdict(settings)},
                  stats=stats, wall_s=wall)
