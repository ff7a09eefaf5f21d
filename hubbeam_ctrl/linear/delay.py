"""The computation delay in a sampled linear model: one extra state, the previous command.

A controller that samples at ``t_k = k dt`` and needs ``d dt`` (``0 <= d <= 1``) to compute its
command applies ``u[k]`` only from ``t_k + d dt``; over ``[t_k, t_k + d dt)`` the previous
command ``u[k-1]`` still acts. Sampling ``x' = A x + B u`` exactly under that input gives the
standard fractional-delay zero-order hold (Franklin, Powell and Workman, *Digital Control of
Dynamic Systems*, 3rd ed., sec. 4.3.4)::

    x[k+1] = Phi x[k] + Gamma1 u[k-1] + Gamma0 u[k]
    Phi    = exp(A dt)
    Gamma0 = int_0^{(1-d) dt} exp(A s) ds B
    Gamma1 = exp(A (1-d) dt) int_0^{d dt} exp(A s) ds B

and, with ``u[k-1]`` as an extra state, the augmented model ``z = [x, u_prev]``::

    z[k+1] = [[Phi, Gamma1], [0, 0]] z[k] + [[Gamma0], [I]] u[k]

``d = 0`` is the ordinary zero-order hold (``Gamma1 = 0``); ``d = 1`` a whole sample of delay
(``Gamma0 = 0``). The integrals come from one matrix exponential each (Van Loan's block form).

Examples
--------
>>> A, B = np.array([[0.0, 1.0], [0.0, 0.0]]), np.array([[0.0], [1.0]])    # a unit inertia
>>> Ad, Bd = delay_augmented(A, B, 0.1, 0.5)
>>> np.round(Ad[:2, 2], 6).tolist(), np.round(Bd[:2, 0], 6).tolist()
([0.00375, 0.05], [0.00125, 0.05])
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import expm

from hubbeam_ctrl.core.errors import ParameterError

__all__ = ["delay_augmented", "delay_inputs"]


def _zoh(A: np.ndarray, B: np.ndarray, h: float) -> tuple:
    """``(exp(A h), int_0^h exp(A s) ds B)`` by one exponential of ``[[A, B], [0, 0]] h``."""
    n, m = B.shape
    if h == 0.0:
        return np.eye(n), np.zeros((n, m))
    M = np.zeros((n + m, n + m))
    M[:n, :n], M[:n, n:] = A, B
    E = expm(M * h)
    return E[:n, :n], E[:n, n:]


def delay_inputs(A, B, dt: float, delay: float) -> tuple:
    """``(Phi, Gamma0, Gamma1)`` of the fractional-delay zero-order hold (module docstring).

    Parameters
    ----------
    A : array_like (n, n)
        Continuous state matrix [1/s].
    B : array_like (n, m)
        Continuous input matrix.
    dt : float
        Sample time [s], > 0.
    delay : float
        Computation delay as a fraction of the sample [-], in [0, 1] (``timing.delay``).

    Returns
    -------
    tuple of ndarray
        ``Phi`` (n, n), ``Gamma0`` (n, m) (this sample's command), ``Gamma1`` (n, m) (the previous one).
    """
    A = np.atleast_2d(np.asarray(A, dtype=float))
    B = np.asarray(B, dtype=float).reshape(A.shape[0], -1)
    if A.shape[0] != A.shape[1] or not np.all(np.isfinite(A)) or not np.all(np.isfinite(B)):
        raise ParameterError(f"A must be a finite square matrix and B have its rows, got A {A.shape}, B {B.shape}")
    if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
        raise ParameterError(f"dt must be > 0 [s], got {dt!r}")
    if not (isinstance(delay, (int, float)) and 0.0 <= delay <= 1.0):
        raise ParameterError(f"timing.delay must be in [0, 1] (a fraction of the sample, at most one), got {delay!r}")
    late = (1.0 - delay) * dt
    Phi_late, Gamma0 = _zoh(A, B, late)
    _, G_early = _zoh(A, B, delay * dt)
    Gamma1 = Phi_late @ G_early
    Phi = _zoh(A, B, dt)[0]
    return Phi, Gamma0, Gamma1


def delay_augmented(A, B, dt: float, delay: float) -> tuple:
    """The sampled model with the computation delay as an extra state ``u_prev``.

    Parameters
    ----------
    A, B, dt, delay
        As :func:`delay_inputs`.

    Returns
    -------
    Ad : ndarray (n + m, n + m)
        ``[[Phi, Gamma1], [0, 0]]`` on ``z = [x, u_prev]``.
    Bd : ndarray (n + m, m)
        ``[[Gamma0], [I]]``.

    Notes
    -----
    An output ``y = C x + D u`` of the plant is ``[C, 0] z`` (plus ``D u``) on the augmented state.
    """
    Phi, G0, G1 = delay_inputs(A, B, dt, delay)
    n, m = G0.shape
    Ad = np.zeros((n + m, n + m))
    Ad[:n, :n], Ad[:n, n:] = Phi, G1
    Bd = np.vstack([G0, np.eye(m)])
    return Ad, Bd
