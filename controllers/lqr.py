"""Discrete LQR on the sampled SFOAM model, full state from the plant's modal coordinates."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError

from .base import Controller, DesignModel, LQSettings, Reference, Weights, saturate
from .residual import residual_design
from .riccati import dlqr

__all__ = ["LQRSettings", "LQR", "dlqr_gain"]


def dlqr_gain(design: DesignModel, weights: Weights):
    """Discrete LQR gain on the design model (:func:`control.dlqr`).

    Minimises ``sum e' Q e + R u^2`` for ``e[k+1] = Ad e[k] + Bd u[k]``.

    Parameters
    ----------
    design : DesignModel
        Sampled design model (``Ad``, ``Bd``).
    weights : Weights
        Gives ``Q`` and ``R`` (:meth:`Weights.matrices`).

    Returns
    -------
    K : ndarray (nx,)
        Gain [N m per state unit]: ``u = -K e``.
    P : ndarray (nx, nx)
        Solution of the discrete algebraic Riccati equation (the cost-to-go).

    Raises
    ------
    ParameterError
        If the weights are not positive (semi)definite or the Riccati equation has no
        stabilising solution (e.g. an undamped mode with zero weight).

    Examples
    --------
    >>> from controllers import DesignModel, Weights
    >>> K, P = dlqr_gain(DesignModel.build(n_modes=2), Weights())
    >>> K.shape, P.shape
    ((6,), (6, 6))
    """
    if not isinstance(weights, Weights):
        raise ParameterError(f"weights must be a Weights, got {type(weights).__name__}")
    Q, R = weights.matrices(design)
    try:
        K, P, poles = dlqr(design.Ad, design.Bd, Q, R)       # control.dlqr's numbers, without its import
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise ParameterError(f"weights: the LQR Riccati equation has no stabilising solution "
                             f"({exc}); give weight to the hub angle and the modes") from None
    K = np.asarray(K).ravel()
    rho = np.max(np.abs(poles))
    if not np.all(np.isfinite(K)) or rho >= 1.0 - 1e-9:
        raise ParameterError(f"weights: the LQR design is not stabilising (spectral radius {rho:.6f}); "
                             "give weight to the hub angle and the modes")
    return K, np.asarray(P)


@dataclass(frozen=True)
class LQRSettings(LQSettings):
    """Settings of :class:`LQR` (all shared with LQG and MPC, see :class:`LQSettings`)."""


class LQR(Controller):
    """``tau = sat(tau_ff - K (x - x_ref))`` with ``x`` the plant's SFOAM-ordered state.

    Parameters
    ----------
    design : DesignModel
        Sampled SFOAM at the design spin rate.
    settings : LQRSettings, optional
        Weights, torque limit, feedforward and elastic reference.
    reference : Reference, optional
        Hub trajectory and feedforward torque (default: rest at theta = 0).

    Attributes
    ----------
    K : ndarray (nx,)
        State-feedback gain.
    P : ndarray (nx, nx)
        Riccati solution.

    Examples
    --------
    >>> from controllers import DesignModel, LQR
    >>> ctrl = LQR(DesignModel.build(n_modes=2))
    >>> ctrl.K.shape
    (6,)
    """

    measurement = "state"

    def __init__(self, design: DesignModel, settings: LQRSettings | None = None,
                 reference: Reference | None = None):
        settings = settings or LQRSettings()
        model, weights = residual_design(design, settings.weights, settings.residual_modes) \
            if settings.residual_control \
            else (design, settings.weights)
        super().__init__(model, settings, reference)
        self.n_modes = design.n_modes           # the design's; the gain reads model.n_modes
        self.K, self.P = dlqr_gain(model, weights)
        self._ff = 1.0 if settings.feedforward else 0.0
        self._prepare_reference(settings.elastic_reference)

    def feedback_matrices(self) -> tuple:
        """Static state feedback ``u = -K e``: no states, inputs the design model's states."""
        n = self.design.n_x
        return (np.zeros((0, 0)), np.zeros((0, n)), np.zeros((1, 0)), -self.K[None, :], [],
                list(self.design.state_names))

    def __call__(self, t: float, y) -> float:
        """Hub torque [N m] at time ``t`` [s] from the SFOAM-ordered state ``y``."""
        xr, tff = self._reference_at(int(round(t / self.dt)))
        u = self.K @ (y - xr)
        return saturate(float(self._ff * tff - u), self.tau_max)
