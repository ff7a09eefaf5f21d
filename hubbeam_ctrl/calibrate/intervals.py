"""Confidence intervals of a least-squares fit whose cost may be rough (issue 38, item 4).

Why the Jacobian's intervals did not cover (measured, ``docs/calibration.md``): on records
of a rig with Coulomb friction the simulated sensors are not smooth in the parameters. The
hardware's Karnopp sticking decides at each sample whether the hub sticks, so a change of
1e-5 in E moves a sticking episode and the cost jumps (the servo link's 2 s chirp and PRBS:
+13 % of the cost for E -1e-5 relative). The optimiser then stops on its step tolerance in a
notch of this staircase, up to 1.6 % off in m_t with a cost 38 % above the truth's, and the
forward-difference Jacobian (step 1e-4) spans a jump, so ``s^2 (J' J)^-1`` gives a standard
deviation of 0.01 %: the truth lay 12-900 of them away. Without Coulomb friction the same fit
reaches the minimum and the Jacobian's intervals cover (39, 40 and 39 of 40 records for E,
J_h, m_t); the residuals' autocorrelation (the encoder's rounding: 0.05-0.16 at lag 1) is
not what breaks them.

:func:`rough_intervals` therefore measures the cost at the scale of the intervals instead of
at the difference step: a Jacobian regressed over points spread by twice the current
half-widths along each field, the cost's roughness (how far it departs from the quadratic
models of that Jacobian and of the local slope at 1 and 10 difference steps, the smaller of
the two) and the smoothed minimum; the half-widths become the distance at which the
smoothed cost rises by the noise's 95 % quantile plus the roughness (a jump the optimiser
may have stopped against), plus the distance to the smoothed minimum; repeated until the
scale is consistent. On a smooth cost it gives about
the Jacobian's intervals (with a sandwich covariance that gives each record's sensor its own
residual variance and autocorrelation). Measured by ``benchmarks/bench_interval_coverage.py``.

Not covered: a wrong local minimum far from the truth (a different basin, not a notch), and
a model whose structure is wrong (a plant with fewer modes than the records' biases the
estimate smoothly).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError

__all__ = ["IntervalEstimate", "sandwich_covariance", "rough_intervals"]

#: Two-sided 95 % quantile of the standard normal.
Z95 = 1.959963984540054
#: The roughness probes are at 1 and this many difference steps.
JUMP_STEPS = 10.0


@dataclass(frozen=True)
class IntervalEstimate:
    """What :func:`rough_intervals` found, in the fit's scaled variables (value / scale).

    Attributes
    ----------
    half_width : ndarray (p,)
        95 % half-widths [scaled].
    std : ndarray (p,)
        The noise's part alone (sandwich covariance) [scaled].
    covariance : ndarray (p, p)
        The sandwich covariance with the regressed Jacobian [scaled^2].
    roughness : float
        The largest departure of the cost from its quadratic model at the probe points [cost].
    noise_cost : float
        The cost of the noise's 95 % quantile, ``Z95^2 s^2 / 2`` [cost].
    shift : ndarray (p,)
        Smoothed minimum minus the estimate [scaled].
    evaluations : int
        Residual evaluations spent.
    """

    half_width: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    roughness: float
    noise_cost: float
    shift: np.ndarray
    evaluations: int

    def summary(self, scale) -> dict:
        """JSON-ready: ``method`` ``"rough"``, ``roughness``, ``noise_cost``, ``evaluations``, and in
        each field's unit the noise's part of the half-widths ``noise_half_width`` and ``shift``.

        Parameters
        ----------
        scale : ndarray (p,)
            Each field's unit per scaled variable.
        """
        scale = np.asarray(scale, dtype=float)
        return {"method": "rough", "roughness": self.roughness, "noise_cost": self.noise_cost,
                "evaluations": self.evaluations, "noise_half_width": (Z95 * self.std * scale).tolist(),
                "shift": (self.shift * scale).tolist()}

    def warnings(self) -> list:
        """One warning when the cost is rougher than the noise's 95 % level, else none."""
        if not self.roughness > self.noise_cost:
            return []
        return [f"the cost is rough at the estimate (it departs from its quadratic model by "
                f"{self.roughness / self.noise_cost:.3g} times the noise's 95 % level: e.g. stick-slip friction's "
                "sticking switching with the values); the intervals are widened to the scale where the cost's "
                "trend stands above its jumps"]


