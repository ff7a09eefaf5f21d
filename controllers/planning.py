"""Planned slews: a torque on the design model that leaves the beam at rest when the slew ends.

A rigid-body reference (:func:`controllers.slew_reference`) turns the hub in ``t_f`` but leaves
the beam ringing, so the feedback spends the time after the slew damping what the reference
excited. :func:`planned_slew_reference` plans the whole motion on the design model instead:
the sampled torque ``u_0 .. u_{N-1}`` (held over each sample, ``N = t_f / dt``; piecewise
linear between :data:`MAX_UNKNOWNS` knots when ``N`` is larger) that

* turns the hub by the slew angle and stops it (hard constraints on the design model at rest),
* leaves the beam's flexible modes that the sample rate resolves at rest at ``t_f``, on the
  design model at rest **and** on the design model linearised at the slew's peak rate
  (centrifugal stiffening raises the frequencies during a fast slew; planning on both makes
  the plan insensitive to it); a slew too short for both falls back to a heavily weighted
  least-squares term,
* is smooth (least squared second differences, starting and ending at zero torque), and
* stays within the torque budget at every sample.

That is one dense quadratic programme in ``N`` unknowns (at most :data:`MAX_UNKNOWNS`): one
linear solve when the budget is not active, else DAQP (milliseconds for a
few hundred samples, against seconds for the nonlinear :func:`hubbeam_ctrl.limit.min_vibration_slew`).
The reference carries the planned bending (:attr:`Reference.elastic`) so that the feedback
tracks the planned motion and only corrects model error.

Examples
--------
>>> from hubbeam_ctrl import Params
>>> lab = Params(L=1, rho=2700, A=9e-5, E=69e9, I=6.75e-11, J_h=0.02, r=0.05, m_t=0.05, tau_max=1.5)
>>> ref = planned_slew_reference(lab, 1.5708, 1.26, 1.5, 0.01, 3.0, n_modes=2)
>>> round(float(ref.theta[-1]), 4), float(abs(ref.torque).max()) <= 1.5
(1.5708, True)
"""

from __future__ import annotations

import math

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.validation import check_finite, check_positive
from hubbeam_ctrl.plant.params import Params

from .base import DesignModel, Reference

__all__ = ["planned_slew_reference", "replanned", "terminal_map"]

#: At most this many unknowns: a longer slew's torque is piecewise linear between this many
#: evenly spaced knots (sampled and held at every sample), so that a slow task at a fast
#: sample rate (4 s at 1 ms) stays a problem of milliseconds instead of a dense one in
#: thousands of unknowns.
MAX_UNKNOWNS = 600
#: Largest violation of the plan's equality rows [dimensionless: the angle's row is 1, each
#: mode's row the motion the rigid plan gives it] accepted from the equality-constrained
#: minimiser before the bounded solver is asked.
ROW_TOLERANCE = 1e-7
#: Weight of the beam's terminal motion against the torque's smoothness, both normalised (see
#: :func:`planned_slew_reference`): large enough that the plan leaves the beam at rest
#: whenever the torque budget allows it.
ELASTIC_WEIGHT = 1e6
#: The plan brings to rest the flexible modes below this fraction of the sampling frequency
#: (a quarter: at least four held torques per period); faster modes are left to the torque's
#: smoothness.
RESOLVED_FRACTION = 0.25
#: Largest planned ``|v_tip|`` relative to L (the models' validated range, as the time-optimal slew's
#: :attr:`~hubbeam_ctrl.limit.slew.SlewSettings.deflection_limit`): the smoothest plan on a light link
#: swings the hub ahead of its beam, which the linear design model follows to any deflection (issue 36:
#: ``servo_payload`` at 1.05 T* planned 0.58 L, where FOAM's mass matrix is singular) [-].
DEFLECTION_LIMIT = 0.3


def terminal_map(design: DesignModel, n_samples: int) -> np.ndarray:
    """The state after ``n_samples`` held torques from rest: ``x_N = G u`` (``G``: n_x x N).

    Parameters
    ----------
    design : DesignModel
        Sampled linear model (``Ad``, ``Bd``).
    n_samples : int
        Number of samples ``N`` (> 0).

    Returns
    -------
    ndarray (n_x, N)
        Column ``k`` is ``Ad^(N-1-k) Bd`` [state units per N m].
    """
    A, v = design.Ad, np.asarray(design.Bd, dtype=float).ravel().copy()
    G = np.empty((A.shape[0], n_samples))
    for k in range(n_samples - 1, -1, -1):
        G[:, k] = v
        v = A @ v
    return G


