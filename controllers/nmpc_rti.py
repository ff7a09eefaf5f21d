"""One real-time iteration of the NMPC as a CasADi function, and the RK4 substeps of its shooting map.

:func:`rti_step_function` is the whole step of :class:`controllers.NMPC` (the Python step calls
it; :func:`hubbeam_ctrl.deploy.nmpc_c.nmpc_to_c` generates its C): the shooting map linearised
along the previous plan, the condensed QP solved by DAQP (or ``qrqp``) through ``casadi.conic``, the new plan.
"""

from __future__ import annotations

import math

import casadi as ca

__all__ = ["RK4_REACH", "rk4", "rk4_substeps", "shooting_function", "rti_step_function"]

#: RK4 keeps ``|lambda h|`` below this for the fastest modelled mode (its stability limit on the
#: imaginary axis is 2.83).
RK4_REACH = 1.5


def rk4_substeps(omega_max: float, dt: float) -> int:
    """RK4 substeps per sample that keep ``omega_max h`` within :data:`RK4_REACH`.

    Parameters
    ----------
    omega_max : float
        Fastest modelled natural frequency [rad/s].
    dt : float
        Sample time [s].

    Returns
    -------
    int
        At least 1.
    """
    return max(1, int(math.ceil(omega_max * dt / RK4_REACH)))


def rk4(f, x, u, span: float, steps: int):
    """The state after ``span`` from ``x`` under the constant input ``u``: RK4 of ``f`` in ``steps`` steps.

    Parameters
    ----------
    f : callable
        ``f(x, u)``: the state derivative (CasADi expressions) [state unit / s].
    x, u : casadi.SX
        The state and the input.
    span : float
        [s].
    steps : int
        RK4 steps, >= 1.

    Returns
    -------
    casadi.SX
    """
    h = span / steps
    z = x
    for _ in range(steps):
        k1 = f(z, u)
        k2 = f(z + h / 2 * k1, u)
        k3 = f(z + h / 2 * k2, u)
        k4 = f(z + h * k3, u)
        z = z + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return z


def shooting_function(name: str, f, x, u, extra: list, span: float, steps: int,
                      jacobian: str = "linearised") -> ca.Function:
    """``(x, u, *extra) -> (x+, dx+/dx, dx+/du)``: the shooting map of :func:`rti_step_function`.

    ``x+`` is RK4 of ``f`` (:func:`rk4`). Its Jacobians are, with ``jacobian="exact"``, the
    derivatives of that RK4 map; with ``"linearised"`` those of RK4 (the same steps) of the model
    linearised at ``(x, u)``, ``dz' = J_x dz + J_u du``: the matrix polynomial of RK4 in ``h J_x``,
    which agrees with the exact one to ``O(h^5)`` per step and costs one Jacobian of ``f`` instead of
    the derivative of four evaluations (67 k against 14 k instructions on ``servo_link``'s 2-mode
    FOAM with its drive). The step's QP is then a Gauss-Newton step with these sensitivities; the
    defects and the prediction use the exact ``x+``.

    Parameters
    ----------
    name : str
        The function's name.
    f : callable
        ``f(x, u)``: the state derivative [state unit / s].
    x, u : casadi.SX
        Symbols of the state and the input.
    extra : list of casadi.SX
        More inputs ``f`` depends on (the model's parameter vector).
    span : float
        One sample [s].
    steps : int
        RK4 steps per sample.
    jacobian : {"linearised", "exact"}

    Returns
    -------
    casadi.Function
    """
    z = rk4(f, x, u, span, steps)
    if jacobian == "exact":
        return ca.Function(name, [x, u, *extra], [z, ca.jacobian(z, x), ca.jacobian(z, u)], {"cse": True})
    fx = f(x, u)
    Jx, Ju = ca.jacobian(fx, x), ca.jacobian(fx, u)
    dz, du = ca.SX.sym("dz", x.size1()), ca.SX.sym("du")
    w = rk4(lambda w, v: ca.mtimes(Jx, w) + Ju * v, dz, du, span, steps)
    return ca.Function(name, [x, u, *extra], [z, ca.jacobian(w, dz), ca.jacobian(w, du)], {"cse": True})


