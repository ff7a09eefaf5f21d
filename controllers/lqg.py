"""LQG: the LQR gain on a steady-state Kalman filter fed by realistic hub and root sensors."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import Controller, DesignModel, LQSettings, Reference, saturate
from .estimator import KalmanEstimator, KalmanNoise
from .lqr import dlqr_gain

__all__ = ["LQGSettings", "LQG"]


@dataclass(frozen=True)
class LQGSettings(KalmanNoise, LQSettings):
    """Settings of :class:`LQG`: those of LQR plus the Kalman filter's noise model.

    The sensor noise levels are what the filter assumes; they default to the closed-loop
    simulator's :class:`hubbeam_ctrl.plant.sensors.SensorSettings`.
    """


class LQG(Controller):
    """Output feedback: a :class:`KalmanEstimator` on ``[theta, theta_dot, M_root]`` and the LQR gain.

    The filter works in deviations from the steady rotation at the design spin ``Omega``:
    ``x - [Omega t, 0, Omega, 0]``. Each call updates the estimate with the measurement
    (after predicting with the torque applied since the last call) and returns
    ``tau = sat(tau_ff - K (x_hat - x_ref))``.

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
        LQR gain.
    P : ndarray (nx, nx)
        LQR Riccati solution.
    estimator : KalmanEstimator
        The state estimator (gain ``estimator.L``).
    """

    measurement = "sensors"

    def __init__(self, design: DesignModel, settings: LQGSettings | None = None,
                 reference: Reference | None = None):
        settings = settings or LQGSettings()
        super().__init__(design, settings, reference)
        self.K, self.P = dlqr_gain(design, settings.weights)
        self.estimator = KalmanEstimator(design, settings)
        self._ff = 1.0 if settings.feedforward else 0.0
        self._n = design.n_x // 2
        self._prepare_reference(settings.elastic_reference)
        self.reset()

    @property
    def L(self) -> np.ndarray:
        """Kalman filter gain (nx, 3) of the estimator."""
        return self.estimator.L

    @property
    def x_hat(self) -> np.ndarray:
        """Current state estimate (deviation from the steady rotation)."""
        return self.estimator.x_hat

    @property
    def x_pred(self) -> np.ndarray:
        """Prediction of the state at the next sample (the initial guess after :meth:`reset`)."""
        return self.estimator.x_pred if self._tau is None else self.estimator.predict(self._tau)

    def reset(self) -> None:
        """Start the estimator from the reference's first state; forget the last torque."""
        x, _ = self._reference_at(0)
        x = x.copy()
        x[self._n] -= self.design.spin
        self.estimator.reset(x)
        self._tau = None

    def __call__(self, t: float, y) -> float:
        """Hub torque [N m] at time ``t`` [s] from the sensors ``y = [theta, theta_dot, M_root]``."""
        spin = self.design.spin
        xr, tff = self._reference_at(int(round(t / self.dt)))
        yd = np.array([y[0] - spin * t, y[1] - spin, y[2]])
        x_hat = self.estimator.update(yd, self._tau)
        K = self.K
        # x_hat is a deviation from the steady rotation; x_ref is absolute
        u = K @ (x_hat - xr) + K[0] * spin * t + K[self._n] * spin
        self._tau = saturate(float(self._ff * tff - u), self.settings.tau_max)
        return self._tau