def _modal_rows(design: DesignModel, f_max_hz: float) -> np.ndarray:
    """Rows ``W`` (2 per flexible mode below ``f_max_hz``) with ``W x = 0`` iff those modes rest.

    Real and imaginary parts of the left eigenvectors of ``design.A`` of its oscillatory
    eigenvalues with ``|lambda| < 2 pi f_max_hz``; the rigid body's (defective) pair at zero is
    left out, so the rows do not see the hub angle.
    """
    lam, W = np.linalg.eig(np.asarray(design.A, dtype=float).T)
    scale = max(1.0, float(np.max(np.abs(lam))))
    keep = (lam.imag > 1e-9 * scale) & (np.abs(lam) < 2 * np.pi * f_max_hz)
    W = W[:, keep].T
    return np.vstack([W.real, W.imag])


def _trajectory(design: DesignModel, u: np.ndarray) -> np.ndarray:
    """States ``x_0 .. x_N`` (N+1, n_x) of ``design`` from rest under the held torques ``u``."""
    A, B = design.Ad, np.asarray(design.Bd, dtype=float).ravel()
    X = np.zeros((len(u) + 1, A.shape[0]))
    for k, uk in enumerate(u):
        X[k + 1] = A @ X[k] + B * uk
    return X


def _second_differences(P: np.ndarray) -> np.ndarray:
    """Second differences ``D P`` of the sampled torque ``P v``, padded with zero torque before and
    after ((n+2) x m for ``P`` n x m)."""
    zeros = np.zeros((2, P.shape[1]))
    return np.diff(np.vstack([zeros, P, zeros]), 2, axis=0)


def _knots(n: int, m: int) -> np.ndarray:
    """Linear interpolation (n x m) from ``m`` evenly spaced knots onto ``n`` samples (ends on ends);
    the identity for ``m == n``."""
    pos = np.linspace(0.0, m - 1.0, n)
    lo = np.minimum(np.floor(pos).astype(int), m - 2)
    frac = pos - lo
    P = np.zeros((n, m))
    P[np.arange(n), lo] = 1.0 - frac
    P[np.arange(n), lo + 1] = frac
    return P


def _within_deflection(design: DesignModel, U: np.ndarray, v: np.ndarray, H, rows, rhs, limit: float) -> tuple:
    """The plan ``v`` (torques ``U v``) with its tip on ``design`` kept within ``limit`` [m].

    ``(v, note)``: ``v`` itself when its planned ``|v_tip|`` stays within ``limit`` (note ""),
    else ``min 1/2 v' H v`` on the same equality ``rows = rhs`` and ``|v| <= 1`` with
    ``|v_tip| <= limit`` at every sample (DAQP); when that has no solution, ``v`` with a note
    saying how far its tip goes.
    """
    c = np.asarray(design.C_tip, dtype=float)[0]
    tip = _trajectory(design, U @ v)[1:] @ c
    peak = float(np.max(np.abs(tip)))
    if peak <= limit:
        return v, ""
    A, B = design.Ad, np.asarray(design.Bd, dtype=float).ravel()
    X, T = np.zeros((A.shape[0], U.shape[1])), np.empty_like(U)
    for k in range(U.shape[0]):                 # the tip at sample k + 1 of each unknown's torque
        X = A @ X + np.outer(B, U[k])
        T[k] = c @ X
    from .mpc import DirectDAQP  # the QP solver the MPC uses

    n = len(v)
    qp = DirectDAQP(H, np.vstack([rows, T / limit]), -np.ones(n), np.ones(n))
    try:
        bounded = qp.solve(np.zeros(n), lba=np.concatenate([rhs, -np.ones(len(T))]),
                           uba=np.concatenate([rhs, np.ones(len(T))]))
    except RuntimeError:
        bounded = None
    if bounded is None or not np.allclose(rows @ bounded, rhs, rtol=0, atol=ROW_TOLERANCE):
        return v, f"; its tip reaches {peak:.3g} m, past the deflection limit {limit:.3g} m, which no plan keeps"
    return bounded, f"; tip within {limit:.3g} m (the smoothest plan reached {peak:.3g} m)"


