"""Poles of a linear model: z- or s-plane, and the undamped natural frequencies of its modes.

Each function takes a :class:`~hubbeam_ctrl.linear.statespace.LinearModel` or a
python-control :class:`~control.StateSpace`.
"""

from __future__ import annotations

import numpy as np

__all__ = ["poles", "continuous_poles", "poles_hz"]


def _system(lm):
    """The python-control system of ``lm`` (a LinearModel holds it as ``sys``)."""
    return getattr(lm, "sys", lm)


def poles(lm) -> np.ndarray:
    """Poles of a :class:`LinearModel` or :class:`control.StateSpace` (z-plane if sampled).

    Parameters
    ----------
    lm : LinearModel or control.StateSpace
        The model.
    """
    sys = _system(lm)
    return sys.poles()


def continuous_poles(lm) -> np.ndarray:
    """Poles in the s-plane [rad/s]; a sampled model's ``z`` are mapped by ``log(z)/dt``.

    Parameters
    ----------
    lm : LinearModel or control.StateSpace
        The model (continuous or sampled).
    """
    sys = _system(lm)
    lam = poles(sys).astype(complex)
    if sys.dt:
        dt = float(sys.dt)
        with np.errstate(divide="ignore", invalid="ignore"):
            lam = np.log(lam) / dt
    return lam


def split_rigid(lam: np.ndarray, n_rigid: int):
    """Indices of the ``n_rigid`` poles nearest zero, and of the rest.

    Parameters
    ----------
    lam : ndarray
        Poles [rad/s].
    n_rigid : int
        Number of rigid-body poles.
    """
    order = np.argsort(np.abs(lam), kind="stable")
    return order[:n_rigid], order[n_rigid:]


def poles_hz(lm, n_rigid: int | None = None) -> np.ndarray:
    """Undamped natural frequencies of the oscillatory poles [Hz], ascending.

    Each complex-conjugate pair counts once (``|s| / 2 pi``); the rigid-body double pole
    at ``s = 0`` and real poles (a mode that has lost its stiffness) are left out.

    Parameters
    ----------
    lm : LinearModel or control.StateSpace
    n_rigid : int, optional
        Number of rigid-body poles to drop (the ones nearest zero). Default: 2 for a
        :class:`LinearModel` (free hub), else those with ``|s| < 1e-9 max|s|``.

    Returns
    -------
    ndarray
    """
    lam = continuous_poles(lm)
    if n_rigid is None and _system(lm) is not lm:       # a LinearModel: free hub
        n_rigid = 2
    if n_rigid is None:
        keep = np.abs(lam) > 1e-9 * max(np.abs(lam).max(), 1.0)
    else:
        keep = np.zeros(len(lam), bool)
        keep[split_rigid(lam, n_rigid)[1]] = True
    lam = lam[keep]
    osc = lam[(lam.imag > 0) & (np.abs(lam.imag) > 1e-9 * np.abs(lam))]
    return np.sort(np.abs(osc)) / (2 * np.pi)
