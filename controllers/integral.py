"""Integral action by disturbance estimation (offset-free control) and observers for state feedback.

A constant torque at the hub that the design model does not know (Coulomb friction, a
gravity load, a drive whose torque constant is off) leaves a state-feedback loop with a
steady hub-angle error: with the LQG's loop gain of a few rad per N m, 10 mN m of friction
leaves about a degree. The standard cure that keeps the controller's structure is to model
the unknown torque as a state, ``d[k+1] = d[k]`` driven by white noise, estimate it with the
Kalman filter from the same sensors, and subtract it from the command (offset-free control,
Pannocchia and Rawlings 2003; Maeder, Borrelli and Morari 2009): with ``u = u_fb - d_hat``
the model's net input ``u + d_hat`` is the designed feedback, and at rest any angle error the
feedback asks torque for moves ``d_hat`` until the hub moves, i.e. integral action. Unlike an
integrator of the angle error it needs no anti-windup: ``d_hat`` is estimated from the torque
that was commanded and the motion that followed, so a saturated drive does not wind it up.

:class:`OffsetFreeEstimator` is the steady-state Kalman filter on the augmented model
``[x; d]``; :class:`ObservedFeedback` closes a state-feedback controller (LQR, MPC, which read
the plant's modal state in the simulator) through it, so it reads only the sensors
``[theta, theta_dot, M_root]`` a rig has, with or without the disturbance state.
:func:`observer_feedback_matrices` gives the linear law of either for the loop certificate.
"""

from __future__ import annotations

import math

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError

from .base import Controller, DesignModel, saturate
from .estimator import (
    AppliedTorque,
    KalmanNoise,
    decay_model,
    error_decay_rate,
    plan_offsets,
    plan_worth_predicting,
    solve_kalman,
)
from .filter_model import filter_gain, filter_matrices, filter_state_names
from .lqr import LQR

__all__ = ["OffsetFreeEstimator", "ObservedFeedback", "observer_feedback_matrices", "augment_disturbance"]


def augment_disturbance(Ad: np.ndarray, Bd: np.ndarray, C: np.ndarray):
    """The sampled model with a constant input disturbance as an extra state.

    ``[x; d][k+1] = [[Ad, Bd], [0, 1]] [x; d][k] + [Bd; 0] u[k]``, ``y = [C, 0] [x; d]``.

    Parameters
    ----------
    Ad : ndarray (nx, nx)
    Bd : ndarray (nx, 1)
    C : ndarray (ny, nx)

    Returns
    -------
    tuple of ndarray
        ``(Aa, Ba, Ca)`` of sizes ``(nx+1, nx+1)``, ``(nx+1, 1)``, ``(ny, nx+1)``.
    """
    nx = Ad.shape[0]
    Aa = np.zeros((nx + 1, nx + 1))
    Aa[:nx, :nx], Aa[:nx, nx:], Aa[nx, nx] = Ad, Bd, 1.0
    Ba = np.vstack([Bd, np.zeros((1, Bd.shape[1]))])
    Ca = np.hstack([C, np.zeros((C.shape[0], 1))])
    return Aa, Ba, Ca


