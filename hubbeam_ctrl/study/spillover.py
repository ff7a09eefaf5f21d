"""Spillover: the sampled poles of a linear controller on a richer linear plant.

A controller designed on an ``m``-mode model meets the modes it leaves out through its
sensors (observation spillover) and its torque (control spillover). With no structural
damping those modes sit on the unit circle, and the feedback moves them in or out. This
module closes the loop on the sampled (zero-order hold) linear SFOAM with any number of
modes and returns its poles: a spectral radius above 1 is a growing mode, at the frequency
(aliased into ``0..f_s/2``) given by the pole's angle.

Controllers: :class:`controllers.LQR` (plant coordinates of the design modes),
:class:`controllers.LQG` (sensors, its own filter) and :class:`controllers.PD` (sensors);
the feedback part only (reference and feedforward are inputs, not dynamics; saturation
is ignored).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from controllers import LQG, LQR, PD, Controller
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.linear.statespace import discretize, linearize
from hubbeam_ctrl.plant.params import MAX_MODES, Params

__all__ = ["LoopPoles", "feedback_realization", "loop_poles"]


@dataclass(frozen=True)
class LoopPoles:
    """Poles of a sampled closed loop.

    Attributes
    ----------
    poles : ndarray (complex)
        z-plane poles of plant and controller together.
    plant_modes : int
        Transverse modes of the linear plant.
    dt : float
        Sample time [s].
    """

    poles: np.ndarray
    plant_modes: int
    dt: float

    @property
    def spectral_radius(self) -> float:
        """Largest ``|z|`` [-]; above 1 the loop is unstable."""
        return float(np.max(np.abs(self.poles)))

    @property
    def worst_hz(self) -> float:
        """Frequency of the pole of largest ``|z|``, aliased into ``0..1/(2 dt)`` [Hz]."""
        z = self.poles[np.argmax(np.abs(self.poles))]
        return float(abs(np.angle(z)) / (2 * np.pi * self.dt))

def feedback_realization(controller: Controller):
    """The controller's feedback as a discrete state space from its measurement to ``tau``.

    ``z[k+1] = Ak z[k] + Bk y[k]``, ``tau[k] = Ck z[k] + Dk y[k]``, with ``y`` the sensors
    ``[theta, theta_dot, M_root]`` (LQG, PD) or the SFOAM-ordered state of the design modes
    (LQR).

    Parameters
    ----------
    controller : LQR, LQG or PD

    Returns
    -------
    tuple of ndarray
        ``(Ak, Bk, Ck, Dk)``.
    """
    if isinstance(controller, LQG):
        est = controller.filter_model
        K = controller._Ke[None, :]
        L, C = controller.L, est.C_sensors
        F = est.Ad - est.Bd @ K
        I_LC = np.eye(est.n_x) - L @ C
        return F @ I_LC, F @ L, -K @ I_LC, -K @ L
    if isinstance(controller, LQR):
        n = controller.design.n_x
        return np.zeros((0, 0)), np.zeros((0, n)), np.zeros((1, 0)), -controller.K[None, :]
    if isinstance(controller, PD):
        return (np.zeros((0, 0)), np.zeros((0, 3)), np.zeros((1, 0)),
                np.array([[-controller.kp, -controller.kd, 0.0]]))
    raise ParameterError(f"controller must be an LQR, LQG or PD for the loop poles, got "
                         f"{type(controller).__name__}")


def loop_poles(controller: Controller, plant_modes: int, params: Params | None = None,
               damping_ratio: float | None = None) -> LoopPoles:
    """Sampled poles of ``controller`` on the linear SFOAM with ``plant_modes`` modes.

    Parameters
    ----------
    controller : LQR, LQG or PD
    plant_modes : int
        Transverse modes of the plant, the controller's design modes..20.
    params : Params, optional
        Physical parameters of the plant (default: the controller's design model's).
    damping_ratio : float, optional
        Modal damping ratio of the plant (default: that of ``params``).

    Returns
    -------
    LoopPoles

    Examples
    --------
    >>> from controllers import DesignModel, LQG, LQGSettings
    >>> naive = LQG(DesignModel.build(), LQGSettings(robust=False))
    >>> lp = loop_poles(naive, 10)                    # the paper's beam, 10 modes, 100 Hz
    >>> round(lp.spectral_radius, 3), round(lp.worst_hz, 1)   # mode 7 (52 Hz) folded to 48 Hz
    (1.011, 47.6)
    """
    design = controller.design
    if isinstance(plant_modes, bool) or not isinstance(plant_modes, (int, np.integer)) \
            or not design.n_modes <= plant_modes <= MAX_MODES:
        raise ParameterError(f"plant_modes must be an integer in {design.n_modes}..{MAX_MODES}, "
                             f"got {plant_modes!r}")
    p = (params if params is not None else design.params).replace(n_transverse=int(plant_modes))
    if damping_ratio is not None:
        p = p.replace(damping_ratio=damping_ratio)
    lm = discretize(linearize("sfoam", design.spin, p, ("theta", "theta_dot", "root_moment")), design.dt)
    Ap, Bp, Cp = np.asarray(lm.A), np.asarray(lm.B), np.asarray(lm.C)
    if controller.measurement == "state":      # the design modes' plant coordinates
        n, m = 1 + plant_modes, 1 + design.n_modes
        Cp = np.zeros((2 * m, 2 * n))
        Cp[:m, :m] = np.eye(m)
        Cp[m:, n:n + m] = np.eye(m)
    Ak, Bk, Ck, Dk = feedback_realization(controller)
    A = np.block([[Ap + Bp @ Dk @ Cp, Bp @ Ck], [Bk @ Cp, Ak]])
    return LoopPoles(np.linalg.eigvals(A), int(plant_modes), design.dt)