def _solve(H, rows, rhs, bound: float):
    """``min 1/2 v' H v  s.t.  rows v = rhs, |v| <= bound``, or None if infeasible.

    The equality-constrained minimiser (one KKT solve) when it is within the bound, else DAQP.
    """
    n, m = H.shape[0], len(rhs)
    kkt = np.block([[H, rows.T], [rows, np.zeros((m, m))]])
    b = np.concatenate([np.zeros(n), rhs])
    try:
        z = np.linalg.solve(kkt, b)
        if np.all(np.isfinite(z)) and not np.allclose(rows @ z[:n], rhs, rtol=0, atol=1e-9):
            z = z + np.linalg.solve(kkt, b - kkt @ z)          # one step of iterative refinement
        v = z[:n]
    except np.linalg.LinAlgError:
        v = None
    if v is not None and np.all(np.isfinite(v)) and np.allclose(rows @ v, rhs, rtol=0, atol=ROW_TOLERANCE):
        if np.max(np.abs(v)) <= bound:
            return v
    from .mpc import DirectDAQP  # the QP solver the MPC uses

    qp = DirectDAQP(H, rows, np.full(n, -bound), np.full(n, bound))
    try:
        return qp.solve(np.zeros(n), lba=rhs, uba=rhs)
    except RuntimeError:
        return None


