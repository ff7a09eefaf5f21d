"""Residual modes for an estimator: model what the sensors see, control only the design modes.

A Kalman filter built on the ``m``-mode design model attributes every signal on the root
bending-moment sensor to those ``m`` modes. The beam's next modes (on the paper's beam
mode 6 at 37 Hz, and mode 7 at 52 Hz, which 100 Hz sampling folds to 48 Hz) are in that
signal too; the filter misreads them as modes 4-5 and the feedback, acting on the wrong
estimate, pumps energy into them: with no structural damping the loop grows by 1.4 % per
sample at 48 Hz (docs/controllers.md).

The cure measured best (issue 27): the estimator's model carries **residual modes**, the
same modes as the default evaluation plant (every bending mode below the *sampling*
frequency, the first above it, and at least three more than the design model: modes the
zero-order hold folds back are modelled, not guessed), and the state-feedback gain is
computed on that model (:class:`controllers.LQGSettings` ``residual_control``), so the
sampled loop is stable on every mode the filter models. The earlier rule (modes below the
Nyquist frequency plus one, the gain padded with zeros) left the paper's mode 8 (70 Hz,
folded to 30 Hz) unmodelled, and the loop grew by 0.04 % per sample there.
"""

from __future__ import annotations

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.params import MAX_MODES
from hubbeam_ctrl.sim.evaluation import default_plant_modes

from .base import DesignModel

__all__ = ["estimator_modes", "estimator_model", "embedding", "residual_design"]


def estimator_modes(design: DesignModel) -> int:
    """Transverse modes of the estimator: those of the default evaluation plant.

    Every bending mode below the sampling frequency ``1/dt``, the first above it, and at
    least three more than the design model, at most 20
    (:func:`hubbeam_ctrl.sim.evaluation.default_plant_modes` at the design spin).

    Parameters
    ----------
    design : DesignModel

    Returns
    -------
    int
        At least ``design.n_modes``, at most 20.

    Examples
    --------
    >>> estimator_modes(DesignModel.build())     # the paper's beam at 100 Hz: modes 1-10
    10
    """
    return int(default_plant_modes(design.params, design.dt, design.n_modes, design.spin)[0])


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
    return DesignModel.build(design.params, design.spin, design.dt, int(n)).like(design)


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


def residual_design(design: DesignModel, weights, n_modes: int | None = None) -> tuple:
    """The design model with residual modes and the design's weights embedded in it.

    A state feedback (LQR, MPC, LQG's gain) computed on the returned pair weighs exactly
    what the design asked for (the state weight is the design's on the design modes and
    zero on the residual modes) while its Riccati solution keeps the residual modes stable,
    so the sampled loop is stable on every mode the model carries instead of pumping
    energy into the ones a gain padded with zeros ignores.

    Parameters
    ----------
    design : DesignModel
    weights : Weights
        The design's weights.
    n_modes : int, optional
        Transverse modes of the model (default :func:`estimator_modes`).

    Returns
    -------
    tuple
        ``(model, weights)``: the :class:`DesignModel` with residual modes (``design``
        itself when none are added) and a :class:`~controllers.Weights` whose
        ``state_matrix`` is the embedded state weight (``weights`` itself when none are
        added).

    Examples
    --------
    >>> from controllers import Weights
    >>> d = DesignModel.build(n_modes=2)
    >>> model, w = residual_design(d, Weights(), 4)
    >>> model.n_modes, w.state_matrix.shape
    (4, (10, 10))
    """
    model = estimator_model(design, n_modes)
    if model is design:
        return design, weights
    E = embedding(design.n_modes, model.n_modes)
    Qd, _ = weights.matrices(design)
    return model, weights.replace(state_matrix=E @ Qd @ E.T)