def rti_step_function(shooting: ca.Function, horizon: int, nx: int, r: float, tau_max: float,
                      parametric: bool = False, current: tuple | None = None,
                      in_flight: ca.Function | None = None, qp_solver: str = "daqp",
                      state_limits: tuple | None = None) -> ca.Function:
    """One real-time iteration of the NMPC as a CasADi function (its C is the generated step).

    ``(x, X, U, XR, UR, Q, P[, p]) -> (X+, U+, qp_residual)``: the shooting map linearised along the
    previous plan ``(X, U)`` (``nx x N+1``, ``1 x N``), the condensed QP in the moves' deltas
    (cost ``sum |x_j - XR_j|^2_Q + r (u_j - UR_j)^2 + |x_N - XR_N|^2_P``, dynamics with the
    stages' defects, ``|u| <= tau_max``) solved by an active-set solver through CasADi's ``conic``
    (DAQP by default, linked into the generated C), and the new plan rolled out along the
    linearisation from the measured state ``x``.

    ``qp_residual`` is the QP's optimality residual at the solver's answer, whatever the solver
    says of itself: the largest of the stationarity ``|H dU + g + lam_x + A' lam_a|``, the
    constraints' violation and the complementarity ``min(lam, slack)`` on each bound's side, on
    the QP scaled to a unit Hessian diagonal (so in the command's unit, [N m] or [V], and for the
    general rows, each divided by its bound, in shares of their limits). A solver
    that stopped short (an iteration limit, cycling) shows here; the caller keeps its shifted plan
    when it exceeds a tolerance.

    Parameters
    ----------
    shooting : casadi.Function
        ``(x, u[, p]) -> (x+, dx+/dx, dx+/du)`` over one sample.
    horizon : int
        ``N`` [samples].
    nx : int
        States of the prediction.
    r : float
        Weight of the command [1/(N m)^2].
    tau_max : float
        Command limit [N m].
    parametric : bool
        The shooting map takes the model's parameter vector ``p`` (a learnt payload).
    current : tuple, optional
        ``(row, emf, bound, stages)``: a DC drive's current limit ``|u_j - emf x_j[row]| <= bound`` at
        the start of the first ``stages`` stages (``u`` in volts, ``x[row]`` the hub rate [rad/s],
        ``emf = k_e N`` [V s/rad], ``bound = R I_max`` [V]): linear constraints of the QP, or with
        ``stages == 1`` a bound on the first move (the QP stays a box QP).
    in_flight : casadi.Function, optional
        ``(x, u_prev) -> x``: the state where this sample's command starts to act, from the measured
        one under the command in flight (a computation delay); the step then takes ``u_prev`` as its
        last input.
    qp_solver : {"daqp", "qrqp"}
        CasADi's ``conic`` plugin for the QP: DAQP (a dual active set for dense QPs, shipped with
        CasADi's wheel as a static library the C links) or CasADi's own ``qrqp``.
    state_limits : tuple, optional
        ``(C, b)``: ``|C x_j| <= b`` at every predicted state ``x_1 .. x_N`` (``C`` ``k x nx``, ``b``
        ``k`` bounds in the outputs' units, e.g. the tip deflection [m] and the hub rate [rad/s]):
        linear constraints of the QP in the moves. They are hard: a QP they make infeasible shows in
        ``qp_residual`` and the caller keeps its shifted plan.

    Returns
    -------
    casadi.Function
    """
    N = int(horizon)
    x, X, U = ca.MX.sym("x", nx), ca.MX.sym("X", nx, N + 1), ca.MX.sym("U", 1, N)
    XR, UR = ca.MX.sym("XR", nx, N + 1), ca.MX.sym("UR", 1, N)
    Q, P = ca.MX.sym("Q", nx, nx), ca.MX.sym("P", nx, nx)
    extra = [ca.MX.sym("p", shooting.size1_in(2))] if parametric else []
    measured, late = x, []
    if in_flight is not None:
        late = [ca.MX.sym("u_prev")]
        x = in_flight(measured, late[0])
    Xn, Ax, Bu = shooting.map(N)(X[:, :N], U, *extra)
    eye = ca.DM.eye(N)
    S, c = ca.MX.zeros(nx, N), x - X[:, 0]        # dX_j = S_j dU + c_j, dX_0 the measured offset
    H, g = r * ca.MX.eye(N), r * (U - UR).T
    # general rows on dU: their values at dU = 0 and bounds (the current limit's, the state limits')
    rows, values, bounds = [], [], []
    if state_limits is not None:
        Cs, bs = ca.DM(state_limits[0]), ca.DM(state_limits[1])
    for j in range(N + 1):
        if current is not None and j < current[3]:
            row, emf = current[:2]
            rows.append(eye[j, :] - emf * S[row, :])
            values.append(U[j] - emf * (X[row, j] + c[row]))
            bounds.append(ca.DM([current[2]]))
        if j > 0 and state_limits is not None:
            rows.append(ca.mtimes(Cs, S))
            values.append(ca.mtimes(Cs, X[:, j] + c))
            bounds.append(bs)
        if j > 0:
            WS = ca.mtimes(P if j == N else Q, S)
            H = H + ca.mtimes(S.T, WS)
            g = g + ca.mtimes(WS.T, X[:, j] - XR[:, j] + c)
        if j < N:
            A = Ax[:, nx * j:nx * (j + 1)]
            S = ca.mtimes(A, S) + ca.mtimes(Bu[:, j], eye[j, :])
            c = ca.mtimes(A, c) + Xn[:, j] - X[:, j + 1]
    # the QP scaled to a unit Hessian diagonal (same solution): the weights of the modal states reach
    # 1e10 on a rig, and the solvers' tolerances are absolute (unscaled, qrqp cycled on servo_link at 1.1 T*)
    scale = 1.0 / ca.mmax(ca.diag(H))
    H, g = scale * H, scale * g
    H = 0.5 * (H + H.T)
    lbx, ubx = -tau_max - U.T, tau_max - U.T
    if current is not None and current[3] == 1:   # the first move's current: a bound
        bound, first = current[2], ca.DM.eye(N)[:, 0]
        lbx = lbx + first * (ca.fmax(lbx[0], -bound - values[0]) - lbx[0])
        ubx = ubx + first * (ca.fmin(ubx[0], bound - values[0]) - ubx[0])
    if current is not None and current[3] == 1:   # the first move's current is a bound, not a row
        rows, values, bounds = rows[1:], values[1:], bounds[1:]
    if rows:                  # each row over its bound: the rows and their residuals as shares of the limits
        inv = 1.0 / ca.vertcat(*bounds)
        Ac, val = ca.mtimes(ca.diag(inv), ca.vertcat(*rows)), inv * ca.vertcat(*values)
        lba, uba = -1.0 - val, 1.0 - val
    else:
        Ac, lba, uba = ca.MX(0, N), ca.MX(0, 1), ca.MX(0, 1)
    qp = ca.conic("nmpc_qp", qp_solver, {"h": ca.Sparsity.dense(N, N), "a": ca.Sparsity.dense(Ac.size1(), N)},
                  _QP_OPTIONS[qp_solver])
    sol = qp(h=H, g=g, a=Ac, lba=lba, uba=uba, lbx=lbx, ubx=ubx)
    dU = sol["x"]
    residual = _kkt_residual(H, g, Ac, dU, sol["lam_x"], sol["lam_a"], (lbx, ubx), (lba, uba))
    c = x - X[:, 0]
    cols = [x]
    for j in range(N):                         # the new plan, rolled out along the linearisation
        c = ca.mtimes(Ax[:, nx * j:nx * (j + 1)], c) + Bu[:, j] * dU[j] + Xn[:, j] - X[:, j + 1]
        cols.append(X[:, j + 1] + c)
    return ca.Function("nmpc_rti", [measured, X, U, XR, UR, Q, P, *extra, *late],
                       [ca.horzcat(*cols), U + dU.T, residual],
                       ["x", "X", "U", "XR", "UR", "Q", "P", *(["p"] if parametric else []),
                        *(["u_prev"] if late else [])], ["X_next", "U_next", "qp_residual"])


