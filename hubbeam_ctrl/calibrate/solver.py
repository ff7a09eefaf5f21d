"""The least-squares machinery of the fits: bounds, scales, the optimiser with its wall-time
limit and progress bar, and the diagnostics of the Jacobian (intervals, correlations,
identifiability). Used by :mod:`hubbeam_ctrl.calibrate.fit` and :mod:`hubbeam_ctrl.calibrate.table`.
"""

from __future__ import annotations

import math
import time

import numpy as np

from hubbeam_ctrl.calibrate.intervals import Z95
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.progress import progress_bar

__all__: list = []   # private machinery: fit.py re-exports IDENTIFIABILITY_CONDITION

#: Condition number of the column-scaled Jacobian above which the fit warns that its
#: parameters are not separately identifiable.
IDENTIFIABILITY_CONDITION = 1e4


def check_bounds(fit_fields, bounds, option: str = "--bounds") -> tuple:
    """The search bounds of the fitted fields: each field's range, narrowed by ``bounds``.

    Parameters
    ----------
    fit_fields : sequence of FitField
        The fitted fields (:func:`~hubbeam_ctrl.calibrate.fit.resolve_fields`).
    bounds : dict or None
        Field name (or path) -> ``(lo, hi)`` in the field's unit; each within the field's range.
    option : str
        The bounds' name as the caller spelled it (starts the messages).

    Returns
    -------
    lo, hi : ndarray

    Raises
    ------
    ParameterError
        A name that is not fitted, bounds that are not finite, reversed, or outside the
        field's range (refused, not clipped).
    """
    lo = np.array([f.lo for f in fit_fields])
    hi = np.array([f.hi for f in fit_fields])
    for name, pair in (bounds or {}).items():
        k = next((i for i, f in enumerate(fit_fields) if name in (f.name, f.path)), None)
        if k is None:
            raise ParameterError(f"{option}: {name!r} is not a fitted field ({', '.join(f.name for f in fit_fields)})")
        a, b = (float(v) for v in pair)
        if not (math.isfinite(a) and math.isfinite(b)):
            raise ParameterError(f"{option}: {name} bounds must be finite, got {a:g}:{b:g}")
        if a > b:
            raise ParameterError(f"{option}: {name} has lo = {a:g} > hi = {b:g}")
        f = fit_fields[k]
        if a < f.lo or b > f.hi:        # refused, not clipped: the fit would not search what was asked
            raise ParameterError(f"{option}: {name} bounds {a:g}:{b:g} must lie within its range "
                                 f"[{f.lo:g}, {f.hi:g}] [{f.unit}]")
        lo[k], hi[k] = a, b
    return lo, hi


def _bounds(fit_fields, bounds, start, option="--bounds"):
    lo, hi = check_bounds(fit_fields, bounds, option)
    for k, f in enumerate(fit_fields):
        if not lo[k] <= start[k] <= hi[k]:
            raise ParameterError(f"{option}: the start of {f.name} ({start[k]:g}) is outside its bounds "
                                 f"[{lo[k]:g}, {hi[k]:g}]")
    return lo, hi


def _scales(fit_fields, start, rig) -> np.ndarray:
    out = []
    for f, s in zip(fit_fields, start):
        if s != 0.0:
            out.append(abs(s))
        elif f.table == "friction":
            stall = rig.drive.stall_torque if not rig.drive.is_ideal else rig.beam.tau_max
            out.append(0.01 * stall)
        elif f.key == "ratios":
            out.append(0.01)
        else:
            out.append(1.0)
    return np.array(out)


