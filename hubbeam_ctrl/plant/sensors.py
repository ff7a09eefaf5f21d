"""Hub sensors: the measured signals, defined once for the linear model and the simulator.

The sensors are the hub angle (encoder), the hub rate (tachometer or gyro) and the root
bending moment ``M_root = E I w2''(0) = E I f2''(0) q2`` (a strain gauge at the root).
:func:`sensor_matrix` gives their rows on a plant state ``[q, v]``; the linear models of
:mod:`hubbeam_ctrl.linear.statespace` and the closed-loop simulator both use it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.core.settings import Settings, setting
from hubbeam_ctrl.plant.basis import modal_basis
from hubbeam_ctrl.plant.params import Params

__all__ = ["SensorSettings", "SENSOR_NAMES", "sensor_matrix"]

#: The measured signals, in the order of :func:`sensor_matrix`'s rows.
SENSOR_NAMES = ("theta", "theta_dot", "root_moment")


@dataclass(frozen=True)
class SensorSettings(Settings):
    """Realistic hub sensors for output-feedback controllers (``measurement="sensors"``).

    The measurement is ``[theta, theta_dot, M_root]`` plus independent zero-mean Gaussian
    white noise of the standard deviations below, drawn afresh at each sample.
    """

    angle_noise_rad: float = setting(1e-4, unit="rad", lo=0.0, hi=1.0,
                                     doc="Hub-angle encoder noise, standard deviation (about a 16-bit "
                                         "encoder).")
    rate_noise_rad_s: float = setting(1e-3, unit="rad/s", lo=0.0, hi=10.0,
                                      doc="Hub-rate (tachometer / gyro) noise, standard deviation.")
    moment_noise_nm: float = setting(0.02, unit="N m", lo=0.0, hi=1e6,
                                     doc="Root bending-moment (strain gauge) noise, standard deviation.")
    seed: int = setting(0, lo=0, hi=2**63 - 1, doc="Seed of the noise generator (runs are reproducible).")
    encoder_counts: int = setting(0, lo=0, hi=10**9, unit="counts/rev",
                                  doc="Hub encoder resolution: the measured hub angle (noise included) is "
                                      "rounded to the nearest multiple of 2 pi / encoder_counts, for every "
                                      "controller (also those that read the state); 0: not quantised.")

    @property
    def encoder_step(self) -> float:
        """Angle quantum ``2 pi / encoder_counts`` [rad] (0.0: not quantised)."""
        return 0.0 if self.encoder_counts == 0 else 2.0 * np.pi / self.encoder_counts

    @property
    def std(self) -> np.ndarray:
        """Noise standard deviations ``[rad, rad/s, N m]``."""
        return np.array([self.angle_noise_rad, self.rate_noise_rad_s, self.moment_noise_nm])


def sensor_matrix(params: Params, n_modes: int, n_axial: int = 0) -> np.ndarray:
    """Output matrix of the sensors (:data:`SENSOR_NAMES`) on a state ``[q, v]``.

    ``M_root = EI f2''(0) q2`` is the bending moment at the beam root [N m].

    Parameters
    ----------
    params : Params
    n_modes : int
        Number of transverse modes in the state.
    n_axial : int
        Number of axial coordinates between ``theta`` and ``q2`` (0 for SFOAM).

    Returns
    -------
    ndarray (3, 2 (1 + n_axial + n_modes))
    """
    basis = modal_basis(params.replace(n_transverse=n_modes))
    n = 1 + n_axial + n_modes
    C = np.zeros((3, 2 * n))
    C[0, 0] = 1.0
    C[1, n] = 1.0
    C[2, 1 + n_axial:n] = params.EI * basis.f2pp_root
    return C
