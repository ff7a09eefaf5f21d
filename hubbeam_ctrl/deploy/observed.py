"""The LQR as it can run on a rig: its gain on a Kalman filter that reads the hub sensors.

The full-state :class:`controllers.LQR` reads the beam's modal coordinates, which no sensor
measures. :class:`ObservedLQR` is the LQR's own gain (on the LQR's own model, with its
residual modes when ``residual_control``) acting on a steady-state
:class:`controllers.KalmanEstimator` of that model fed by ``[theta, theta_dot, M_root]``:
the controller that :func:`hubbeam_ctrl.deploy.to_c` exports for an LQR, and the Python
reference its C code is checked against.
"""

from __future__ import annotations

import numpy as np

from controllers import LQR, MPC, Controller, KalmanEstimator, KalmanNoise, saturate
from hubbeam_ctrl.core.errors import ParameterError

__all__ = ["ObservedLQR", "ObservedMPC"]


class ObservedLQR(Controller):
    """``tau = sat(tau_ff - K (x_hat - x_ref))`` with ``x_hat`` a Kalman estimate from the sensors.

    Mirrors :class:`controllers.LQG`'s sample operation by operation (deviation coordinates
    from the steady rotation at the design spin, measurement update before the gain), with
    the LQR's gain ``K`` and reference table.

    Parameters
    ----------
    lqr : controllers.LQR
        The full-state design (its gain, model, reference, torque limit, feedforward).
    noise : controllers.KalmanNoise, optional
        The filter's noise model (default :class:`~controllers.KalmanNoise`: the simulator's
        sensor noise).

    Attributes
    ----------
    K : ndarray (nx,)
        The LQR's gain [N m per state unit].
    estimator : controllers.KalmanEstimator
        The filter on the LQR's model (gain ``estimator.L``, (nx, 3)).
    """

    name = "lqr"
    measurement = "sensors"

    def __init__(self, lqr: LQR, noise: KalmanNoise | None = None):
        if not isinstance(lqr, LQR):
            raise ParameterError(f"lqr must be an LQR, got {type(lqr).__name__}")
        noise = KalmanNoise() if noise is None else noise
        if not isinstance(noise, KalmanNoise):
            raise ParameterError(f"noise must be a KalmanNoise, got {type(noise).__name__}")
        super().__init__(lqr.design, lqr.settings, lqr.reference)
        self.lqr = lqr
        self.n_modes = lqr.n_modes
        self.state_modes = lqr.state_modes
        self.tau_max = lqr.tau_max
        self.K = lqr.K
        self.noise = noise
        self.estimator = KalmanEstimator(lqr.design, noise, min(lqr.n_modes, lqr.design.n_modes))
        self._ff = lqr._ff
        self._n = lqr.design.n_x // 2
        self.reset()

    def _reference_at(self, k: int):
        return self.lqr._reference_at(k)

    @property
    def L(self) -> np.ndarray:
        """Kalman filter gain (nx, 3)."""
        return self.estimator.L

    def reset(self) -> None:
        """Start the filter from the reference's first state; forget the last torque."""
        x = np.array(self._reference_at(0)[0], dtype=float)
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
        u = K @ (x_hat - xr) + K[0] * spin * t + K[self._n] * spin
        self._tau = saturate(float(self._ff * tff - u), self.tau_max)
        return self._tau


class ObservedMPC(Controller):
    """The MPC's QP solved on a Kalman estimate from the hub sensors (the MPC as exported).

    :class:`controllers.MPC` reads the full state (modal coordinates); this wraps it with a
    steady-state :class:`controllers.KalmanEstimator` of its model, exactly as
    :class:`ObservedLQR` does for the LQR: each call updates the estimate with the sensors
    and hands the MPC the estimated absolute state ``x_hat + [spin t, 0, spin, 0]``.

    Parameters
    ----------
    mpc : controllers.MPC
    noise : controllers.KalmanNoise, optional
        The filter's noise model (default: the simulator's sensors).
    """

    name = "mpc"
    measurement = "sensors"

    def __init__(self, mpc: MPC, noise: KalmanNoise | None = None):
        if not isinstance(mpc, MPC):
            raise ParameterError(f"mpc must be an MPC, got {type(mpc).__name__}")
        noise = KalmanNoise() if noise is None else noise
        if not isinstance(noise, KalmanNoise):
            raise ParameterError(f"noise must be a KalmanNoise, got {type(noise).__name__}")
        super().__init__(mpc.design, mpc.settings, mpc.reference)
        self.mpc = mpc
        self.n_modes = mpc.n_modes
        self.state_modes = mpc.state_modes
        self.tau_max = mpc.tau_max
        self.noise = noise
        self.estimator = KalmanEstimator(mpc.design, noise, min(mpc.n_modes, mpc.design.n_modes))
        self._n = mpc.design.n_x // 2
        self.reset()

    def reset(self) -> None:
        """Reset the MPC and start the filter from the reference's first state."""
        self.mpc.reset()
        x = np.array(self.mpc._reference_at(0)[0], dtype=float)
        x[self._n] -= self.design.spin
        self.estimator.reset(x)
        self._tau = None

    def stats(self) -> dict:
        """The MPC's counters (QP solves and fallbacks)."""
        return self.mpc.stats()

    def __call__(self, t: float, y) -> float:
        """Hub torque [N m] at time ``t`` [s] from the sensors ``y = [theta, theta_dot, M_root]``."""
        spin = self.design.spin
        yd = np.array([y[0] - spin * t, y[1] - spin, y[2]])
        x = self.estimator.update(yd, self._tau).copy()
        x[0] += spin * t
        x[self._n] += spin
        self._tau = self.mpc(t, x)
        return self._tau
