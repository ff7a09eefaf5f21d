"""The physical limit of a slew: time-optimal and minimum-vibration rest-to-rest torques.

The hub turns by ``Theta`` from rest, within ``|tau| <= tau_max``, and ends with the beam's
residual vibration below a tolerance. The trajectory is computed on the nonlinear model
(FOAM by default, its axial coordinates condensed: :func:`~hubbeam_ctrl.plant.models.build_model`
with ``axial="quasi-static"``, which removes the stiff axial modes from the problem) by direct
collocation: ``N`` intervals of the free final time ``T`` (time scaling), the torque constant
on each, Radau collocation of the coordinates, rates and accelerations with the implicit
equations of motion ``M(q) a + c(q, v) = B tau`` at every collocation point, solved by IPOPT.

**End conditions.** At ``T`` the torque stops. The hub-free system linearised at rest,
``M0 q'' + K0 q = 0``, has one rigid mode and the bending modes ``phi_i`` (``K0 phi = w^2 M0
phi``, ``phi' M0 phi = 1``). The end state must carry no angular momentum (``(M0 v)_0 = 0``,
the hub does not drift), its mean angle ``(M0 q)_0 / M0_00`` must be ``Theta``, and the
residual amplitude of the tip deflection in the hub frame, ``sum_i |c_i| sqrt(eta_i^2 +
(eta_i'/w_i)^2)`` with ``eta = Phi' M0 q`` and ``c_i`` mode ``i``'s tip deflection, must
stay within the tolerance (imposed through Cauchy-Schwarz: ``n sum_i c_i^2 (eta_i^2 +
eta_i'^2/w_i^2) <= tol^2``, which implies it).

**Time-optimal.** The smallest ``T`` (objective ``T``), started from the rigid bang-bang
(``T_rigid = 2 sqrt(Theta J / tau_max)``, the angle of the rigid body) on a coarse grid and
warm-started on the fine one; its yardstick ``rigid_bound_s`` is :func:`rigid_bound` (on a DC
drive the rigid bang-bang within the voltage limit through back-EMF, the current limit and
friction, :mod:`hubbeam_ctrl.limit.bound`). **Minimum vibration.** For a given ``T >= T_rigid``: the
smallest residual (objective: the residual's modal energy).

**Check.** The optimal torque (piecewise constant, zero after ``T``) is applied to the
evaluation plant (FOAM with dynamic axial coordinates and more bending modes,
:func:`~hubbeam_ctrl.sim.stepper.simulate_fixed_step`), and the residual is the largest
``|v_tip|`` over two periods of the first bending mode after ``T``.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np
import scipy.linalg as sla

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.native import capture_native_output
from hubbeam_ctrl.core.progress import progress_bar
from hubbeam_ctrl.core.settings import Settings, setting
from hubbeam_ctrl.core.validation import check_finite, check_in_range, check_positive
from hubbeam_ctrl.limit.bound import _drive_terms, drive_bang_bang_time, rigid_bang_bang_time, rigid_bound
from hubbeam_ctrl.limit.ipopt_progress import iteration_callback
from hubbeam_ctrl.plant.linearization import second_order_linearization
from hubbeam_ctrl.plant.models import AXIAL_TREATMENTS, build_model
from hubbeam_ctrl.plant.params import MAX_MODES, Params
from hubbeam_ctrl.plant.rig import Rig

__all__ = ["OptimalSettings", "OptimalSlew", "DEFAULT_TOLERANCE", "rigid_bang_bang_time", "drive_bang_bang_time",
           "rigid_bound", "default_tolerance",
           "time_optimal_slew", "min_vibration_slew"]

#: Default residual tip vibration, relative to the beam length (the issue's 0.1 % of L).
DEFAULT_TOLERANCE = 1e-3

#: Smallest residual tolerance, relative to the beam length (the NLP divides the residual energy
#: by the tolerance squared).
MIN_TOLERANCE = 1e-9

#: Smallest slew angle [rad] (as a task's, :data:`hubbeam_ctrl.study.tasks.MIN_TARGET`).
MIN_SLEW_ANGLE = 1e-6

#: Longest slew time [s] (as a task's ``tf``).
MAX_DURATION = 1e6


@dataclass(frozen=True)
class OptimalSettings(Settings):
    """How the optimal slew is computed and checked."""

    intervals: int = setting(40, lo=4, hi=2000, doc="Collocation intervals N of the slew (torque constant "
                                                    "on each).")
    degree: int = setting(3, lo=1, hi=9, doc="Radau collocation points per interval.")
    coarse_intervals: int = setting(0, lo=0, hi=2000,
                                    doc="Intervals of the first, coarse solve whose result warm-starts "
                                        "the fine one (0: no coarse solve).")
    model: str = setting("foam", choices=("foam", "cfoam", "tlam"), doc="Design model of the optimisation.")
    axial: str = setting("quasi-static", choices=AXIAL_TREATMENTS,
                         doc="Axial coordinates of the design model (quasi-static: no stiff axial modes).")
    modes: int | None = setting(None, lo=1, hi=MAX_MODES, kind=int,
                                doc="Transverse modes of the design model (None: params.n_transverse).")
    plant_modes: int | None = setting(None, lo=1, hi=MAX_MODES, kind=int,
                                      doc="Transverse modes of the evaluation plant (None: 3 more than "
                                          "the design, at most 20).")
    check: bool = setting(True, doc="Apply the optimal torque to the evaluation plant and report its "
                                    "residual.")
    max_iter: int = setting(1000, lo=1, doc="IPOPT iteration limit per solve.")
    torque_smoothing: float = setting(0.0, lo=0.0, doc="Minimum vibration only: weight of the torque's squared "
                                                        "steps (scaled by tau_max) added to the residual's "
                                                        "objective, which picks one plan among the many that "
                                                        "leave the model at rest (0: none).")
    max_wall_s: float | None = setting(None, unit="s", lo=0.0, lo_open=True, kind=float,
                                       doc="IPOPT's wall-clock limit per solve (None: none; building the NLP "
                                           "before it is not counted); past it the result is the last iterate, "
                                           "not converged. A real-time re-plan's deadline.")
    deflection_limit: float = setting(0.3, lo=0.0, lo_open=True, hi=10.0,
                                      doc="Largest abs(v_tip) during the slew, relative to L, kept at every grid "
                                          "point (0.3: the models' validated range; a light link driven by its "
                                          "full torque would otherwise bend past it, where the model is not "
                                          "the beam).")


@dataclass(frozen=True, eq=False)
class OptimalSlew:
    """An optimal rest-to-rest slew and how well it did.

    Attributes
    ----------
    kind : {"time-optimal", "min-vibration"}
    slew_angle : float
        Theta [rad].
    duration_s : float
        Slew time T [s].
    t : ndarray (N+1,)
        Grid times [s].
    tau : ndarray (N,)
        Torque on each interval ``[t_k, t_k+1)`` [N m].
    theta, theta_dot, v_tip : ndarray (N+1,)
        Hub angle [rad], hub rate [rad/s] and tip deflection in the hub frame [m] of the
        design model at the grid times.
    q2, q2_dot : ndarray (N+1, n2)
        Transverse modal coordinates [m] and rates [m/s] of the design model at the grid times.
    tolerance : float
        Allowed residual tip vibration [m].
    residual_design : float
        Residual tip amplitude of the design model at ``T`` (modal bound) [m].
    residual_plant : float or None
        Largest ``|v_tip|`` of the evaluation plant after ``T`` [m] (None: not checked).
    final_angle_plant : float or None
        Mean hub angle of the evaluation plant after ``T`` [rad].
    rigid_bound_s : float
        The rigid body's shortest slew [s] (:func:`rigid_bound`): ``2 sqrt(Theta J / tau_max)``,
        or on a DC drive the bang-bang within its voltage (back-EMF), current and friction.
    converged : bool
        Whether IPOPT reported success.
    message : str
        IPOPT's return status, and what was kept if it did not converge.
    solve_s : float
        Wall time of the optimisation [s].
    iterations : int
        IPOPT iterations (all solves).
    design : str
        The design model (name, modes, axial treatment).
    plant : str
        The evaluation plant, or "" if not checked.
    params : Params
    """

    kind: str
    slew_angle: float
    duration_s: float
    t: np.ndarray
    tau: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    v_tip: np.ndarray
    q2: np.ndarray
    q2_dot: np.ndarray
    tolerance: float
    residual_design: float
    residual_plant: float | None
    final_angle_plant: float | None
    rigid_bound_s: float
    converged: bool
    message: str
    solve_s: float
    iterations: int
    design: str
    plant: str
    params: Params = field(repr=False)

    @property
    def ratio(self) -> float:
        """``duration_s / rigid_bound_s`` [-]."""
        return self.duration_s / self.rigid_bound_s

    def torque(self, t):
        """The optimal torque at times ``t`` [s] (piecewise constant, 0 outside ``[0, T)``) [N m].

        Parameters
        ----------
        t : float or array_like
            Times [s].
        """
        t = np.asarray(t, dtype=float)
        k = np.clip(np.floor(t / self.duration_s * len(self.tau)).astype(int), 0, len(self.tau) - 1)
        return np.where((t >= 0) & (t < self.duration_s), self.tau[k], 0.0)

    def to_dict(self) -> dict:
        """Plain-data summary (JSON-ready, without the trajectories)."""
        return {"kind": self.kind, "slew_angle": self.slew_angle, "duration_s": self.duration_s,
                "rigid_bound_s": self.rigid_bound_s, "ratio": self.ratio, "tolerance_m": self.tolerance,
                "residual_design_m": self.residual_design, "residual_plant_m": self.residual_plant,
                "final_angle_plant": self.final_angle_plant, "converged": self.converged,
                "message": self.message, "solve_s": self.solve_s, "iterations": self.iterations,
                "design": self.design, "plant": self.plant, "tau_max": self.params.tau_max}


def default_tolerance(params: Params) -> float:
    """Default residual tip vibration: :data:`DEFAULT_TOLERANCE` times the beam length [m].

    Parameters
    ----------
    params : Params
        Beam (``L``).
    """
    return DEFAULT_TOLERANCE * params.L


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


def _plant_check(params: Params, result: "OptimalSlew", settings: OptimalSettings, design_modes: int) -> tuple:
    """Largest ``|v_tip|`` and the mean hub angle of the evaluation plant after ``T``."""
    from hubbeam_ctrl.plant.modal import natural_frequencies
    from hubbeam_ctrl.sim.stepper import StepperSettings, simulate_fixed_step
    modes = settings.plant_modes or min(design_modes + 3, MAX_MODES)
    plant = params.replace(n_transverse=modes)
    hz = natural_frequencies("foam", 0.0, "free", params=plant)
    period = 1.0 / hz[0]
    dt = min(result.duration_s / (4 * len(result.tau)), 0.05 / hz[-1], period / 40)
    t_end = result.duration_s + 2 * period
    dt = t_end / math.ceil(t_end / dt)
    run = simulate_fixed_step("foam", result.torque, t_end, params=plant,
                              settings=StepperSettings(dt=dt))
    after = run.t >= result.duration_s
    return (float(np.max(np.abs(run.v_tip[after]))), float(np.mean(run.q[after, 0])),
            f"FOAM, {modes} transverse and {plant.n_axial} axial modes (dynamic), dt = {dt:.3g} s")


def _source(params) -> tuple:
    """``(Params, Rig or None)`` of the first argument: a beam, or a rig (its plant parameters)."""
    if isinstance(params, Rig):
        return params.plant_params, params
    return params, None


def _check_inputs(params: Params, slew_angle, tolerance, settings) -> tuple:
    if not isinstance(params, Params):
        raise ParameterError(f"params must be a Params or a Rig, got {type(params).__name__}")
    slew_angle = check_finite("slew_angle", slew_angle, "rad")
    if slew_angle == 0.0:
        raise ParameterError("slew_angle must be a finite number != 0 [rad], got 0")
    if tolerance is not None:
        tolerance = check_in_range("tolerance", check_positive("tolerance", tolerance, "m"), "m",
                                   MIN_TOLERANCE * params.L, params.L,
                                   f"{MIN_TOLERANCE:g} L to the beam length L")
    else:
        tolerance = default_tolerance(params)
    if not isinstance(settings, OptimalSettings):
        raise ParameterError(f"settings must be an OptimalSettings, got {type(settings).__name__}")
    return slew_angle, tolerance


def _check_slew(params: Params, slew_angle: float, duration: float | None = None, name: str = "duration") -> float:
    """Refuse a slew from rest the models cannot describe; returns the checked ``duration`` (or None).

    The slew's rigid peak rate must stay within ``Params.max_spin`` (the 1 % root-strain spin,
    as :func:`~hubbeam_ctrl.study.scenarios.make_scenario` requires): ``sqrt(|Theta| tau_max /
    J_total)`` for the time-optimal (bang-bang) slew, ``2 |Theta| / T`` in a given time ``T``;
    ``|Theta| >= 1e-6 rad``; ``T <= MAX_DURATION``.
    """
    if abs(slew_angle) < MIN_SLEW_ANGLE:
        raise ParameterError(f"slew_angle must be a finite number with |slew_angle| >= {MIN_SLEW_ANGLE:g} [rad], "
                             f"got {slew_angle:g}")
    J = params.total_inertia
    if duration is not None:
        duration = check_positive(name, duration, "s")
        if duration > MAX_DURATION:
            raise ParameterError(f"{name} must be in (0, {MAX_DURATION:g}] [s], got {duration:g}")
        if 2 * abs(slew_angle) / duration > params.max_spin:
            raise ParameterError(f"{name} must be >= {2 * abs(slew_angle) / params.max_spin:.5g} s (a slew by "
                                 f"{slew_angle:g} rad in T reaches the rigid peak rate 2 |Theta| / T, at most "
                                 f"Params.max_spin = {params.max_spin:.4g} rad/s), got {duration:g} s")
        return duration
    peak, how = math.sqrt(abs(slew_angle) * params.tau_max / J), "sqrt(|Theta| tau_max / J_total), bang-bang"
    if peak > params.max_spin:
        raise ParameterError(f"slew_angle = {slew_angle:g} rad spins the hub up to {peak:.4g} rad/s ({how}), above "
                             f"Params.max_spin = {params.max_spin:.4g} rad/s (1 % centrifugal strain at the root)")
    return duration


def _result(kind: str, params: Params, slew_angle: float, tolerance: float, pb: _Problem, w, stats,
            iterations: int, wall: float, settings: OptimalSettings) -> OptimalSlew:
    N = settings.intervals
    tr = _trajectory(pb, w, N)
    converged = bool(stats["success"])
    message = str(stats["return_status"])
    if not converged:
        message += "; the last iterate is kept (" + (
            "feasible" if abs(tr["angle_error"]) < 1e-3 * abs(slew_angle) and tr["residual"] <= 1.01 * tolerance
            else "NOT feasible") + f": residual {tr['residual']:.3g} m, angle error {tr['angle_error']:.3g} rad)"
    m = pb.model
    design = f"{m.name.upper()}, {m.n_transverse} transverse modes, {m.axial} axial, {N} x {settings.degree} Radau"
    out = OptimalSlew(kind=kind, slew_angle=slew_angle, duration_s=tr["T"], t=tr["t"], tau=tr["tau"],
                      theta=tr["theta"], theta_dot=tr["theta_dot"], v_tip=tr["v_tip"], q2=tr["q2"], q2_dot=tr["q2_dot"],
                      tolerance=tolerance,
                      residual_design=tr["residual"], residual_plant=None, final_angle_plant=None,
                      rigid_bound_s=pb.bound, converged=converged, message=message, solve_s=wall,
                      iterations=iterations, design=design, plant="", params=params)
    if settings.check:
        residual, angle, plant = _plant_check(params, out, settings, m.n_transverse)
        out = _replace(out, residual_plant=residual, final_angle_plant=angle, plant=plant)
    return out


def _replace(result: OptimalSlew, **changes) -> OptimalSlew:
    return dataclasses.replace(result, **changes)


def time_optimal_slew(params: Params, slew_angle: float, *, tolerance: float | None = None,
                      settings: OptimalSettings = OptimalSettings(), progress: bool = False) -> OptimalSlew:
    """The minimum-time rest-to-rest slew within ``|tau| <= tau_max`` and the residual tolerance.

    Parameters
    ----------
    params : Params or Rig
        Beam, hub and drive (``tau_max``); or a rig: its plant parameters, and with a DC motor
        the voltage limit through back-EMF, the current limit and the friction the drive must
        overcome (:func:`_drive_terms`).
    slew_angle : float
        Theta [rad], finite, not 0.
    tolerance : float, optional
        Allowed residual tip vibration [m], > 0 (default :func:`default_tolerance`, 1e-3 L).
    settings : OptimalSettings
        Grid, design model and check.
    progress : bool
        Show IPOPT's iterations on a progress bar (on a terminal only; default False).

    Returns
    -------
    OptimalSlew
        ``kind="time-optimal"``; ``converged`` False (with the message) if IPOPT did not
        converge, the last iterate kept.
    """
    params, rig = _source(params)
    slew_angle, tolerance = _check_inputs(params, slew_angle, tolerance, settings)
    _check_slew(params, slew_angle)
    pb, w, stats, iterations, wall = _optimise(params, slew_angle, tolerance, None, settings, rig, progress)
    return _result("time-optimal", params, slew_angle, tolerance, pb, w, stats, iterations, wall, settings)


def min_vibration_slew(params: Params, slew_angle: float, duration: float, *, tolerance: float | None = None,
                       settings: OptimalSettings = OptimalSettings(), name: str = "duration",
                       progress: bool = False) -> OptimalSlew:
    """The rest-to-rest slew in a given time with the smallest residual vibration.

    Parameters
    ----------
    params : Params or Rig
        Beam, hub and drive (``tau_max``); or a rig: its plant parameters, and with a DC motor
        the voltage limit through back-EMF, the current limit and the friction the drive must
        overcome (:func:`_drive_terms`).
    slew_angle : float
        Theta [rad], finite, not 0.
    duration : float
        Slew time T [s], at least the time-optimal one.
    tolerance : float, optional
        Allowed residual tip vibration [m], > 0 (default 1e-3 L): a result above it raises.
    settings : OptimalSettings
        Grid, design model and check.
    name : str
        The duration's name as the caller spelled it (``--duration`` on the command line).
    progress : bool
        Show IPOPT's iterations on a progress bar (on a terminal only; default False).

    Returns
    -------
    OptimalSlew
        ``kind="min-vibration"``.

    Raises
    ------
    ParameterError
        ``duration`` so short that the smallest residual exceeds ``tolerance`` (below the
        time-optimal duration): one line naming ``name`` and the shortest feasible duration,
        found by :func:`time_optimal_slew`.
    """
    source = params
    params, rig = _source(params)
    slew_angle, tolerance = _check_inputs(params, slew_angle, tolerance, settings)
    duration = _check_slew(params, slew_angle, duration, name)
    quick = settings.replace(check=False)

    def refuse():
        fastest = time_optimal_slew(source, slew_angle, tolerance=tolerance, settings=quick)
        if duration < fastest.duration_s:
            raise ParameterError(f"{name} must be >= {fastest.duration_s:.5g} s (the time-optimal slew with "
                                 f"residual <= {tolerance:.3g} m; the rigid bang-bang bound is "
                                 f"{fastest.rigid_bound_s:.5g} s), got {duration:g} s")

    if duration < rigid_bound(params, slew_angle, rig):          # below the rigid bound: hardly ever feasible
        refuse()
    pb, w, stats, iterations, wall = _optimise(params, slew_angle, tolerance, duration, settings, rig, progress)
    out = _result("min-vibration", params, slew_angle, tolerance, pb, w, stats, iterations, wall, quick)
    if out.residual_design > tolerance * 1.0001:
        refuse()
    if settings.check:
        residual, angle, plant = _plant_check(params, out, settings, pb.model.n_transverse)
        out = _replace(out, residual_plant=residual, final_angle_plant=angle, plant=plant)
    return out
