"""Discrete LQR on the sampled SFOAM model, full state from the plant's modal coordinates."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from hubbeam_ctrl.core.errors import ParameterError

from .base import Controller, DesignModel, Reference, Weights, check_positive, saturate

__all__ = ["LQRSettings", "LQR", "dlqr_gain"]


def dlqr_gain(design: DesignModel, weights: Weights):
    """Discrete LQR gain on the design model.

    Minimises ``sum e' Q e + R u^2`` for ``e[k+1] = Ad e[k] + Bd u[k]``.

    Parameters
    ----------
    design : DesignModel
    weights : Weights

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
    """
    if not isinstance(weights, Weights):
        raise ParameterError(f"weights must be a Weights, got {type(weights).__name__}")
    Q, R = weights.matrices(design)
    A, B = design.Ad, design.Bd
    try:
        P = scipy.linalg.solve_discrete_are(A, B, Q, R)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise ParameterError(f"weights: the LQR Riccati equation has no stabilising solution "
                             f"({exc}); give weight to the hub angle and the modes") from None
    K = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A).ravel()
    rho = max(abs(np.linalg.eigvals(A - B @ K[None, :])))
    if not np.all(np.isfinite(K)) or rho >= 1.0 - 1e-9:
        raise ParameterError(f"weights: the LQR design is not stabilising (spectral radius {rho:.6f}); "
                             "give weight to the hub angle and the modes")
    return K, P


@dataclass(frozen=True)
class LQRSettings:
    """Settings of :class:`LQR`."""

    weights: Weights = field(default_factory=Weights)
    """State and torque weights (see :class:`Weights`)."""
    tau_max: float | None = None
    """Torque limit [N m], 0 < tau_max <= Params.tau_max: the output is clipped to
    +-tau_max. None (default): the motor's limit ``Params.tau_max`` of the design model."""
    feedforward: bool = True
    """Add the reference's rigid-body feedforward torque."""
    elastic_reference: bool = True
    """Track the quasi-static deflection the reference acceleration causes instead of
    a straight beam (see :meth:`DesignModel.reference_states`)."""

    def __post_init__(self):
        if not isinstance(self.weights, Weights):
            raise ParameterError(f"weights must be a Weights, got {type(self.weights).__name__}")
        if self.tau_max is not None:
            check_positive("tau_max", self.tau_max, "N m")


class LQR(Controller):
    """``tau = sat(tau_ff - K (x - x_ref))`` with ``x`` the plant's SFOAM-ordered state.

    Parameters
    ----------
    design : DesignModel
        Sampled SFOAM at the design spin rate.
    settings : LQRSettings, optional
    reference : Reference, optional

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

    name = "lqr"
    measurement = "state"

    def __init__(self, design: DesignModel, settings: LQRSettings | None = None,
                 reference: Reference | None = None):
        settings = settings or LQRSettings()
        super().__init__(design, settings, reference)
        self.K, self.P = dlqr_gain(design, settings.weights)
        self._ff = 1.0 if settings.feedforward else 0.0
        self._prepare_reference(settings.elastic_reference)

    def feedback_matrices(self) -> tuple:
        """Static state feedback ``u = -K e``: no states, inputs the design model's states."""
        n = self.design.n_x
        return (np.zeros((0, 0)), np.zeros((0, n)), np.zeros((1, 0)), -self.K[None, :], [],
                list(self.design.state_names))

    def __call__(self, t: float, y) -> float:
        xr, tff = self._reference_at(int(round(t / self.dt)))
        u = self.K @ (y - xr)
        return saturate(float(self._ff * tff - u), self.tau_max)
