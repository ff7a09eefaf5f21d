"""The LQR and the MPC as they run on sensors: thin names for :class:`controllers.integral.ObservedFeedback`.

The full-state :class:`controllers.LQR` and :class:`controllers.MPC` read the beam's modal
coordinates, which no sensor measures. There is one observer-based feedback,
:class:`controllers.integral.ObservedFeedback` (the rig path of ``compare --rig``): a
steady-state Kalman filter of the design model's sensors (the beam alone's
``[theta, theta_dot, M_root]``, or a rig's own set when the design reads it,
:meth:`controllers.DesignModel.on_rig`) feeding the state-feedback law. :class:`ObservedLQR`
and :class:`ObservedMPC` are that class without integral action, with the simulator's sensor
noise as the filter's default: what :func:`hubbeam_ctrl.deploy.to_c` exports for a bare LQR or
MPC, and the Python reference its C code is checked against.
"""

from __future__ import annotations

import numpy as np

from controllers import LQR, MPC, KalmanNoise
from controllers.integral import ObservedFeedback
from hubbeam_ctrl.core.errors import ParameterError

__all__ = ["ObservedLQR", "ObservedMPC"]


def _checked(value, kind: type, rule: str):
    """``value`` if it is a ``kind``, else a one-line :class:`ParameterError`: ``rule, got <type>``."""
    if not isinstance(value, kind):
        raise ParameterError(f"{rule}, got {type(value).__name__}")
    return value


class ObservedLQR(ObservedFeedback):
    """``tau = sat(tau_ff - K (x_hat - x_ref))`` with ``x_hat`` a Kalman estimate from the sensors.

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
        The filter on the LQR's model (gain ``estimator.L``, (nx, ny)).
    """

    def __init__(self, lqr: LQR, noise: KalmanNoise | None = None):
        self.noise = _checked(KalmanNoise() if noise is None else noise, KalmanNoise,
                              "noise must be a KalmanNoise")
        super().__init__(_checked(lqr, LQR, "lqr must be an LQR"), self.noise)
        self.lqr, self.K = lqr, lqr.K

    @property
    def L(self) -> np.ndarray:
        """Kalman filter gain (nx, ny)."""
        return self.estimator.L


class ObservedMPC(ObservedFeedback):
    """The MPC's QP solved on a Kalman estimate from the sensors (the MPC as exported).

    Parameters
    ----------
    mpc : controllers.MPC
    noise : controllers.KalmanNoise, optional
        The filter's noise model (default: the simulator's sensors).
    """

    def __init__(self, mpc: MPC, noise: KalmanNoise | None = None):
        self.noise = _checked(KalmanNoise() if noise is None else noise, KalmanNoise,
                              "noise must be a KalmanNoise")
        super().__init__(_checked(mpc, MPC, "mpc must be an MPC"), self.noise)
        self.mpc = mpc