def _lags(r) -> int:
    """Bartlett window's lag for a segment's residual ``r``: Andrews' AR(1) plug-in rule
    ``1.1447 (alpha n)^(1/3)``, ``alpha = 4 rho^2 / ((1 - rho)^2 (1 + rho)^2)`` with ``rho`` the
    residual's lag-1 autocorrelation, at least Newey-West's ``4 (n / 100)^(2/9)`` and at most ``n / 4``."""
    n = len(r)
    den = float(r @ r)
    rho = min(max(float(r[1:] @ r[:-1]) / den, 0.0), 0.97) if den > 0 and n > 2 else 0.0
    alpha = 4.0 * rho ** 2 / ((1.0 - rho) ** 2 * (1.0 + rho) ** 2)
    lag = max(1.1447 * (alpha * n) ** (1.0 / 3.0), 4.0 * (n / 100.0) ** (2.0 / 9.0))
    return int(min(math.floor(lag), n // 4))


def sandwich_covariance(J, residual, segments) -> np.ndarray:
    """Heteroscedasticity- and autocorrelation-consistent covariance of a least-squares estimate.

    ``A^-1 S A^-1 m / (m - p)`` with ``A = J' J`` and ``S`` the sum over the segments (one
    record's sensor each) of the Bartlett-weighted autocovariances of the scores
    ``J_t r_t`` up to the lag of Andrews' AR(1) rule on the segment's residual (at least
    Newey-West's; :func:`_lags`).

    Assumes the residual at the estimate is the noise: zero mean, stationary within each
    segment, independent between segments, its autocorrelation close to an AR(1)'s (the lag's rule);
    and the model linear in the parameters over the interval (``J`` the residual's slope there).

    Parameters
    ----------
    J : ndarray (m, p)
        Jacobian of the residual [residual unit per parameter unit].
    residual : ndarray (m,)
    segments : sequence of int
        Lengths of the consecutive segments of ``residual`` (sum ``m``).

    Returns
    -------
    ndarray (p, p)
        [parameter unit^2] (a pseudo-inverse: a direction ``J`` does not see gets 0).
    """
    J = np.asarray(J, dtype=float)
    r = np.asarray(residual, dtype=float)
    m, p = J.shape
    A_inv = np.linalg.pinv(J.T @ J)
    S = np.zeros((p, p))
    start = 0
    for n in segments:
        g = J[start:start + n] * r[start:start + n, None]
        start += n
        S += g.T @ g
        window = _lags(r[start - n:start])
        for lag in range(1, window + 1):
            gam = g[lag:].T @ g[:-lag]
            S += (1.0 - lag / (window + 1.0)) * (gam + gam.T)
    return A_inv @ S @ A_inv * (m / max(m - p, 1))


def rough_intervals(residual_of, x, residual, J, segments, lo, hi, *, step: float = 1e-4, iterations: int = 4,
                    tolerance: float = 0.3) -> IntervalEstimate:
    """95 % intervals of a least-squares estimate that hold when the cost is rough (module docstring).

    From half-widths ``w`` (first the sandwich's with ``J``), each iteration evaluates the
    residual at ``x +- 2 w_k`` and ``x +- w_k`` along each parameter, regresses the
    Jacobian ``G`` on them (the slope through ``x``; probes at twice the interval keep a jump
    from passing for a steep slope), and sets

    ``w_k = max(sqrt(Z95^2 C_kk + 2 R (G'G)^-1_kk) + |shift_k|, w0_k)``

    (``w0`` the first, the noise's alone)
    with ``C`` the :func:`sandwich_covariance` with ``G``, ``R`` the roughness (at ``d`` = +-1
    and +-:data:`JUMP_STEPS` difference steps along each parameter, the smaller departure of
    the cost ``||r||^2 / 2`` from ``||r_0 + L d||^2 / 2`` and from ``||r_0 + G d||^2 / 2``,
    ``L`` the local slope by central differences over one step; the largest over the probes:
    what neither the local slope of a smooth response nor the trend explains is the cost's
    jumps) and
    ``shift = -(G'G)^-1 G' r_0`` the smoothed minimum; until no half-width changes by more than
    ``tolerance`` (relative) or ``iterations`` are spent.

    Assumes: the residual at the smoothed minimum is the noise (as for
    :func:`sandwich_covariance`); the optimiser stopped where the smoothed cost is at most the
    roughness above its minimum (a jump of the cost, e.g. stick-slip sticking, held it there);
    the residual is close to linear in the parameters over the interval (the probes are at the
    interval's scale, so a curved response widens the interval rather than narrowing it).
    Not covered: an estimate in another basin of the cost (a wrong local minimum, not a notch),
    a model whose structure is wrong.

    Parameters
    ----------
    residual_of : callable
        Scaled parameters (p,) -> residual (m,).
    x : ndarray (p,)
        The estimate [scaled].
    residual : ndarray (m,)
        ``residual_of(x)``.
    J : ndarray (m, p)
        The optimiser's Jacobian at ``x`` (the first scale).
    segments : sequence of int
        Lengths of the residual's segments (one record's sensor each).
    lo, hi : ndarray (p,)
        Bounds [scaled]: the probes stay within them.
    step : float
        The relative difference step of the roughness probes (the optimiser's) [-].
    iterations : int
        Most rounds of probes at the intervals' scale (``4 p`` evaluations each; ``4 p`` more
        for the roughness).
    tolerance : float
        Relative change of every half-width that ends them.

    Returns
    -------
    IntervalEstimate

    Raises
    ------
    ParameterError
        ``iterations`` not in 1..100, ``tolerance`` or ``step`` not in (0, 1].
    """
    if isinstance(iterations, bool) or not isinstance(iterations, int) or not 1 <= iterations <= 100:
        raise ParameterError(f"iterations must be an integer in 1..100, got {iterations!r}")
    for name, v in (("tolerance", tolerance), ("step", step)):
        if not isinstance(v, (int, float)) or not 0 < v <= 1:
            raise ParameterError(f"{name} must be in (0, 1], got {v!r}")
    x = np.asarray(x, dtype=float)
    r0 = np.asarray(residual, dtype=float)
    m, p = J.shape
    c0 = 0.5 * float(r0 @ r0)
    s2 = 2.0 * c0 / max(m - p, 1)
    noise_cost = 0.5 * Z95 ** 2 * s2
    cov = sandwich_covariance(J, r0, segments)
    w = Z95 * np.sqrt(np.maximum(np.diag(cov), 0.0))
    w = np.where(np.isfinite(w) & (w > 0), w, 1e-3 * np.maximum(np.abs(x), 1.0))
    w_first = w.copy()
    evaluations = 0

    def probe(k, d):
        nonlocal evaluations
        if not lo[k] <= x[k] + d <= hi[k]:
            return None
        xk = x.copy()
        xk[k] += d
        evaluations += 1
        return residual_of(xk)

    # the jumps: the cost at 1 and JUMP_STEPS difference steps, changes too small for the trend of a cost that
    # is rough at the interval's scale (a smooth cost's curvature there widens the interval: conservative)
    h = step * np.maximum(np.abs(x), 1e-3)
    jumps = [(k, d, probe(k, d)) for k in range(p) for d in (h[k], -h[k], JUMP_STEPS * h[k], -JUMP_STEPS * h[k])]
    jumps = [(k, d, rk) for k, d, rk in jumps if rk is not None]
    # the local slope (central differences over +-h): a cost smooth at the probes' scale follows it
    local = J.copy()
    for k in range(p):
        pair = [(d, rk) for kk, d, rk in jumps if kk == k and abs(d) <= 1.5 * h[k]]
        if pair:
            steps = np.array([d for d, _ in pair])
            local[:, k] = np.array([rk - r0 for _, rk in pair]).T @ steps / float(steps @ steps)

    def departure(slope, k, d, rk):
        return abs(0.5 * float(rk @ rk) - 0.5 * float(np.sum((r0 + slope[:, k] * d) ** 2)))
    G, shift = J, np.zeros(p)
    for _ in range(iterations):
        G = J.copy()
        for k in range(p):
            wide = [(d, rk) for d, rk in ((d, probe(k, d)) for d in (f * w[k] for f in (2.0, -2.0, 1.0, -1.0)))
                    if rk is not None]
            if wide:
                steps = np.array([d for d, _ in wide])
                G[:, k] = np.array([rk - r0 for _, rk in wide]).T @ steps / float(steps @ steps)
        A_inv = np.linalg.pinv(G.T @ G)
        # roughness: what neither the local slope nor the trend at the interval's scale explains
        rough = max((min(departure(local, k, d, rk), departure(G, k, d, rk)) for k, d, rk in jumps), default=0.0)
        shift = -A_inv @ (G.T @ r0)
        cov = sandwich_covariance(G, r0, segments)
        new = np.sqrt(Z95 ** 2 * np.maximum(np.diag(cov), 0.0) + 2.0 * rough * np.maximum(np.diag(A_inv), 0.0))
        new = np.maximum(new + np.abs(shift), w_first)        # never below the noise's own
        done = np.all(np.abs(new - w) <= tolerance * w)
        w = new
        if done:
            break
    std = np.sqrt(np.maximum(np.diag(cov), 0.0))
    return IntervalEstimate(w, std, cov, rough, noise_cost, shift, evaluations)
