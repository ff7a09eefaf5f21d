"""The slew as a nonlinear program: direct collocation of the hub-free model on ``N``
intervals of the free final time, its end conditions, the rigid first guess, and the IPOPT
solves (coarse, then fine) behind :mod:`hubbeam_ctrl.limit.optimal` and
:mod:`hubbeam_ctrl.limit.replan`.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass

import casadi as ca
import numpy as np
import scipy.linalg as sla

from hubbeam_ctrl.core.native import capture_native_output
from hubbeam_ctrl.core.progress import progress_bar
from hubbeam_ctrl.limit.bound import _drive_terms, rigid_bang_bang_time, rigid_bound
from hubbeam_ctrl.limit.ipopt_progress import iteration_callback
from hubbeam_ctrl.limit.slew import OptimalSettings
from hubbeam_ctrl.plant.linearization import second_order_linearization
from hubbeam_ctrl.plant.models import build_model
from hubbeam_ctrl.plant.params import Params

__all__: list = []   # plumbing of limit.optimal and limit.replan, no public name

# -- the problem ----------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class _Problem:
    """The hub-free model, its modes at rest and the scales of the NLP."""

    model: object
    n: int
    M0: np.ndarray
    Phi: np.ndarray          # bending modes, mass-normalised (n, n-1)
    w: np.ndarray            # their frequencies [rad/s]
    tip_modal: np.ndarray    # tip deflection of each mode [m]
    q_scale: np.ndarray
    v_scale: np.ndarray
    a_scale: np.ndarray
    f_scale: np.ndarray
    T_rigid: float
    theta: float
    tau_max: float
    tip_row: np.ndarray      # v_tip = tip_row @ q [m]
    tip_limit: float         # [m]
    drive: tuple | None      # (stall torque, back-EMF damping, current-limit torque, viscous, Coulomb, v_c)
    bound: float = math.nan  # the yardstick [s]: the rigid bang-bang within the drive's limits (limit.bound)
    start: np.ndarray | None = None   # scaled initial state [q, v] (None: at rest; limit.replan)
    hold: np.ndarray | None = None    # scaled torques of the first intervals, fixed (limit.replan)


def _problem(params: Params, slew_angle: float, settings: OptimalSettings, rig=None) -> _Problem:
    p = params if settings.modes is None else params.replace(n_transverse=settings.modes)
    model = build_model(settings.model, p, axial=settings.axial)
    n = model.n_q
    lin = second_order_linearization(model, 0.0, "free")
    M0, K0 = np.asarray(lin.M), np.asarray(lin.K)
    w2, V = sla.eigh(K0, M0)
    order = np.argsort(w2)
    w2, V = w2[order], V[:, order]
    tip = np.zeros(n)
    tip[model.transverse_slice] = model.basis.f2_tip
    # the rigid mode is the first; axial modes (dynamic axial coordinates) count as residual too
    Phi, w = V[:, 1:], np.sqrt(np.maximum(w2[1:], 1e-12))
    J = params.total_inertia
    T_rigid = rigid_bang_bang_time(params, slew_angle)
    alpha = params.tau_max / J
    q_scale = np.ones(n)
    q_scale[0] = abs(slew_angle)
    flex = np.arange(1, n)
    if len(flex):
        static = np.abs(np.linalg.solve(K0[1:, 1:], M0[1:, 0] * alpha))
        q_scale[1:] = np.maximum(static, 1e-3 * static.max() + 1e-12)
    rate = np.full(n, 2.0 / T_rigid)
    rate[1:] = np.maximum(np.sqrt(np.diag(K0)[1:] / np.diag(M0)[1:]), rate[1:])
    v_scale = q_scale * rate
    a_scale = v_scale * rate
    f_scale = np.full(n, params.tau_max)
    f_scale[1:] = np.diag(K0)[1:] * q_scale[1:]
    drive = _drive_terms(rig)
    return _Problem(model, n, M0, Phi, w, tip @ Phi, q_scale, v_scale, a_scale, f_scale, T_rigid,
                    float(slew_angle), params.tau_max, tip, settings.deflection_limit * params.L, drive,
                    bound=rigid_bound(params, slew_angle, drive))


def _interval_function(pb: _Problem, d: int, parametric: bool = False) -> tuple:
    """One interval's collocation equations in scaled variables, and the Radau points.

    ``parametric``: the model's parameter vector (:attr:`HubBeamModel.p`) is the function's last
    input instead of built in (one NLP for every payload of the model's family).
    """
    n = pb.n
    points = np.array(ca.collocation_points(d, "radau"))
    C, D, _ = ca.collocation_coeff(list(points))
    C, D = np.array(C), np.array(D).ravel()
    x0 = ca.SX.sym("x0", 2 * n)
    z = ca.SX.sym("z", 3 * n, d)
    u = ca.SX.sym("u")
    h = ca.SX.sym("h")
    qs, vs, as_ = pb.q_scale[:, None], pb.v_scale[:, None], pb.a_scale[:, None]
    Q = ca.horzcat(x0[:n], z[:n, :]) * np.hstack([qs] * (d + 1))
    V = ca.horzcat(x0[n:], z[n:2 * n, :]) * np.hstack([vs] * (d + 1))
    A = z[2 * n:, :] * np.hstack([as_] * d)
    inputs = [x0, z, u, h]
    f = pb.model.inverse_dynamics_function
    if parametric:
        family = pb.model.parametric.inverse_dynamics
        p = ca.SX.sym("p", family.sparsity_in(3).nnz())
        inputs.append(p)
        f = lambda q, v, a: family(q, v, a, p)
    B = np.zeros(n)
    B[0] = 1.0
    eqs = [ca.vec((ca.mtimes(Q, C) - h * V[:, 1:]) / np.hstack([vs] * d)),
           ca.vec((ca.mtimes(V, C) - h * A) / np.hstack([as_] * d))]
    for j in range(d):
        eqs.append((f(Q[:, j + 1], V[:, j + 1], A[:, j]) - B * (u * pb.tau_max)) / pb.f_scale)
    end = ca.vertcat(ca.mtimes(ca.horzcat(x0[:n], z[:n, :]), D), ca.mtimes(ca.horzcat(x0[n:], z[n:2 * n, :]), D))
    F = ca.Function("interval", inputs, [ca.vertcat(*eqs), end], {"cse": True})
    return F, points


def _end_terms(pb: _Problem, xN) -> tuple:
    """(mean angle - Theta, momentum, residual modal energy sum c_i^2 (eta^2 + eta'^2/w^2)) at the end."""
    n = pb.n
    q = xN[:n] * pb.q_scale
    v = xN[n:] * pb.v_scale
    mq = ca.mtimes(pb.M0, q)
    mv = ca.mtimes(pb.M0, v)
    eta = ca.mtimes(pb.Phi.T, mq)
    etad = ca.mtimes(pb.Phi.T, mv)
    c = pb.tip_modal
    energy = ca.sumsqr(c * eta) + ca.sumsqr(c * etad / pb.w)
    return mq[0] / pb.M0[0, 0] - pb.theta, mv[0] / pb.M0[0, 0], energy


def _nlp(pb: _Problem, N: int, d: int, tolerance: float, duration: float | None, parametric: bool = False,
         smoothing: float = 0.0) -> tuple:
    """The NLP over ``w = [T, u (N), x (2n, N+1), z (3n d, N)]``; returns the solver pieces.

    ``smoothing`` (minimum vibration only): weight of the scaled torque's squared steps added to
    the objective (:attr:`OptimalSettings.torque_smoothing`).

    ``parametric``: the NLP's parameter ``p`` holds what depends on the payload
    (:func:`_parameter_values`: the model's parameters and the modes at rest of the end terms).
    """
    n = pb.n
    F, points = _interval_function(pb, d, parametric)
    T = ca.MX.sym("T")
    U = ca.MX.sym("u", 1, N)
    X = ca.MX.sym("x", 2 * n, N + 1)
    Z = ca.MX.sym("z", 3 * n * d, N)
    Zr = ca.reshape(Z, 3 * n, d * N)          # column k*d + j: point j of interval k
    h = T / N
    ends, P = pb, None
    if parametric:
        P = [ca.MX.sym("p", len(pb.model.p)), ca.MX.sym("M0", n, n), ca.MX.sym("Phi", n, n - 1),
             ca.MX.sym("w", n - 1), ca.MX.sym("c", n - 1)]
        ends = dataclasses.replace(pb, M0=P[1], Phi=P[2], w=P[3], tip_modal=P[4])
        eqs, end = F.map(N, "serial")(X[:, :N], Zr, U, h, P[0])
    else:
        eqs, end = F.map(N, "serial")(X[:, :N], Zr, U, h)
    g = [ca.vec(eqs), ca.vec(X[:, 1:] - end)]
    lbg, ubg = [np.zeros(g[0].shape[0] + g[1].shape[0])], [np.zeros(g[0].shape[0] + g[1].shape[0])]
    dangle, momentum, energy = _end_terms(ends, X[:, N])
    g += [dangle / abs(pb.theta), momentum * pb.T_rigid / abs(pb.theta)]
    lbg += [np.zeros(2)]
    ubg += [np.zeros(2)]
    # the tip within the models' range at every grid point (linear in the scaled states)
    g.append(ca.mtimes((pb.tip_row * pb.q_scale / pb.tip_limit)[None, :], X[:n, 1:]).T)
    lbg.append(np.full(N, -1.0))
    ubg.append(np.full(N, 1.0))
    if pb.drive is not None:            # the DC drive's voltage (back-EMF) and current limits
        stall, k_emf, current, viscous, coulomb, v_c = pb.drive
        rate = Zr[n, :] * pb.v_scale[0]                                  # hub rate at every collocation point
        u = ca.repmat(U, d, 1)
        u = ca.reshape(u, 1, d * N) * pb.tau_max                        # net torque of each point's interval
        drive = u + viscous * rate + coulomb * ca.tanh(rate / (v_c * 2.0 / pb.T_rigid * abs(pb.theta)))
        g += [((drive + k_emf * rate) / stall).T, (drive / current).T]
        lbg += [np.full(d * N, -1.0), np.full(d * N, -1.0)]
        ubg += [np.full(d * N, 1.0), np.full(d * N, 1.0)]
    n_flex = max(len(pb.w), 1)
    if duration is None:
        g.append(energy * n_flex / tolerance ** 2)
        lbg.append([-np.inf])
        ubg.append([1.0])
        objective = T / pb.T_rigid
    else:
        objective = energy * n_flex / tolerance ** 2
        if smoothing > 0:                # one plan among those that leave the model at rest
            objective = objective + smoothing * ca.sumsqr(U[1:] - U[:-1])
    w = ca.vertcat(T, ca.vec(U), ca.vec(X), ca.vec(Z))
    nlp = {"x": w, "f": objective, "g": ca.vertcat(*g)}
    if P is not None:
        nlp["p"] = ca.vertcat(*[ca.vec(s) for s in P])
    lbw = np.full(w.shape[0], -np.inf)
    ubw = np.full(w.shape[0], np.inf)
    lbw[1:1 + N], ubw[1:1 + N] = -1.0, 1.0
    if pb.hold is not None:
        lbw[1:1 + len(pb.hold)] = ubw[1:1 + len(pb.hold)] = pb.hold
    x0 = 0.0 if pb.start is None else pb.start                        # x0: at rest, or a re-plan's state
    lbw[1 + N:1 + N + 2 * n], ubw[1 + N:1 + N + 2 * n] = x0, x0
    if duration is None:
        lbw[0], ubw[0] = 0.5 * pb.T_rigid, 20.0 * pb.T_rigid
    else:
        lbw[0] = ubw[0] = duration
    return nlp, lbw, ubw, np.concatenate(lbg), np.concatenate(ubg), points


def _parameter_values(pb: _Problem) -> np.ndarray:
    """The values of a parametric NLP's ``p`` for the problem ``pb`` (:func:`_nlp`)."""
    return np.concatenate([pb.model.p, pb.M0.ravel(order="F"), pb.Phi.ravel(order="F"), pb.w, pb.tip_modal])


def _rigid_guess(pb: _Problem, N: int, d: int, points, T: float) -> np.ndarray:
    """Initial guess: the rigid bang-bang stretched to ``T`` (scaled), the beam undeformed."""
    n = pb.n
    s = np.linspace(0.0, 1.0, N + 1)
    sc = (np.arange(N)[:, None] + points[None, :]) / N
    th = lambda s: np.where(s < 0.5, 2 * s ** 2, 1 - 2 * (1 - s) ** 2)
    rate = lambda s: np.where(s < 0.5, 4 * s, 4 * (1 - s))
    acc = lambda s: np.where(s < 0.5, 4.0, -4.0)
    sign = math.copysign(1.0, pb.theta)
    X = np.zeros((2 * n, N + 1))
    X[0] = th(s)
    X[n] = rate(s) * abs(pb.theta) / T / pb.v_scale[0]
    Z = np.zeros((3 * n, d, N))
    Z[0] = th(sc).T
    Z[n] = (rate(sc) * abs(pb.theta) / T / pb.v_scale[0]).T
    Z[2 * n] = (acc(sc) * abs(pb.theta) / T ** 2 / pb.a_scale[0]).T
    u = sign * np.where((np.arange(N) + 0.5) / N < 0.5, 1.0, -1.0) * min(1.0, (pb.T_rigid / T) ** 2)
    if pb.start is not None:            # a re-plan: the hub's rigid guess from its angle, the state fixed
        X[0] = pb.start[0] + (pb.theta / pb.q_scale[0] - pb.start[0]) * X[0]
        X[:, 0] = pb.start
    return np.concatenate([[T], u, X.ravel(order="F"), Z.reshape(3 * n * d, N, order="F").ravel(order="F")])


def _resample(pb: _Problem, w: np.ndarray, N0: int, N: int, d: int, points) -> np.ndarray:
    """A solution on ``N0`` intervals interpolated onto ``N`` (warm start of the fine solve)."""
    n = pb.n
    T = w[0]
    u0 = w[1:1 + N0]
    X0 = w[1 + N0:1 + N0 + 2 * n * (N0 + 1)].reshape(2 * n, N0 + 1, order="F")
    Z0 = w[1 + N0 + 2 * n * (N0 + 1):].reshape(3 * n, d, N0, order="F")
    s0 = np.linspace(0, 1, N0 + 1)
    sc0 = ((np.arange(N0)[:, None] + points[None, :]) / N0).ravel()
    A0 = Z0[2 * n:].transpose(0, 2, 1).reshape(n, -1)
    s = np.linspace(0, 1, N + 1)
    sc = (np.arange(N)[:, None] + points[None, :]) / N
    X = np.array([np.interp(s, s0, row) for row in X0])
    Z = np.zeros((3 * n, d, N))
    for i in range(2 * n):
        Z[i] = np.interp(sc, s0, X0[i]).T
    for i in range(n):
        Z[2 * n + i] = np.interp(sc, sc0, A0[i]).T
    u = u0[np.minimum((((np.arange(N) + 0.5) / N) * N0).astype(int), N0 - 1)]
    return np.concatenate([[T], u, X.ravel(order="F"), Z.reshape(3 * n * d, N, order="F").ravel(order="F")])


def _solve(pb: _Problem, N: int, d: int, tolerance: float, duration, w0, settings: OptimalSettings,
           bar=None) -> tuple:
    nlp, lbw, ubw, lbg, ubg, points = _nlp(pb, N, d, tolerance, duration, smoothing=settings.torque_smoothing)
    ipopt = {"print_level": 0, "max_iter": settings.max_iter, "sb": "yes", "tol": 1e-8, "acceptable_tol": 1e-6}
    if settings.max_wall_s is not None:
        ipopt["max_wall_time"] = max(float(settings.max_wall_s), 1e-3)
    options = {"print_time": False, "ipopt": ipopt}
    callback = iteration_callback(nlp, bar)          # None unless a progress bar is drawn
    if callback is not None:
        options["iteration_callback"] = callback
    solver = ca.nlpsol("optimal_slew", "ipopt", nlp, options)
    with capture_native_output():
        sol = solver(x0=w0, lbx=lbw, ubx=ubw, lbg=lbg, ubg=ubg)
    stats = solver.stats()
    return np.array(sol["x"]).ravel(), stats, points


def _fallback_guess(pb: _Problem, N: int, d: int, duration) -> tuple:
    points = np.array(ca.collocation_points(d, "radau"))
    T = duration if duration is not None else 1.3 * pb.T_rigid
    return _rigid_guess(pb, N, d, points, T), points


def _optimise(params: Params, slew_angle: float, tolerance: float, duration, settings: OptimalSettings,
              rig=None, progress: bool = False) -> tuple:
    return _optimise_problem(_problem(params, slew_angle, settings, rig), tolerance, duration, settings, progress)


def _optimise_problem(pb: _Problem, tolerance: float, duration, settings: OptimalSettings,
                      progress: bool = False) -> tuple:
    N, d = settings.intervals, settings.degree
    iterations, statuses = 0, []
    start = time.perf_counter()
    w0, points = _fallback_guess(pb, N, d, duration)
    N0 = settings.coarse_intervals
    coarse = 0 < N0 < N
    # the bar's total is the iteration limit of the solves (IPOPT stops sooner when it converges)
    with progress_bar(settings.max_iter * (2 if coarse else 1), "optimal: IPOPT iterations",
                      enabled=progress) as bar:
        if coarse:
            wc, points = _fallback_guess(pb, N0, d, duration)
            wc, stats, points = _solve(pb, N0, d, tolerance, duration, wc, settings, bar)
            iterations += stats["iter_count"]
            statuses.append(stats["return_status"])
            if stats["success"]:
                w0 = _resample(pb, wc, N0, N, d, points)
        w, stats, points = _solve(pb, N, d, tolerance, duration, w0, settings, bar)
    iterations += stats["iter_count"]
    return pb, w, stats, iterations, time.perf_counter() - start


def _trajectory(pb: _Problem, w: np.ndarray, N: int) -> dict:
    n = pb.n
    T = float(w[0])
    tau = np.asarray(w[1:1 + N]) * pb.tau_max
    X = w[1 + N:1 + N + 2 * n * (N + 1)].reshape(2 * n, N + 1, order="F")
    q = X[:n] * pb.q_scale[:, None]
    v = X[n:] * pb.v_scale[:, None]
    tip = pb.model.tip_series(q.T, v.T)[0]
    dangle, momentum, energy = (float(x) for x in _end_terms(pb, X[:, N]))
    c = pb.tip_modal
    eta, etad = pb.Phi.T @ pb.M0 @ q[:, -1], pb.Phi.T @ pb.M0 @ v[:, -1]
    residual = float(np.sum(np.abs(c) * np.hypot(eta, etad / pb.w)))
    sl = pb.model.transverse_slice
    return {"T": T, "t": np.linspace(0.0, T, N + 1), "tau": tau, "theta": q[0], "theta_dot": v[0],
            "v_tip": tip, "q2": q[sl].T.copy(), "q2_dot": v[sl].T.copy(), "residual": residual, "angle_error": dangle}
