"""One real-time iteration of the NMPC as a CasADi function, and the RK4 substeps of its shooting map.

:func:`rti_step_function` is the whole step of :class:`controllers.NMPC` (the Python step calls
it; :func:`hubbeam_ctrl.deploy.nmpc_c.nmpc_to_c` generates its C): the shooting map linearised
along the previous plan, the condensed QP solved by CasADi's ``qrqp`` and the new plan.
"""

from __future__ import annotations

import math

import casadi as ca

__all__ = ["RK4_REACH", "rk4_substeps", "rti_step_function"]

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


def rti_step_function(shooting: ca.Function, horizon: int, nx: int, r: float, tau_max: float,
                      parametric: bool = False, current: tuple | None = None,
                      in_flight: ca.Function | None = None) -> ca.Function:
    """One real-time iteration of the NMPC as a CasADi function (its C is the generated step).

    ``(x, X, U, XR, UR, Q, P[, p]) -> (X+, U+)``: the shooting map linearised along the
    previous plan ``(X, U)`` (``nx x N+1``, ``1 x N``), the condensed QP in the moves' deltas
    (cost ``sum |x_j - XR_j|^2_Q + r (u_j - UR_j)^2 + |x_N - XR_N|^2_P``, dynamics with the
    stages' defects, ``|u| <= tau_max``) solved by CasADi's active-set ``qrqp``, and the new plan
    rolled out along the linearisation from the measured state ``x``.

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
    rows, values = [], []                       # the current limit's rows on dU and values at dU = 0
    for j in range(N + 1):
        if current is not None and j < current[3]:
            row, emf = current[:2]
            rows.append(eye[j, :] - emf * S[row, :])
            values.append(U[j] - emf * (X[row, j] + c[row]))
        if j > 0:
            WS = ca.mtimes(P if j == N else Q, S)
            H = H + ca.mtimes(S.T, WS)
            g = g + ca.mtimes(WS.T, X[:, j] - XR[:, j] + c)
        if j < N:
            A = Ax[:, nx * j:nx * (j + 1)]
            S = ca.mtimes(A, S) + ca.mtimes(Bu[:, j], eye[j, :])
            c = ca.mtimes(A, c) + Xn[:, j] - X[:, j + 1]
    opts = {"print_iter": False, "print_header": False, "print_info": False, "error_on_fail": False}
    lbx, ubx = -tau_max - U.T, tau_max - U.T
    if current is not None and current[3] == 1:   # the first move's current: a bound
        bound, first = current[2], ca.DM.eye(N)[:, 0]
        lbx = lbx + first * (ca.fmax(lbx[0], -bound - values[0]) - lbx[0])
        ubx = ubx + first * (ca.fmin(ubx[0], bound - values[0]) - ubx[0])
    if current is None or current[3] == 1:
        qp = ca.conic("nmpc_qp", "qrqp", {"h": ca.Sparsity.dense(N, N), "a": ca.Sparsity(0, N)}, opts)
        dU = qp(h=0.5 * (H + H.T), g=g, lbx=lbx, ubx=ubx)["x"]
    else:
        Ac, val, bound = ca.vertcat(*rows), ca.vertcat(*values), current[2]
        qp = ca.conic("nmpc_qp", "qrqp", {"h": ca.Sparsity.dense(N, N), "a": ca.Sparsity.dense(len(rows), N)}, opts)
        dU = qp(h=0.5 * (H + H.T), g=g, a=Ac, lba=-bound - val, uba=bound - val, lbx=lbx, ubx=ubx)["x"]
    c = x - X[:, 0]
    cols = [x]
    for j in range(N):                         # the new plan, rolled out along the linearisation
        c = ca.mtimes(Ax[:, nx * j:nx * (j + 1)], c) + Bu[:, j] * dU[j] + Xn[:, j] - X[:, j + 1]
        cols.append(X[:, j + 1] + c)
    return ca.Function("nmpc_rti", [measured, X, U, XR, UR, Q, P, *extra, *late], [ca.horzcat(*cols), U + dU.T],
                       ["x", "X", "U", "XR", "UR", "Q", "P", *(["p"] if parametric else []),
                        *(["u_prev"] if late else [])], ["X_next", "U_next"])