class OffsetFreeEstimator:
    """Steady-state Kalman filter on the design model plus a constant input disturbance.

    Same interface as :class:`~controllers.estimator.KalmanEstimator`; the estimate has one
    more entry, the disturbance torque ``d_hat`` [N m] (:attr:`disturbance`), which the
    controller subtracts from its command.

    Parameters
    ----------
    model : DesignModel
        The filter's model (``Ad``, ``Bd``, ``C_sensors``).
    noise : KalmanNoise
        Sensor and process noise (:meth:`KalmanNoise.covariances`).
    disturbance_noise : float
        Standard deviation of the disturbance's random walk per sample [N m], > 0: sets how
        fast ``d_hat`` follows (the integral action's bandwidth).
    design_modes : int, optional
        Transverse modes of the controller's design model when ``model`` carries residual
        modes beyond them.

    Attributes
    ----------
    A, B, C : ndarray
        The augmented model (:func:`augment_disturbance`).
    L : ndarray (nx+1, 3)
        Filter gain (measurement update).
    """

    def __init__(self, model: DesignModel, noise: KalmanNoise, disturbance_noise: float,
                 design_modes: int | None = None):
        if not isinstance(noise, KalmanNoise):
            raise ParameterError(f"noise must be a KalmanNoise, got {type(noise).__name__}")
        if not (isinstance(disturbance_noise, (int, float)) and np.isfinite(disturbance_noise)
                and disturbance_noise > 0):
            raise ParameterError(f"disturbance_noise must be a number > 0 [N m], got {disturbance_noise!r}")
        self.A, self.B, self.C, Qa, Rn = filter_matrices(model, noise, design_modes, disturbance_noise)
        self._A = self.A                  # KalmanEstimator's name for it (the code generator reads it)
        # the prescribed degree of stability (KalmanNoise.error_decay) covers the disturbance too
        A_riccati = decay_model(self.A, error_decay_rate(model, noise), model.dt)
        self.L, self.P = solve_kalman(A_riccati, self.C, Qa, Rn)
        self._b = self.B[:, 0]
        self._IminusLC = np.eye(self.A.shape[0]) - self.L @ self.C
        self.reset()

    @property
    def disturbance(self) -> float:
        """The current estimate of the input disturbance torque ``d_hat`` [N m]."""
        return float(self.x_hat[-1])

    def reset(self, x0=None) -> None:
        """Start again from a state guess (no disturbance), with no measurement yet.

        Parameters
        ----------
        x0 : array_like (nx,) or (nx+1,), optional
            Initial guess of the (deviation) state; default zero.
        """
        n = len(self._b)
        x = np.zeros(n)
        if x0 is not None:
            x0 = np.asarray(x0, dtype=float)
            x[:len(x0)] = x0
        self.x_pred = x
        self.x_hat = x.copy()

    def predict(self, u: float) -> np.ndarray:
        """Prediction of the next augmented state ``A x_hat + B u`` (the estimator is unchanged).

        Parameters
        ----------
        u : float
            Torque commanded over the coming sample [N m].
        """
        return self.A @ self.x_hat + self._b * u

    def update(self, y, u_prev: float | None, offset=None) -> np.ndarray:
        """Take one measurement ``[theta, theta_dot, M_root]`` (deviation coordinates) and
        return the new augmented estimate ``[x_hat, d_hat]``.

        Parameters
        ----------
        y : ndarray (3,)
        u_prev : float or None
            Torque commanded since the previous update [N m] (None right after :meth:`reset`).
        offset : array_like (nx,), optional
            Added to the prediction of the model's states (not the disturbance's), as in
            :meth:`controllers.estimator.KalmanEstimator.update`.
        """
        if u_prev is not None:
            self.x_pred = self.predict(u_prev)
            if offset is not None:
                self.x_pred = self.x_pred.copy()
                self.x_pred[:len(offset)] += offset
        self.x_hat = self._IminusLC @ self.x_pred + self.L @ y
        return self.x_hat


def observer_feedback_matrices(A, B, C, L, K) -> tuple:
    """The linear law ``sensors -> torque`` of an estimate-feedback loop (state: the prediction).

    ``x_hat = (I - L C) x_pred + L y``, ``u = -K x_hat``, ``x_pred+ = A x_hat + B u``, so
    ``Ac = (A - B K)(I - L C)``, ``Bc = (A - B K) L``, ``Cc = -K (I - L C)``, ``Dc = -K L``.

    Parameters
    ----------
    A, B, C, L : ndarray
        Filter model and gain (possibly augmented with the disturbance).
    K : ndarray (1, n)
        Gain on the filter's state (``[K, 1]`` with a disturbance state: ``u = -K x - d``).

    Returns
    -------
    tuple of ndarray
        ``(Ac, Bc, Cc, Dc)``.
    """
    K = np.atleast_2d(K)
    F = A - B @ K
    M = np.eye(A.shape[0]) - L @ C
    return F @ M, F @ L, -K @ M, -K @ L


