"""The payload as an estimated parameter of the beam's own nonlinear model (issue 40, item 2).

The hub angle is a cyclic coordinate of every model: the Lagrangian does not depend on it, so
the hub's generalised momentum ``H = dL/dtheta_dot`` (the system's angular momentum about the
hub axis) changes only by the torque, ``dH/dt = tau``, whatever the beam's deflection, its
stiffening and its damping (damping acts on the modal coordinates only). Under a zero-order
hold that balance is exact over each sample:

``H(x_k; m_t) - H(x_0; m_t) = dt * sum_{j<k} u_j``,

and ``H`` is affine in the payload (the tip mass's moments; the quasi-static axial modes, the
only part of the parameters that is not, enter ``H`` at second order in the deflection).
:class:`PayloadMomentum` fits ``m_t`` to that balance by recursive least squares over every
sample since the start, with the design's payload as prior: the balance holds on the measured
state whatever the prediction model leaves out (the modes beyond it enter ``H`` only through
their small moments ``V2``), unlike a one-step prediction error of the truncated model, whose
modal rows are dominated by the modes it leaves out (measured: a one-step EKF on a 2-mode model
wandered from 0.1 to 0.008 kg on a 0.3 kg plant before converging after 1 s).

:class:`PayloadTable` holds the model's exact parameter vector on a grid over the range and
interpolates it, so that the NMPC predicts with the estimate's model with no model built while
the slew runs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.params import Params

__all__ = ["PayloadTable", "payload_table", "PayloadMomentum", "TABLE_POINTS"]

#: Grid points of :class:`PayloadTable` over the range (the parameter vector between them is
#: linearly interpolated; the quasi-static axial modes are the only part not affine in m_t).
TABLE_POINTS = 33


@dataclass(frozen=True)
class PayloadTable:
    """The prediction model's parameter vector on a grid of payloads.

    Attributes
    ----------
    masses : ndarray (n,)
        Payloads [kg], increasing.
    vectors : ndarray (n, n_p)
        The model's parameter vector (:attr:`hubbeam_ctrl.plant.models.HubBeamModel.p`) at each.
    """

    masses: np.ndarray
    vectors: np.ndarray

    def at(self, mass: float) -> tuple:
        """``(p, dp/dm)`` at ``mass`` (clipped to the grid): interpolated vector and its slope.

        Parameters
        ----------
        mass : float
            Payload [kg].

        Returns
        -------
        tuple of ndarray
            The parameter vector and its derivative per kg.
        """
        m = self.masses
        x = float(np.clip(mass, m[0], m[-1]))
        k = int(np.clip(np.searchsorted(m, x, side="right") - 1, 0, len(m) - 2))
        w = (x - m[k]) / (m[k + 1] - m[k])
        slope = (self.vectors[k + 1] - self.vectors[k]) / (m[k + 1] - m[k])
        return (1.0 - w) * self.vectors[k] + w * self.vectors[k + 1], slope


def payload_table(params: Params, n_modes: int, lo: float, hi: float, points: int = TABLE_POINTS) -> PayloadTable:
    """The FOAM prediction model's parameter vector over payloads ``lo..hi``.

    Parameters
    ----------
    params : Params
        The beam (its ``m_t`` is replaced by each grid point).
    n_modes : int
        Bending modes of the prediction model.
    lo, hi : float
        The payload range [kg], ``0 <= lo < hi``.
    points : int
        Grid points (at least 2).

    Returns
    -------
    PayloadTable
    """
    from hubbeam_ctrl.plant.models import build_model
    if not (0.0 <= lo < hi) or not np.isfinite(hi):
        raise ParameterError(f"payload range must have 0 <= min < max (finite) [kg], got {lo:g}..{hi:g}")
    masses = np.linspace(lo, hi, max(2, int(points)))
    vectors = np.array([build_model("foam", params.replace(m_t=float(m), n_transverse=n_modes),
                                    axial="quasi-static").p for m in masses])
    return PayloadTable(masses, vectors)


class PayloadMomentum:
    """The payload from the hub's angular-momentum balance (see the module docstring).

    Parameters
    ----------
    momentum : casadi.Function
        ``(q, v, p) -> H``: the prediction model's hub momentum [N m s].
    table : PayloadTable
        The model's parameter vector over the payload range (its ends span ``H``'s dependence).
    mass : float
        Prior payload [kg] (the design's).
    dt : float
        Sample time [s] (the command is held over each sample).
    momentum_noise : float
        Standard deviation of the balance's error per sample [N m s] (what the measured state,
        the modes beyond the model and the torque's lag make of ``H``).

    Attributes
    ----------
    mass, variance : float
        The estimate [kg] and its variance [kg^2].
    lag_s : float
        The torque's estimated lag behind the held command [s] (fitted beside the payload: an
        amplifier's, or the plant integrator's).
    history : list of float
        The estimate after each update [kg].
    """

    def __init__(self, momentum, table: PayloadTable, mass: float, dt: float, momentum_noise: float):
        self._H, self.table, self.dt = momentum, table, float(dt)
        lo, hi = float(table.masses[0]), float(table.masses[-1])
        self._lo, self._span = lo, hi - lo
        self._p_lo, self._p_hi = table.vectors[0], table.vectors[-1]
        self._prior = (float(np.clip(mass, lo, hi)) - lo) / self._span          # in units of the range
        self._w2 = 1.0 / float(momentum_noise) ** 2
        self.reset()

    def reset(self) -> None:
        """Back to the prior: a uniform range's variance, no torque integrated yet."""
        # unknowns (w, lag): w = (m - lo) / span with a uniform range's information 12, and the
        # torque's lag [s] behind the held command (the impulse then trails by lag * u: an amplifier's
        # or an integrator's), a nuisance with prior 0 +- one sample
        self._info = np.diag([12.0, 1.0 / self.dt ** 2])
        self._moment = np.array([12.0 * self._prior, 0.0])
        self._impulse, self._offset = 0.0, None
        self.mass = self._lo + self._span * self._prior
        self.variance = self._span ** 2 / 12.0
        self.lag_s = 0.0
        self.history = []

    def _momenta(self, x) -> tuple:
        x = np.asarray(x, dtype=float)
        n = len(x) // 2
        return (float(self._H(x[:n], x[n:], self._p_lo)), float(self._H(x[:n], x[n:], self._p_hi)))

    def update(self, x, u_prev: float | None) -> float:
        """One measured state; ``u_prev`` the command held over the sample before it [N m]
        (None at the first sample).

        Parameters
        ----------
        x : array_like (2 n,)
            The prediction model's state ``[q, v]`` [rad, m, rad/s, m/s].
        u_prev : float or None
            The command applied over the last sample [N m].

        Returns
        -------
        float
            The new estimate [kg].
        """
        h_lo, h_hi = self._momenta(x)
        if self._offset is None or u_prev is None:     # the first state: the balance starts here
            if self._offset is None:
                self._offset = (h_lo, h_hi)
            self.history.append(self.mass)
            return self.mass
        self._impulse += float(u_prev) * self.dt
        row = np.array([(h_hi - self._offset[1]) - (h_lo - self._offset[0]), float(u_prev)])   # dH/dw, -dI/dlag
        e = self._impulse - (h_lo - self._offset[0])
        self._info += self._w2 * np.outer(row, row)
        self._moment += self._w2 * row * e
        w, self.lag_s = np.linalg.solve(self._info, self._moment)
        self.mass = self._lo + self._span * float(np.clip(w, 0.0, 1.0))
        self.variance = self._span ** 2 * float(np.linalg.inv(self._info)[0, 0])
        self.history.append(self.mass)
        return self.mass
