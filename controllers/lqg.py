"""LQG: the LQR gain on a steady-state Kalman filter fed by realistic hub and root sensors."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from hubbeam_ctrl.core.errors import ParameterError

from .base import Controller, DesignModel, Reference, Weights, check_nonnegative, check_positive, saturate
from .lqr import dlqr_gain

__all__ = ["LQGSettings", "LQG", "kalman_gain"]


@dataclass(frozen=True)
class LQGSettings:
    """Settings of :class:`LQG`.

    The sensor noise levels are what the filter assumes; they default to the closed-loop
    simulator's :class:`hubbeam_ctrl.plant.sensors.SensorSettings`.
    """

    weights: Weights = field(default_factory=Weights)
    """State and torque weights of the LQR part (see :class:`Weights`)."""
    tau_max: float | None = None
    """Torque limit [N m], 0 < tau_max <= Params.tau_max: the output is clipped to
    +-tau_max. None (default): the motor's limit ``Params.tau_max`` of the design model."""
    feedforward: bool = True
    """Add the reference's rigid-body feedforward torque."""
    elastic_reference: bool = True
    """Track the quasi-static deflection of the reference acceleration (as :class:`LQR`)."""
    angle_noise_rad: float = 1e-4
    """Assumed hub-angle sensor noise, standard deviation [rad], > 0."""
    rate_noise_rad_s: float = 1e-3
    """Assumed hub-rate sensor noise, standard deviation [rad/s], > 0."""
    moment_noise_nm: float = 0.02
    """Assumed root-moment sensor noise, standard deviation [N m], > 0."""
    torque_noise_nm: float = 5.0
    """Process noise: white torque disturbance at the hub, standard deviation per sample
    [N m], > 0 (stands for model error: FOAM's stiffening and Q_theta, the axial modes)."""
    modal_noise: float = 1e-4
    """Process noise on each modal coordinate and rate per sample [m, m/s], >= 0."""

    def __post_init__(self):
        if not isinstance(self.weights, Weights):
            raise ParameterError(f"weights must be a Weights, got {type(self.weights).__name__}")
        if self.tau_max is not None:
            check_positive("tau_max", self.tau_max, "N m")
        check_positive("angle_noise_rad", self.angle_noise_rad, "rad")
        check_positive("rate_noise_rad_s", self.rate_noise_rad_s, "rad/s")
        check_positive("moment_noise_nm", self.moment_noise_nm, "N m")
        check_positive("torque_noise_nm", self.torque_noise_nm, "N m")
        check_nonnegative("modal_noise", self.modal_noise, "m")


def kalman_gain(design: DesignModel, settings: LQGSettings) -> np.ndarray:
    """Steady-state Kalman filter gain (measurement update) for the three sensors.

    Parameters
    ----------
    design : DesignModel
    settings : LQGSettings

    Returns
    -------
    ndarray (nx, 3)
        ``x_hat = x_pred + L (y - C x_pred)``.
    """
    A, B, C = design.Ad, design.Bd, design.C_sensors
    nx = design.n_x
    Qn = settings.torque_noise_nm ** 2 * (B @ B.T)
    idx = np.r_[1:nx // 2, nx // 2 + 1:nx]
    Qn[idx, idx] += settings.modal_noise ** 2
    Rn = np.diag([settings.angle_noise_rad ** 2, settings.rate_noise_rad_s ** 2,
                  settings.moment_noise_nm ** 2])
    try:
        P = scipy.linalg.solve_discrete_are(A.T, C.T, Qn, Rn)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise ParameterError(f"the Kalman filter's Riccati equation has no solution ({exc}); "
                             "check the noise levels") from None
    return P @ C.T @ np.linalg.inv(C @ P @ C.T + Rn)


class LQG(Controller):
    """Output feedback: Kalman filter on ``[theta, theta_dot, M_root]`` plus the LQR gain.

    The filter works in deviations from the steady rotation at the design spin ``Omega``:
    ``x - [Omega t, 0, Omega, 0]``. Each call makes the measurement update, computes
    ``tau = sat(tau_ff - K (x_hat - x_ref))`` and predicts the next state with the torque
    actually applied.

    Parameters
    ----------
    design : DesignModel
    settings : LQGSettings, optional
    reference : Reference, optional

    Attributes
    ----------
    K : ndarray (nx,)
        LQR gain.
    L : ndarray (nx, 3)
        Kalman gain.
    """

    name = "lqg"
    measurement = "sensors"

    def __init__(self, design: DesignModel, settings: LQGSettings | None = None,
                 reference: Reference | None = None):
        settings = settings or LQGSettings()
        super().__init__(design, settings, reference)
        self.K, self.P = dlqr_gain(design, settings.weights)
        self.L = kalman_gain(design, settings)
        C = design.C_sensors
        self._IminusLC = np.eye(design.n_x) - self.L @ C
        self._ff = 1.0 if settings.feedforward else 0.0
        self._n = design.n_x // 2
        self._prepare_reference(settings.elastic_reference)
        self.reset()

    def reset(self) -> None:
        x, _ = self._reference_at(0)
        x = x.copy()
        x[self._n] -= self.design.spin
        self.x_pred = x
        self.x_hat = x

    def feedback_matrices(self) -> tuple:
        """The filter and gain as one system, sensors -> torque (state: the prediction).

        With ``x_hat = (I - L C) x_pred + L y``, ``u = -K x_hat`` and
        ``x_pred+ = Ad x_hat + Bd u``: ``Ac = (Ad - Bd K)(I - L C)``, ``Bc = (Ad - Bd K) L``,
        ``Cc = -K (I - L C)``, ``Dc = -K L``.
        """
        d = self.design
        F = d.Ad - d.Bd @ self.K[None, :]
        M = self._IminusLC
        states = [f"{name}_est" for name in d.state_names]
        return (F @ M, F @ self.L, -self.K[None, :] @ M, -self.K[None, :] @ self.L, states,
                ["theta", "theta_dot", "root_moment"])

    def __call__(self, t: float, y) -> float:
        spin = self.design.spin
        xr, tff = self._reference_at(int(round(t / self.dt)))
        yd = np.array([y[0] - spin * t, y[1] - spin, y[2]])
        x_hat = self._IminusLC @ self.x_pred + self.L @ yd
        K = self.K
        # x_hat is a deviation from the steady rotation; x_ref is absolute
        u = K @ (x_hat - xr) + K[0] * spin * t + K[self._n] * spin
        tau = saturate(float(self._ff * tff - u), self.tau_max)
        self.x_hat = x_hat
        self.x_pred = self.design.Ad @ x_hat + self.design.Bd[:, 0] * tau
        return tau
