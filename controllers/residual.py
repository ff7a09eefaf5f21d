"""Residual modes for an estimator: model what the sensors see, control only the design modes.

A Kalman filter built on the ``m``-mode design model attributes every signal on the root
bending-moment sensor to those ``m`` modes. The beam's next modes (on the paper's beam
mode 6 at 37 Hz, and mode 7 at 52 Hz, which 100 Hz sampling folds to 48 Hz) are in that
signal too; the filter misreads them as modes 4-5 and the feedback, acting on the wrong
estimate, pumps energy into them: with no structural damping the loop grows by 1.4 % per
sample at 48 Hz (docs/controllers.md).

The cure measured best: the estimator's model carries **residual modes**, every bending
mode below the Nyquist frequency plus the first above it (the first mode the sampling
folds back), so the filter can tell them apart; the state-feedback gain stays the design
model's, padded with zeros, so the controller does not try to control them. Modes further
up fold onto the low modes (the paper's mode 9, 90.6 Hz, lands at 9.4 Hz beside mode 3)
and make the filter ill-conditioned, and their share of the root moment falls off, so
they are left out.
"""

from __future__ import annotations

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.modal import converged_bending_hz
from hubbeam_ctrl.plant.params import MAX_MODES

from .base import DesignModel

__all__ = ["estimator_modes", "estimator_model", "embedding"]


def estimator_modes(design: DesignModel) -> int:
    """Transverse modes of the estimator: every mode below Nyquist and the first above it.

    Parameters
    ----------
    design : DesignModel

    Returns
    -------
    int
        At least ``design.n_modes``, at most 20.

    Examples
    --------
    >>> estimator_modes(DesignModel.build())     # the paper's beam at 100 Hz: modes 1-7
    7
    """
    f = converged_bending_hz(design.params, design.spin)
    below = int(np.sum(f < 0.5 / design.dt))
    return int(min(MAX_MODES, max(design.n_modes, below + 1)))


def estimator_model(design: DesignModel, n_modes: int | None = None) -> DesignModel:
    """The design model with residual modes (the same SFOAM, more transverse modes).

    Parameters
    ----------
    design : DesignModel
    n_modes : int, optional
        Transverse modes, ``design.n_modes..20`` (default :func:`estimator_modes`).

    Returns
    -------
    DesignModel
        ``design`` itself when no mode is added.
    """
    n = estimator_modes(design) if n_modes is None else n_modes
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not design.n_modes <= n <= MAX_MODES:
        raise ParameterError(f"residual_modes must be an integer in {design.n_modes}..{MAX_MODES} "
                             f"(the estimator's transverse modes), got {n!r}")
    if n == design.n_modes:
        return design
    return DesignModel.build(design.params, design.spin, design.dt, int(n))


def embedding(n_design: int, n_estimator: int) -> np.ndarray:
    """Matrix ``E`` with ``x_est = E x_design`` (residual modes zero); ``x_design = E' x_est``.

    States are ``[theta, q2_1..q2_n, theta_dot, q2_dot_1..q2_dot_n]``.

    Parameters
    ----------
    n_design, n_estimator : int
        Transverse modes of the two models, ``n_design <= n_estimator``.

    Returns
    -------
    ndarray (2 (1 + n_estimator), 2 (1 + n_design))

    Examples
    --------
    >>> embedding(1, 2).astype(int).tolist()
    [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1], [0, 0, 0, 0]]
    """
    a, b = 1 + n_design, 1 + n_estimator
    E = np.zeros((2 * b, 2 * a))
    E[:a, :a] = np.eye(a)
    E[b:b + a, a:] = np.eye(a)
    return E
