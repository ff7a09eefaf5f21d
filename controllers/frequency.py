"""Frequency responses of sampled SISO loops, and the frequency grid they are evaluated on.

:class:`FrequencyResponse` prepares ``C (zI - A)^-1 B + D`` once for many points (a modal form,
a split of the free hub's Jordan block, or Laub's Hessenberg solves); :func:`frequency_grid`
gives the frequencies that resolve every lightly damped mode. Used by the loop margins
(:mod:`controllers.analysis`) and the loop plots (:mod:`hubbeam_ctrl.study.loops`).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["FrequencyResponse", "frequency_grid", "hessenberg_form", "hessenberg_response"]

#: Fewer points than this are solved densely, one LAPACK solve each (a point of a root finder);
#: more go through :func:`hessenberg_response`, whose per-step Python overhead is then shared.
FEW_POINTS = 16


class FrequencyResponse:
    """SISO frequency response ``C (zI - A)^-1 B + D``, prepared once for many points.

    ``A`` is diagonalised once (``A = V diag(lam) V^-1``), so each point costs ``O(n)``:
    ``sum_i (C V)_i (V^-1 B)_i / (z - lam_i) + D``. Measured: the same values to 1e-12 relative
    on the loops of the default comparison, 50-200 times fewer operations on 50 states.

    A sampled hub-beam loop is not diagonalisable: the free hub's double integrator is a
    Jordan block at ``z = 1`` (``cond(V)`` about 1e14). Then ``A`` is split once by an ordered
    Schur form and a Sylvester equation into that cluster of repeated eigenvalues (a small
    block, solved at each point) and the rest (diagonalised, ``O(n)`` per point): 20-50 times
    faster than a linear solve per point on the comparison's loops (12-44 states). The split
    form is less accurate than a solve where its terms nearly cancel (close poles and zeros,
    undamped resonances): on the default comparison's loops, up to 1.2e-3 relative where the
    solves are within 5e-9 (against 80-bit arithmetic), 0.01 dB on a plot. So ``precise=True``
    solves where the values are results (the margins' root finding and refinement,
    :func:`~controllers.analysis.loop_margins`); grids for plots and for bracketing take the
    split form. Where neither form is well conditioned (``cond > 1e6``), every point is solved.

    A solve is Laub's (1981): ``A = Q H Q^T`` with ``H`` upper Hessenberg once, then
    ``(zI - H) x = Q^T B`` at each point by Gaussian elimination with partial pivoting between
    the two rows a Hessenberg column has, vectorised over the points: ``O(n^2)`` a point
    instead of a dense solve's ``O(n^3)`` (:func:`hessenberg_response`; the same margins,
    measured against dense solves in ``benchmarks/bench_frequency.py``). Fewer than
    :data:`FEW_POINTS` points (a root finder's) are solved densely, one LAPACK call each.

    Parameters
    ----------
    A : ndarray (n, n)
    B : ndarray (n, 1)
    C : ndarray (1, n)
    D : ndarray (1, 1) or float, optional
    """

    def __init__(self, A, B, C, D=0.0):
        self.A, self.B, self.C = np.asarray(A), np.asarray(B), np.asarray(C)
        self.D = complex(np.asarray(D, dtype=float).reshape(-1)[0]) if np.size(D) else 0.0
        n = self.A.shape[0]
        self._modal = self._split = self._hessenberg = None
        if n:
            lam, V = np.linalg.eig(self.A)
            if np.linalg.cond(V) < 1e6:
                self._modal = (lam, (self.C @ V)[0], np.linalg.solve(V, self.B)[:, 0])
            else:
                self._split = _cluster_split(self.A, self.B, self.C, lam)

    def __call__(self, z, precise: bool = False) -> np.ndarray:
        """The response at the points ``z`` (complex, any shape flattened to 1-D).

        Parameters
        ----------
        z : array_like of complex
            Points of the z-plane [-].
        precise : bool
            Linear solves instead of the split form of a non-diagonalisable ``A`` (see the class).
        """
        z = np.atleast_1d(np.asarray(z, dtype=complex)).ravel()
        out = np.full(z.shape, self.D, dtype=complex)
        n = self.A.shape[0]
        if n == 0:
            return out
        if self._modal is not None:
            lam, cv, vb = self._modal
            w = cv * vb
            for k in range(0, len(z), 512):
                zz = z[k:k + 512]
                out[k:k + 512] += (w[None, :] / (zz[:, None] - lam[None, :])).sum(axis=1)
            return out
        if self._split is not None and not precise:
            T11, c1, b1, mu, w = self._split
            m = T11.shape[0]
            for k in range(0, len(z), 512):
                zz = z[k:k + 512]
                out[k:k + 512] += (w[None, :] / (zz[:, None] - mu[None, :])).sum(axis=1)
                x = np.linalg.solve(zz[:, None, None] * np.eye(m) - T11, np.broadcast_to(b1[:, None], (len(zz), m, 1)))
                out[k:k + 512] += x[:, :, 0] @ c1
            return out
        if len(z) < FEW_POINTS:             # a dense solve a point is cheaper than the Python loop below
            eye = np.eye(n)
            x = np.linalg.solve(z[:, None, None] * eye - self.A, np.broadcast_to(self.B, (len(z), n, 1)))
            return out + (self.C @ x)[:, 0, 0]
        if self._hessenberg is None:
            self._hessenberg = hessenberg_form(self.A, self.B, self.C)
        return out + hessenberg_response(*self._hessenberg, z)


def _cluster_split(A, B, C, lam, rtol: float = 1e-6):
    """``(T11, c1, b1, mu, w)``: ``C (zI - A)^-1 B = c1 (zI - T11)^-1 b1 + sum_i w_i / (z - mu_i)``,
    with ``T11`` the block of the repeated eigenvalues of ``A`` (within ``rtol``), or None.

    Ordered complex Schur form ``A = Z T Z^H`` with the repeated eigenvalues first, then
    ``X`` from ``T11 X - X T22 = -T12`` block-diagonalises ``T`` (``S = [[I, X], [0, I]]``), and
    ``T22`` (simple eigenvalues) is diagonalised. None when there is no such cluster or a step
    is ill conditioned (the caller then solves at every point).
    """
    import scipy.linalg
    n = len(lam)
    gap = np.abs(lam[:, None] - lam[None, :])
    np.fill_diagonal(gap, np.inf)
    repeated = lam[np.min(gap, axis=1) <= rtol * np.maximum(1.0, np.abs(lam))]
    if not 0 < repeated.size < n:
        return None
    T, Z, k = scipy.linalg.schur(A.astype(complex), output="complex",
                                 sort=lambda x: bool(np.any(np.abs(repeated - x) <= 10 * rtol * max(1.0, abs(x)))))
    if k != repeated.size:
        return None
    X = scipy.linalg.solve_sylvester(T[:k, :k], -T[k:, k:], -T[:k, k:])
    if not np.all(np.isfinite(X)) or np.linalg.norm(X) > 1e6:
        return None
    c = (C @ Z)[0]
    b = (Z.conj().T @ B)[:, 0]
    c2, b1 = c[k:] + c[:k] @ X, b[:k] - X @ b[k:]
    mu, W = np.linalg.eig(T[k:, k:])
    if np.linalg.cond(W) >= 1e6:
        return None
    return T[:k, :k], c[:k], b1, mu, (c2 @ W) * np.linalg.solve(W, b[k:])


def frequency_grid(poles_z, dt: float, n: int = 3000) -> np.ndarray:
    """Frequencies [rad/s] up to the Nyquist frequency, dense around every oscillatory pole.

    Parameters
    ----------
    poles_z : array_like of complex
        Poles (z-plane) whose resonances must be resolved.
    dt : float
        Sample time [s].
    n : int
        Points of the logarithmic background grid.

    Returns
    -------
    ndarray
        Sorted, unique, in ``(0, pi/dt]``.
    """
    nyq = math.pi / dt
    z = np.asarray(poles_z, dtype=complex)
    z = z[np.abs(z) > 1e-12]
    s = np.log(z) / dt
    wn = np.abs(s)
    w_lo = np.min(wn[wn > 1e-9 * nyq]) / 100.0 if np.any(wn > 1e-9 * nyq) else nyq * 1e-5
    parts = [np.geomspace(w_lo, nyq, n)]
    u = np.sinh(np.linspace(-math.asinh(40.0), math.asinh(40.0), 161))   # fine at the centre
    for si in s[(np.abs(s.imag) > 0) & (np.abs(s.imag) < nyq)]:
        w0 = abs(si.imag)
        width = max(abs(si.real), 1e-6 * w0)
        parts.append(w0 + width * u)
        parts.append(w0 * np.geomspace(0.9, 1.1, 81))
    w = np.concatenate(parts)
    return np.unique(w[(w >= w_lo) & (w <= nyq)])


def hessenberg_form(A, B, C) -> tuple:
    """``(H, b, c)`` with ``H = Q^T A Q`` upper Hessenberg, ``b = Q^T B``, ``c = C Q`` (``Q`` orthogonal).

    Parameters
    ----------
    A : ndarray (n, n)
    B : ndarray (n, 1)
    C : ndarray (1, n)

    Returns
    -------
    tuple of ndarray
        ``H`` (n, n), ``b`` (n,), ``c`` (n,): ``C (zI - A)^-1 B = c (zI - H)^-1 b``.
    """
    import scipy.linalg
    H, Q = scipy.linalg.hessenberg(np.asarray(A, dtype=float), calc_q=True)
    return H, (Q.T @ np.asarray(B, dtype=float))[:, 0], (np.asarray(C, dtype=float) @ Q)[0]


def hessenberg_response(H, b, c, z) -> np.ndarray:
    """``c (zI - H)^-1 b`` at the points ``z``, with ``H`` upper Hessenberg (:func:`hessenberg_form`).

    Gaussian elimination of each ``zI - H`` with partial pivoting, vectorised over the points: a
    Hessenberg column has one entry below the diagonal, so each step chooses between two rows
    and eliminates one entry (``O(n)``), and back substitution costs ``O(n^2)`` a point.

    Parameters
    ----------
    H : ndarray (n, n)
        Upper Hessenberg [-].
    b, c : ndarray (n,)
    z : array_like of complex
        Points of the z-plane [-] (flattened).

    Returns
    -------
    ndarray of complex
        The response at each point (inf or nan where ``z`` is an eigenvalue of ``H``).
    """
    z = np.atleast_1d(np.asarray(z, dtype=complex)).ravel()
    n = len(b)
    out = np.empty(z.shape, dtype=complex)
    chunk = int(max(8, min(512, 1_000_000 // max(1, n * n))))    # U holds chunk * n^2 numbers
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for k0 in range(0, len(z), chunk):
            zz = z[k0:k0 + chunk]
            m = len(zz)
            U = np.empty((n, m, n), dtype=complex)       # row k of the triangular factor (columns >= k), per point
            y = np.empty((n, m), dtype=complex)
            cur = np.broadcast_to(-H[0], (m, n)).astype(complex)
            cur[:, 0] += zz
            rc = np.full(m, b[0], dtype=complex)
            for k in range(n - 1):
                nxt = np.broadcast_to(-H[k + 1, k:], (m, n - k)).astype(complex)   # columns < k are zero
                nxt[:, 1] += zz
                cur = cur[:, -(n - k):]
                swap = np.abs(nxt[:, 0]) > np.abs(cur[:, 0])
                rn = np.full(m, b[k + 1], dtype=complex)
                if swap.any():
                    cur[swap], nxt[swap] = nxt[swap], cur[swap].copy()
                    rc[swap], rn[swap] = rn[swap], rc[swap].copy()
                U[k, :, k:], y[k] = cur, rc
                lk = nxt[:, 0] / cur[:, 0]
                nxt -= lk[:, None] * cur
                rn -= lk * rc
                cur, rc = nxt[:, 1:], rn
            U[n - 1, :, n - 1], y[n - 1] = cur[:, -1], rc
            x = np.zeros((m, n), dtype=complex)
            for k in range(n - 1, -1, -1):
                x[:, k] = (y[k] - np.einsum("pj,pj->p", U[k, :, k + 1:], x[:, k + 1:])) / U[k, :, k]
            out[k0:k0 + m] = x @ c
    return out