#: Options of each QP plugin in the step: quiet, and no exception on failure (the step's
#: ``qp_residual`` says whether the answer solves the QP).
_QP_OPTIONS = {
    "daqp": {"error_on_fail": False},
    "qrqp": {"print_iter": False, "print_header": False, "print_info": False, "error_on_fail": False},
}


def _kkt_residual(H, g, A, z, lam_x, lam_a, box: tuple, rows: tuple):
    """The largest violation of the QP's optimality conditions at ``(z, lam_x, lam_a)`` (CasADi's
    sign convention: a positive multiplier on an upper bound, a negative one on a lower bound)."""
    (lbx, ubx), (lba, uba) = box, rows
    parts = [ca.mmax(ca.fabs(ca.mtimes(H, z) + g + lam_x + ca.mtimes(A.T, lam_a))),
             ca.mmax(ca.fmax(lbx - z, z - ubx)),
             ca.mmax(ca.fmin(ca.fmax(lam_x, 0), ubx - z)), ca.mmax(ca.fmin(ca.fmax(-lam_x, 0), z - lbx))]
    if A.size1():
        Az = ca.mtimes(A, z)
        parts += [ca.mmax(ca.fmax(lba - Az, Az - uba)),
                  ca.mmax(ca.fmin(ca.fmax(lam_a, 0), uba - Az)), ca.mmax(ca.fmin(ca.fmax(-lam_a, 0), Az - lba))]
    return ca.fmax(0, ca.mmax(ca.vertcat(*parts)))