class ObservedFeedback(AppliedTorque, Controller):
    """A state-feedback controller (LQR, MPC) closed through a Kalman filter on the rig's sensors.

    In the simulator LQR and MPC read the plant's modal state, which no sensor measures. This
    wrapper gives them the estimate of a steady-state Kalman filter fed by
    ``[theta, theta_dot, M_root]`` (on the model with the residual modes the gain was computed
    on), and with ``disturbance_noise`` the filter also estimates an input disturbance torque
    that is subtracted from the command (:class:`OffsetFreeEstimator`: integral action).

    Parameters
    ----------
    inner : Controller
        The state-feedback controller (``measurement == "state"``).
    noise : KalmanNoise
        The filter's noise model (e.g. the scenario's :class:`~controllers.lqg.LQGSettings`).
    disturbance_noise : float, optional
        Random-walk standard deviation of the disturbance per sample [N m]; None: no
        disturbance state (no integral action).
    plan_prediction : bool, optional
        The filter predicts along the reference (see :class:`controllers.lqg.LQGSettings`);
        None: when the reference plans the beam's motion on the nonlinear model
        (``Reference.elastic``, not ``Reference.planned_on_design``) and the inner controller
        tracks it (``elastic_reference``).
    """

    measurement = "sensors"

    @property
    def signals(self):
        """The rig signals the filter reads (None: the closed loop's default three)."""
        return None if self.filter_model.sensors is None else self.filter_model.signals

    def __init__(self, inner: Controller, noise: KalmanNoise, disturbance_noise: float | None = None,
                 plan_prediction: bool | None = None):
        if getattr(inner, "measurement", None) != "state":
            raise ParameterError(f"ObservedFeedback wraps a state-feedback controller (measurement 'state'), "
                                 f"got {getattr(inner, 'name', type(inner).__name__)!r}")
        from .residual import estimator_model
        super().__init__(inner.design, inner.settings, inner.reference)
        self.inner = inner
        self.name = inner.name
        self.n_modes = inner.n_modes
        self.state_modes = inner.state_modes
        m_f = max(inner.state_modes, inner.design.n_modes)
        model = inner.design if inner.design.n_modes >= m_f else estimator_model(inner.design, m_f)
        self.filter_model = model
        self.noise = noise
        self.integral = disturbance_noise is not None
        if self.integral:
            self.estimator = OffsetFreeEstimator(model, noise, disturbance_noise, inner.n_modes)
        else:
            from .estimator import KalmanEstimator
            self.estimator = KalmanEstimator(model, noise, inner.n_modes)
        n_f, m = model.n_x // 2, inner.state_modes
        self._n_f = n_f
        # filter state (deviation from steady spin) -> the inner controller's state
        self._pick = np.r_[0, 1:1 + m, n_f, n_f + 1:n_f + 1 + m]
        elastic = bool(getattr(inner.settings, "elastic_reference", True))
        if plan_prediction is None:
            plan_prediction = plan_worth_predicting(inner.reference, elastic)
        self.predicts_along_plan = bool(plan_prediction)
        self._defect = None
        if self.predicts_along_plan:
            ff = float(getattr(inner, "_ff", 1.0))
            X = model.reference_states(inner.reference, elastic)
            self._defect = plan_offsets(model, X, ff * np.asarray(inner.reference.torque, dtype=float))
        self.reset()

    def initial_state(self) -> np.ndarray:
        """The filter's first estimate: the reference's first state in deviation from the steady
        spin, on the filter model's states (the previous command and the disturbance start at 0).

        Returns
        -------
        ndarray (nz,)
            The length of the estimator's state [rad, m, rad/s, m/s, N m].
        """
        x0 = np.zeros(len(self.estimator._b))
        x_ref, _ = self.inner._reference_at(0)
        n_in = len(x_ref) // 2
        k = min(n_in, self._n_f)
        x0[:k], x0[self._n_f:self._n_f + k] = x_ref[:k], x_ref[n_in:n_in + k]
        x0[self._n_f] -= self.design.spin
        return x0

    def reset(self) -> None:
        """Start the filter at the reference's first state (the inner one's reset too)."""
        self.inner.reset()
        self.estimator.reset(self.initial_state())
        self._tau = None

    @property
    def disturbance(self) -> float:
        """The estimated input disturbance [N m] (0 without integral action)."""
        return self.estimator.disturbance if self.integral else 0.0

    def stats(self) -> dict:
        """The inner controller's statistics plus the final disturbance estimate [N m]."""
        out = dict(self.inner.stats())
        out["disturbance_estimate_nm"] = self.disturbance
        return out

    def feedback_matrices(self) -> tuple:
        """The filter and the inner law (its unconstrained gain) as one system, sensors -> torque."""
        _, _, _, Dk, _, _ = self.inner.feedback_matrices()
        fm = self.filter_model
        K = np.zeros((1, fm.n_x))
        K[0, self._pick] = -np.asarray(Dk)[0]
        K = filter_gain(K, fm, self.noise, self.integral)
        states = filter_state_names(fm, self.noise, self.integral)
        est = self.estimator
        return (*observer_feedback_matrices(est.A, est.B, est.C, est.L, K), states, fm.sensor_labels)

    def __call__(self, t: float, y) -> float:
        """Hub torque [N m] at time ``t`` [s] from the sensors ``y = [theta, theta_dot, M_root]``."""
        spin = self.design.spin
        fm = self.filter_model
        yd = fm.sensor_deviation(y, t)
        k = int(round(t / self.dt))
        D = self._defect
        x_hat = self.estimator.update(yd, self._tau, D[k - 1] if D is not None and 0 < k <= len(D) else None)
        d = float(x_hat[-1]) if self.integral else 0.0
        x = fm.acting_state(x_hat, d)[self._pick]
        t_act = t + fm.delay * self.dt
        x[0] += spin * t_act
        x[1 + self.state_modes] += spin
        if isinstance(self.inner, LQR):        # its law with the disturbance inside one saturation
            xr, tff = self.inner._reference_acting(k)
            tau = saturate(float(self.inner._ff * tff - self.inner.K @ (x - xr) - d), self.tau_max)
        else:                                  # MPC: its plan within the limit, then the disturbance
            # the plan's reference sample where the command acts (the nearest, rounding half up:
            # round() would alternate between two samples at half a sample of delay)
            tau = float(self.inner((k + math.floor(fm.delay + 0.5)) * self.dt, x))
            if self.integral:
                tau = saturate(tau - d, self.tau_max)
        self._tau = tau
        return tau
