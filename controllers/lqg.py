"""LQG: the LQR gain on a steady-state Kalman filter fed by realistic hub and root sensors.

By default (``robust=True``) the filter's model carries the beam's residual modes (see
:mod:`controllers.residual` and docs/controllers.md): a filter on the design modes alone
destabilises the modes it leaves out through the root-moment sensor.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.core.settings import setting

from .base import Controller, DesignModel, LQSettings, Reference, saturate
from .estimator import KalmanEstimator, KalmanNoise, plan_offsets, plan_worth_predicting
from .integral import OffsetFreeEstimator, observer_feedback_matrices
from .lqr import dlqr_gain
from .residual import embedding, estimator_model, residual_design

__all__ = ["LQGSettings", "LQG"]


@dataclass(frozen=True)
class LQGSettings(KalmanNoise, LQSettings):
    """Settings of :class:`LQG`: those of LQR, the Kalman filter's noise model and its model's modes.

    The sensor noise levels are what the filter assumes; they default to the closed-loop
    simulator's :class:`hubbeam_ctrl.plant.sensors.SensorSettings`.
    """

    robust: bool = setting(True, doc="Model the residual modes in the filter (controllers.residual); "
                                     "False: the filter on the design model alone, which the modes it "
                                     "leaves out destabilise.")
    integral: bool = setting(False, doc="Integral action: the filter also estimates a constant input "
                                        "disturbance torque, which the command cancels (offset-free control, "
                                        "controllers.integral); the default on rigs with friction.")
    disturbance_noise_nm: float | None = setting(None, unit="N m", lo=0.0, lo_open=True, kind=float,
                                                 doc="Random-walk standard deviation per sample of the "
                                                     "disturbance the integral action estimates; None: 1 % "
                                                     "of the torque limit.")
    plan_prediction: bool | None = setting(None, kind=bool,
                                           doc="The filter predicts along the reference: x_pred = x_ref[k+1] "
                                               "+ A (x_hat - x_ref[k]) + B (u - u_ff[k]), so the model's "
                                               "error along a planned slew does not enter the estimate; "
                                               "None: when the reference plans the beam's motion on "
                                               "the nonlinear model (Reference.elastic, "
                                               "reference='optimal') and elastic_reference is on; "
                                               "not along a plan of the design model itself "
                                               "(Reference.planned_on_design), which the filter's "
                                               "own prediction follows.")


def filter_model(design: DesignModel, settings: LQGSettings) -> DesignModel:
    """The model the Kalman filter of an LQG runs on: with residual modes if ``settings.robust``.

    Parameters
    ----------
    design : DesignModel
        The design model of the state feedback.
    settings : LQGSettings

    Returns
    -------
    DesignModel
        :func:`controllers.residual.estimator_model` of ``design``, or ``design`` itself.
    """
    return estimator_model(design, settings.residual_modes) if settings.robust else design


class LQG(Controller):
    """Output feedback: a :class:`KalmanEstimator` on ``[theta, theta_dot, M_root]`` and the LQR gain.

    The filter works in deviations from the steady rotation at the design spin ``Omega``:
    ``x - [Omega t, 0, Omega, 0]``. Each call updates the estimate with the measurement
    (after predicting with the torque applied since the last call) and returns
    ``tau = sat(tau_ff - K (x_hat - x_ref))``. Along a planned reference (an optimal slew,
    ``settings.plan_prediction``) the prediction follows the plan,
    ``x_ref[k+1] + A (x_hat - x_ref[k]) + B (u - u_ff[k])``: the plan comes from the
    nonlinear model, so the linear model's error along the slew does not enter the estimate.
    With ``settings.robust`` the filter's model (:attr:`filter_model`) has the residual modes of
    :func:`controllers.residual.estimator_modes` and, with ``settings.residual_control``, the
    gain acting on the estimate is the LQR gain of that model (:attr:`K` stays the design
    model's, for reports).

    Parameters
    ----------
    design : DesignModel
        Sampled SFOAM at the design spin rate.
    settings : LQGSettings, optional
        LQR settings plus the filter's noise model.
    reference : Reference, optional
        Hub trajectory and feedforward torque (default: rest at theta = 0).

    Attributes
    ----------
    K : ndarray (nx,)
        LQR gain on the design model.
    P : ndarray (nx, nx)
        LQR Riccati solution.
    filter_model : DesignModel
        The filter's model (``design`` itself unless residual modes are added).
    estimator : KalmanEstimator
        The state estimator on :attr:`filter_model` (gain ``estimator.L``, (nx_est, 3)).
    """

    measurement = "sensors"

    def __init__(self, design: DesignModel, settings: LQGSettings | None = None,
                 reference: Reference | None = None):
        settings = settings or LQGSettings()
        super().__init__(design, settings, reference)
        self.K, self.P = dlqr_gain(design, settings.weights)
        self.filter_model = filter_model(design, settings)
        if settings.integral:
            noise_d = settings.disturbance_noise_nm or 0.01 * self.tau_max
            self.estimator = OffsetFreeEstimator(self.filter_model, settings, noise_d, design.n_modes)
        else:
            self.estimator = KalmanEstimator(self.filter_model, settings, design.n_modes)
        self._E = embedding(design.n_modes, self.filter_model.n_modes)
        self._ff = 1.0 if settings.feedforward else 0.0
        self._n = self.filter_model.n_x // 2
        self._prepare_reference(settings.elastic_reference)
        self._Ke = self.K @ self._E.T
        self._xref_filter = None
        if settings.residual_control and self.filter_model is not design:
            model, weights = residual_design(design, settings.weights, self.filter_model.n_modes)
            self._Ke = dlqr_gain(model, weights)[0]
            # the residual modes' own quasi-static deflection along the reference
            self._xref_filter = self.filter_model.reference_states(self.reference, settings.elastic_reference)
        self._defect = self._plan_defect() if self.predicts_along_plan else None
        self.reset()

    @property
    def predicts_along_plan(self) -> bool:
        """Whether the filter predicts along the reference (``settings.plan_prediction``)."""
        if self.settings.plan_prediction is not None:
            return bool(self.settings.plan_prediction)
        return plan_worth_predicting(self.reference, self.settings.elastic_reference)

    def _plan_defect(self) -> np.ndarray:
        """:func:`~controllers.estimator.plan_offsets` of the reference table on the filter's model."""
        table = self._xref_filter
        X = np.array([table[k] if table is not None and k < len(table) else self._E @ self._xref[k]
                      for k in range(len(self._tff))])
        return plan_offsets(self.filter_model, X, self._ff * self._tff)

    @property
    def L(self) -> np.ndarray:
        """Kalman filter gain (nx_est, 3) of the estimator."""
        return self.estimator.L

    @property
    def x_hat(self) -> np.ndarray:
        """Current state estimate (deviation from the steady rotation, filter model's states)."""
        return self.estimator.x_hat

    @property
    def x_pred(self) -> np.ndarray:
        """Prediction of the state at the next sample (the initial guess after :meth:`reset`; without
        the plan's offset of ``plan_prediction``)."""
        return self.estimator.x_pred if self._tau is None else self.estimator.predict(self._tau)

    def reset(self) -> None:
        """Start the estimator from the reference's first state; forget the last torque."""
        x, _ = self._reference_at(0)
        x = self._E @ x
        x[self._n] -= self.design.spin
        self.estimator.reset(x)
        self._tau = None

    def feedback_matrices(self) -> tuple:
        """The filter and gain as one system, sensors -> torque (state: the prediction).

        On the filter's model ``(A, B, C)`` (:attr:`filter_model`), with ``K`` the gain on its
        states: ``x_hat = (I - L C) x_pred + L y``, ``u = -K x_hat``, ``x_pred+ = A x_hat + B u``,
        so ``Ac = (A - B K)(I - L C)``, ``Bc = (A - B K) L``, ``Cc = -K (I - L C)``,
        ``Dc = -K L``.
        """
        fm = self.filter_model
        K = self._Ke[None, :]
        states = [f"{name}_est" for name in fm.state_names]
        A, B, C = fm.Ad, fm.Bd, fm.C_sensors
        if self.settings.integral:
            K = np.hstack([K, [[1.0]]])
            A, B, C = self.estimator.A, self.estimator.B, self.estimator.C
            states.append("d_est")
        return (*observer_feedback_matrices(A, B, C, self.L, K), states, ["theta", "theta_dot", "root_moment"])

    def __call__(self, t: float, y) -> float:
        """Hub torque [N m] at time ``t`` [s] from the sensors ``y = [theta, theta_dot, M_root]``."""
        spin = self.design.spin
        k = int(round(t / self.dt))
        xr, tff = self._reference_at(k)
        yd = np.array([y[0] - spin * t, y[1] - spin, y[2]])
        D = self._defect
        offset = D[k - 1] if D is not None and 0 < k <= len(D) else None
        x_hat = self.estimator.update(yd, self._tau, offset)
        K = self._Ke
        table = self._xref_filter
        xr = table[k] if table is not None and k < len(table) else self._E @ xr
        # x_hat is a deviation from the steady rotation; x_ref is absolute
        u = K @ (x_hat[:len(K)] - xr) + K[0] * spin * t + K[self._n] * spin
        if self.settings.integral:
            u += x_hat[-1]                      # cancel the estimated disturbance torque
        self._tau = saturate(float(self._ff * tff - u), self.tau_max)
        return self._tau