def planned_slew_reference(params: Params, angle: float, duration: float, tau_max: float, dt: float,
                           t_end: float, n_modes: int | None = None,
                           deflection_limit: float | None = DEFLECTION_LIMIT) -> Reference:
    """Rest-to-rest slew planned on the design model: reference, feedforward and planned bending.

    Parameters
    ----------
    params : Params
        The design's beam (its ``max_spin`` bounds the stiffened model's spin).
    angle : float
        Slew angle [rad], finite and not 0.
    duration : float
        Slew time ``t_f`` [s], at least 4 samples.
    tau_max : float
        Torque budget [N m], > 0.
    dt : float
        Controller sample time [s], > 0.
    t_end : float
        Last sample of the reference [s], >= ``duration``; after the slew the reference rests
        at the slew angle with zero torque.
    n_modes : int, optional
        Bending modes of the design model (default ``params.n_transverse``).
    deflection_limit : float or None
        Largest planned ``|v_tip|`` on the design model at rest, relative to L, > 0 (default
        :data:`DEFLECTION_LIMIT`, the models' validated range; None: unbounded). Kept when a plan
        within the budget can keep it; else the smoothest plan, and its description says how far
        its tip goes.

    Returns
    -------
    Reference
        Hub angle and rate [rad, rad/s] of the design model at rest, the planned torque as
        feedforward [N m] and the planned modal coordinates and rates as
        :attr:`Reference.elastic`.

    Raises
    ------
    ParameterError
        If the torque budget cannot turn the hub by ``angle`` in ``duration`` (message names
        ``tf``), or an argument is out of range.

    Notes
    -----
    The unknowns are the held torques over ``tau_max``. With ``G_m`` the terminal map of model
    ``m`` (:func:`terminal_map`), ``W_m`` the left eigenvectors of its flexible modes below
    :data:`RESOLVED_FRACTION` of the sampling frequency, each scaled by that mode's largest
    motion along ``u_r`` (the smoothest rigid-only plan), and ``D`` the torque's second
    differences, the plan is ``min |D u|^2`` subject to ``theta_N = angle``,
    ``theta_dot_N = 0`` on the model at rest, ``W_m G_m u = 0`` on both models (the model at
    rest and the one linearised at ``u_r``'s peak hub rate, within ``params.max_spin``), and
    ``|u_k| <= tau_max``, and ``|c_tip x_k| <= deflection_limit L`` at every sample when the plan
    without that bound passes it (its rows join the QP; a plan within it is left as it is). If
    the budget cannot bring both models to rest, the stiffened model's rows, then also the rest
    model's, move into the objective with weight
    :data:`ELASTIC_WEIGHT`; the reference's description says which.
    """
    if not isinstance(params, Params):
        raise ParameterError(f"params must be a Params, got {type(params).__name__}")
    angle = check_finite("angle", angle, "rad")
    if angle == 0.0:
        raise ParameterError("angle must be a finite number != 0 [rad], got 0")
    dt = check_positive("dt", dt, "s")
    duration = check_positive("duration", duration, "s")
    tau_max = check_positive("tau_max", tau_max, "N m")
    n = int(round(duration / dt))
    if n < 4:
        raise ParameterError(f"duration must span at least 4 samples of dt = {dt:g} s, got {duration:g} s")
    if not (isinstance(t_end, (int, float)) and math.isfinite(t_end) and t_end >= n * dt - 1e-12):
        raise ParameterError(f"t_end must be >= the slew's duration {n * dt:g} s, got {t_end!r}")
    rest = DesignModel.build(params, 0.0, dt, n_modes)
    half = rest.n_x // 2
    rigid, elastic = np.array([0, half]), np.r_[1:half, half + 1:rest.n_x]
    # dimensionless unknowns v = u / tau_max and rows: angle / |angle|, rate * t_f / |angle|
    row_scale = np.array([1.0, n * dt]) / abs(angle)
    target = np.array([np.sign(angle), 0.0])
    n_unknowns = min(n, MAX_UNKNOWNS)
    P = _knots(n, n_unknowns)                               # torque u = tau_max P v
    D = _second_differences(P)
    smoothness = D.T @ D
    G0 = terminal_map(rest, n) * tau_max
    A_rigid = row_scale[:, None] * (G0[rigid] @ P)
    v_rigid = _solve(smoothness + 1e-12 * np.eye(n_unknowns), A_rigid, target, 1.0)
    if v_rigid is None:
        raise ParameterError(f"tau_max = {tau_max:g} N m cannot turn the hub by {angle:g} rad in "
                             f"duration = {n * dt:g} s; give a longer duration (tf / --tf)")
    X_rigid = _trajectory(rest, tau_max * (P @ v_rigid))
    f_max = RESOLVED_FRACTION / dt
    spin = float(np.max(np.abs(X_rigid[:, half])))
    models = [(rest, G0)]
    if 1e-9 < spin <= params.max_spin:
        spun = DesignModel.build(params, spin, dt, n_modes)
        models.append((spun, terminal_map(spun, n) * tau_max))
    stiff = []
    for model, G in models:
        W = _modal_rows(model, f_max)
        size = np.max(np.abs(X_rigid @ W.T), axis=0)        # each mode's motion along the rigid plan
        keep = size > 1e-12 * max(float(size.max(initial=0.0)), 1e-300)
        stiff.append((W[keep] / size[keep, None]) @ G @ P)
    v, how = None, ""
    for hard in range(len(stiff), -1, -1):    # every model at rest exactly, then fewer, then none
        rows = np.vstack([A_rigid, *stiff[:hard]])
        H = smoothness / (float(np.sum((D @ v_rigid) ** 2)) or 1.0)
        for E in stiff[hard:]:
            H = H + ELASTIC_WEIGHT * (E.T @ E)
        v = _solve(H + 1e-12 * np.eye(n_unknowns), rows, np.concatenate([target, np.zeros(len(rows) - 2)]), 1.0)
        if v is not None:
            how = ("the beam at rest on both models" if hard == len(stiff) == 2 else
                   "the beam at rest" if hard == len(stiff) else
                   f"the beam at rest on {hard} of {len(stiff)} models, nearly on the rest")
            break
    if v is None:
        v = v_rigid
        how = "the rigid body only: the budget leaves no room for the beam"
    elif deflection_limit is not None:
        limit = check_positive("deflection_limit", deflection_limit, "of L") * params.L
        rhs = np.concatenate([target, np.zeros(len(rows) - 2)])
        v, note = _within_deflection(rest, tau_max * P, v, H + 1e-12 * np.eye(n_unknowns), rows, rhs, limit)
        how += note
    u = tau_max * (P @ v)
    X = _trajectory(rest, u)
    k_end = int(round(t_end / dt)) + 1
    theta = np.full(k_end, X[-1, 0])
    rate, torque = np.zeros(k_end), np.zeros(k_end)
    modal = np.zeros((k_end, 2 * (half - 1)))
    m = min(n + 1, k_end)
    theta[:m], rate[:m], modal[:m] = X[:m, 0], X[:m, half], X[:m][:, elastic]
    torque[:min(n, k_end)] = u[:k_end]
    accel = np.zeros(k_end)
    accel[:m - 1] = np.diff(rate[:m]) / dt                  # mean acceleration over each sample
    text = (f"slew {angle:.4g} rad in {n * dt:.4g} s planned on the design model at rest and at "
            f"{spin:.3g} rad/s ({how}; peak torque {np.max(np.abs(u)):.4g} N m)")
    return Reference(dt, theta, rate, accel, torque, text, elastic=modal, planned_on_design=True,
                     plan=(angle, n * dt, tau_max, n_modes))


def replanned(reference: Reference, params: Params) -> Reference:
    """The task of a planned reference (:attr:`Reference.plan`) planned again on ``params``.

    Parameters
    ----------
    reference : Reference
        A reference of :func:`planned_slew_reference`.
    params : Params
        The beam to plan on (e.g. another payload).

    Returns
    -------
    Reference
        Over the same samples as ``reference``.
    """
    if reference.plan is None:
        raise ParameterError("reference: not a plan on the design model (no Reference.plan to plan again)")
    angle, duration, tau_max, n_modes = reference.plan
    return planned_slew_reference(params, angle, duration, tau_max, reference.dt,
                                  (len(reference.theta) - 1) * reference.dt, n_modes)