def _diagnose(J, scale, estimate, residual, fit_fields, interval=None) -> tuple:
    """Standard deviations, correlations and identifiability warnings from the Jacobian.

    With ``interval`` (an :class:`~hubbeam_ctrl.calibrate.intervals.IntervalEstimate` in the
    scaled variables) the standard deviations are its 95 % half-widths / 1.96 and the
    correlations its covariance's; the identifiability warnings stay the Jacobian's.
    """
    m, p = J.shape
    warnings = []
    norms = np.linalg.norm(J, axis=0)
    dead = norms <= 1e-12 * max(1.0, norms.max())
    for k in np.nonzero(dead)[0]:
        warnings.append(f"{fit_fields[k].name} is not identifiable from these records: it does not change "
                        "the simulated sensors")
    s2 = float(residual @ residual) / max(m - p, 1)
    Jn = J[:, ~dead] / norms[~dead]
    std = np.full(p, np.inf)
    corr = np.full((p, p), np.nan)
    if Jn.shape[1]:
        u, sv, vt = np.linalg.svd(Jn, full_matrices=False)
        cond = sv[0] / max(sv[-1], 1e-300)
        cov_n = (vt.T / np.maximum(sv, 1e-300) ** 2) @ vt * s2
        idx = np.nonzero(~dead)[0]
        d = np.sqrt(np.diag(cov_n))
        std[idx] = d / norms[~dead] * scale[idx]
        corr[np.ix_(idx, idx)] = cov_n / np.outer(d, d)
        if interval is not None:
            std[idx] = interval.half_width[idx] / Z95 * scale[idx]
            sd = np.sqrt(np.diag(interval.covariance))[idx]
            with np.errstate(invalid="ignore", divide="ignore"):
                corr[np.ix_(idx, idx)] = interval.covariance[np.ix_(idx, idx)] / np.outer(sd, sd)
        if cond > IDENTIFIABILITY_CONDITION:
            weak = vt[-1]
            who = [fit_fields[idx[k]].name for k in np.argsort(-np.abs(weak)) if abs(weak[k]) > 0.3]
            warnings.append(f"{', '.join(who)} are not separately identifiable from these records (condition "
                            f"number {cond:.3g} of the scaled Jacobian): only a combination is determined")
    for k, f in enumerate(fit_fields):
        if not dead[k] and estimate[k] != 0 and 1.96 * std[k] > 0.5 * abs(estimate[k]):
            warnings.append(f"{f.name} is poorly determined: its 95 % interval (+-{1.96 * std[k]:.3g}) is wider "
                            f"than half its value")
    return std, corr, warnings


class _WallStop(Exception):
    """The fit's wall-time limit passed."""


def _least_squares(residual_of, x0, lo, hi, n_params, settings, label, enabled, deadline=math.inf):
    """SciPy's trf on a residual function with a forward-difference Jacobian and a progress bar.

    Past ``deadline`` (a :func:`time.perf_counter` time) it stops and returns the best point
    evaluated, with ``status`` -2 and the last Jacobian.
    """
    from types import SimpleNamespace

    from scipy.optimize import least_squares

    cache = {}
    best = {"cost": math.inf, "x": None, "fun": None, "jac": None, "nfev": 0}
    budget = settings.max_evaluations * (n_params + 1)
    bar = progress_bar(budget, label, enabled=enabled)

    def evaluate(x):
        if time.perf_counter() > deadline:
            raise _WallStop
        return residual_of(x)

    def fun(x):
        key = x.tobytes()
        if key not in cache:
            cache.clear()
            cache[key] = evaluate(x)
            best["nfev"] += 1
            cost = 0.5 * float(cache[key] @ cache[key])
            if cost < best["cost"]:
                best.update(cost=cost, x=x.copy(), fun=cache[key])
            bar.update(1)
        return cache[key]

    def jac(x):
        r0 = fun(x)
        J = np.empty((r0.size, x.size))
        for k in range(x.size):
            h = settings.difference_step * max(abs(x[k]), 1e-3)
            xk = x.copy()
            xk[k] = x[k] + h if x[k] + h <= hi[k] else x[k] - h
            if settings.central and x[k] - h >= lo[k] and x[k] + h <= hi[k]:
                xm = x.copy()
                xm[k] = x[k] - h
                J[:, k] = (evaluate(xk) - evaluate(xm)) / (2 * h)
                bar.update(2)
                continue
            J[:, k] = (evaluate(xk) - r0) / (xk[k] - x[k])
            bar.update(1)
        best["jac"] = J
        return J

    x0 = np.clip(x0, lo, hi)
    tol = settings.tolerance
    try:
        return least_squares(fun, x0, jac=jac, bounds=(lo, hi), method="trf", x_scale="jac",
                             max_nfev=settings.max_evaluations, ftol=tol, xtol=tol, gtol=tol)
    except _WallStop:
        if best["x"] is None:
            best.update(x=x0, fun=None)
        J = best["jac"] if best["jac"] is not None else np.zeros((0 if best["fun"] is None else best["fun"].size,
                                                                   x0.size))
        return SimpleNamespace(x=best["x"], fun=best["fun"], jac=J, cost=best["cost"], status=-2,
                               nfev=best["nfev"], message="stopped at --max-wall")
    finally:
        bar.close()
