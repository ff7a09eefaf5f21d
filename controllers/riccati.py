"""Discrete algebraic Riccati equations of the LQR gain and the Kalman filter, without importing
python-control.

:func:`dlqr` and :func:`dlqe` return exactly what :func:`control.dlqr` and :func:`control.dlqe`
return (python-control 0.10): with Slycot installed they call python-control (which then
solves with Slycot); without it they do python-control's SciPy path step for step
(:func:`scipy.linalg.solve_discrete_are`, then the gain by :func:`scipy.linalg.solve` and the
closed-loop eigenvalues by :func:`scipy.linalg.eigvals`), bit for bit, but without importing
python-control, whose import loads SciPy's signal and statistics packages and Matplotlib's
pyplot (``-X importtime`` of a ``hubbeam compare`` on the 2-core machine: 2.6 s of imports with
python-control, 1.5 s without; more than the designs).

Examples
--------
>>> import numpy as np
>>> K, S, E = dlqr(np.array([[1.0, 0.1], [0.0, 1.0]]), np.array([[0.005], [0.1]]), np.eye(2), np.eye(1))
>>> K.shape, bool(np.all(np.abs(E) < 1))
((1, 2), True)
"""

from __future__ import annotations

import importlib.util

import numpy as np

__all__ = ["dlqr", "dlqe"]


def _slycot() -> bool:
    """Whether python-control would solve with Slycot (it does when Slycot is installed)."""
    return importlib.util.find_spec("slycot") is not None


def _check(M: np.ndarray, n: int, m: int, name: str, symmetric: bool = False) -> None:
    """python-control's shape and symmetry checks (``ValueError`` naming the matrix)."""
    if symmetric and M.shape[0] != M.shape[1]:
        raise ValueError(f"{name} must be a square matrix")
    if symmetric and not ((M - M.T) < np.finfo(M.dtype).eps).all():
        raise ValueError(f"{name} must be a symmetric matrix")
    if M.shape != (n, m):
        raise ValueError(f"Incompatible dimensions of {name} matrix; expected ({n}, {m}) but found {M.shape}")


def _dare(A, B, Q, R, S, names) -> tuple:
    """``(X, L, G)`` of python-control's ``dare(A, B, Q, R, S, method="scipy")``."""
    import scipy.linalg  # here, not at the top: ``import controllers`` stays free of SciPy (CLI start-up)
    A, B, Q, R = (np.array(M, ndmin=2) for M in (A, B, Q, R))
    S = None if S is None else np.array(S, ndmin=2)
    n, m = A.shape[0], B.shape[1]
    _check(A, n, n, names[0])
    _check(B, n, m, names[1])
    _check(Q, n, n, names[2], symmetric=True)
    _check(R, m, m, names[3], symmetric=True)
    if S is not None:
        _check(S, n, m, names[4])
    X = scipy.linalg.solve_discrete_are(A, B, Q, R, e=None, s=S)
    if S is None:
        G = scipy.linalg.solve(B.T @ X @ B + R, B.T @ X @ A)
    else:
        G = scipy.linalg.solve(B.T @ X @ B + R, B.T @ X @ A + S.T)
    return X, scipy.linalg.eigvals(A - B @ G), G


def dlqr(A, B, Q, R) -> tuple:
    """Discrete-time LQR: :func:`control.dlqr` ``(A, B, Q, R)``.

    Parameters
    ----------
    A : array_like (n, n)
        Sampled state matrix [-].
    B : array_like (n, m)
        Sampled input matrix [state units per input unit].
    Q : array_like (n, n)
        State weight, symmetric.
    R : array_like (m, m)
        Input weight, symmetric.

    Returns
    -------
    K : ndarray (m, n)
        Gain of ``u = -K x``.
    S : ndarray (n, n)
        Solution of the Riccati equation.
    E : ndarray (n,)
        Closed-loop eigenvalues (z-plane).

    Raises
    ------
    ValueError
        Bad shapes, a non-symmetric weight, or no stabilising solution (SciPy's message).
    numpy.linalg.LinAlgError
        A singular equation.
    """
    if _slycot():
        import control
        try:
            return control.dlqr(A, B, Q, R)
        except control.ControlArgument as exc:
            raise ValueError(str(exc)) from None
        except Exception as exc:      # noqa: BLE001 - Slycot's Schur reordering fails on stiff modes: SciPy's
            if not type(exc).__module__.startswith("slycot"):
                raise
    A, B = np.array(A, ndmin=2, dtype=float), np.array(B, ndmin=2, dtype=float)
    Q, R = np.array(Q, ndmin=2, dtype=float), np.array(R, ndmin=2, dtype=float)
    N = np.zeros((Q.shape[0], R.shape[1]))
    S, E, K = _dare(A, B, Q, R, N, ("A", "B", "Q", "R", "N"))
    return K, S, E


def dlqe(A, G, C, QN, RN) -> tuple:
    """Discrete-time Kalman filter: :func:`control.dlqe` ``(A, G, C, QN, RN)``.

    Parameters
    ----------
    A : array_like (n, n)
        Sampled state matrix [-].
    G : array_like (n, k)
        How the process noise enters the state.
    C : array_like (p, n)
        Output matrix.
    QN : array_like (k, k)
        Process-noise covariance, symmetric.
    RN : array_like (p, p)
        Measurement-noise covariance, symmetric.

    Returns
    -------
    L : ndarray (n, p)
        Gain of the prediction form ``x[k+1] = A x[k] + ... + L (y - C x[k])``.
    P : ndarray (n, n)
        A-priori error covariance.
    E : ndarray (n,)
        Eigenvalues of the filter (z-plane).

    Raises
    ------
    ValueError
        Bad shapes, a non-symmetric covariance, or no stabilising solution.
    numpy.linalg.LinAlgError
        A singular equation.
    """
    if _slycot():
        import control
        try:
            return control.dlqe(A, G, C, QN, RN)
        except control.ControlArgument as exc:
            raise ValueError(str(exc)) from None
    A, G, C = (np.array(M, ndmin=2, dtype=float) for M in (A, G, C))
    QN, RN = np.array(QN, ndmin=2, dtype=float), np.array(RN, ndmin=2, dtype=float)
    _check(QN, G.shape[1], G.shape[1], "QN")
    P, E, LT = _dare(A.T, C.T, G @ QN @ G.T, RN, None, ("A", "C", "QN", "RN", "NN"))
    return LT.T, P, E
