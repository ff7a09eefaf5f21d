"""Spillover: the sampled poles of a linear controller on a richer linear plant.

A controller designed on an ``m``-mode model meets the modes it leaves out through its
sensors (observation spillover) and its torque (control spillover). With no structural
damping those modes sit on the unit circle, and the feedback moves them in or out. This
module closes the loop on the sampled (zero-order hold) linear SFOAM with any number of
modes and returns its poles: a spectral radius above 1 is a growing mode, at the frequency
(aliased into ``0..f_s/2``) given by the pole's angle.

Controllers: any with a linear form (:class:`controllers.LQR` reading plant coordinates,
:class:`controllers.LQG` and :class:`controllers.PD` reading sensors, the MPC's unconstrained law);
the feedback part only (reference and feedforward are inputs, not dynamics; saturation
is ignored).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from controllers import Controller
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.params import MAX_MODES, Params
from hubbeam_ctrl.study.certificate import loop_matrix

__all__ = ["LoopPoles", "loop_poles"]


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

def loop_poles(controller: Controller, plant_modes: int, params: Params | None = None,
               damping_ratio: float | None = None) -> LoopPoles:
    """Sampled poles of ``controller`` on the linear SFOAM with ``plant_modes`` modes.

    The loop of :func:`hubbeam_ctrl.study.certificate.loop_matrix` (the controller's
    :meth:`~controllers.Controller.feedback_matrices` on the zero-order-hold SFOAM at the
    design spin).

    Parameters
    ----------
    controller : Controller
        With a linear form (PD, LQR, LQG, MPC's unconstrained law).
    plant_modes : int
        Transverse modes of the plant, the modes the controller's gain acts on..20.
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
    (1.011, 47.7)
    """
    design = controller.design
    lo = int(getattr(controller, "state_modes", design.n_modes))
    if isinstance(plant_modes, bool) or not isinstance(plant_modes, (int, np.integer)) \
            or not lo <= plant_modes <= MAX_MODES:
        raise ParameterError(f"plant_modes must be an integer in {lo}..{MAX_MODES}, got {plant_modes!r}")
    p = (params if params is not None else design.params).replace(n_transverse=int(plant_modes))
    zeta = p.damping_ratio if damping_ratio is None else damping_ratio
    A, _ = loop_matrix(controller, p, design.spin, zeta)
    return LoopPoles(np.linalg.eigvals(A), int(plant_modes), design.dt)
