"""Linear MPC on the sampled SFOAM: a condensed dense QP built once, solved each step.

The decision variables are the ``N`` torques of the horizon (plus one slack when the tip
deflection is soft-bounded). With ``X = Phi x0 + Gamma U`` the predicted states
``x_1..x_N`` and the reference ``X_r``, ``U_ff`` of the horizon, the QP is::

    min  (X - X_r)' Qb (X - X_r) + (U - U_ff)' Rb (U - U_ff) + w_s s^2
    s.t. -tau_max <= U <= tau_max                      (hard)
         |c_tip x_i| <= v_max + s,  s >= 0,  i = 1..N  (soft, optional)

``Qb = diag(Q, .., Q, P)`` with ``P`` the LQR Riccati solution (terminal cost), so the
Hessian and the constraint matrix are fixed and only the gradient and the constraint
bounds change with the measured state. By default (``solver="daqp"``) DAQP's own
workspace (the ``daqp`` package) holds the QP: set up once per controller, then only the
linear term and the bounds are updated each step, and the active set of the previous
solve warm-starts the next (:class:`DirectDAQP`; about 7 us per solve against ~30 us plus
argument conversion through CasADi). CasADi's ``conic`` interface is kept for the other
solvers (``daqp-casadi``, qpOASES, qrqp, OSQP), warm-started with the shifted previous
plan. A failed solve falls back to the saturated LQR torque; :meth:`MPC.stats` counts them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.settings import setting

from .base import Controller, DesignModel, LQSettings, Reference, saturate
from .lqr import dlqr_gain
from .residual import residual_design

__all__ = ["MPCSettings", "MPC", "QP_SOLVERS", "condensed_matrices", "DirectDAQP"]

#: QP solvers :class:`MPC` accepts: ``daqp`` is DAQP called directly (:class:`DirectDAQP`),
#: the others are plugins of CasADi's ``conic`` with their quiet options.
QP_SOLVERS = {
    "daqp": {},
    "daqp-casadi": {},
    "qpoases": {"printLevel": "none", "sparse": False, "error_on_fail": False},
    "qrqp": {"print_iter": False, "print_header": False, "print_info": False,
             "error_on_fail": False},
    "osqp": {"osqp": {"verbose": False, "eps_abs": 1e-7, "eps_rel": 1e-7, "max_iter": 20000},
             "error_on_fail": False},
}
#: Solvers not called through CasADi, and the ``conic`` plugin behind each other name.
DIRECT_SOLVERS = ("daqp",)
_CONIC_PLUGIN = {"daqp-casadi": "daqp"}


@dataclass(frozen=True)
class MPCSettings(LQSettings):
    """Settings of :class:`MPC`: those of LQR plus the horizon, the tip bound and the solver.

    The stage weights are ``weights``; the terminal weight is their LQR Riccati solution.
    ``tau_max`` is a hard constraint of the QP; ``feedforward`` makes the reference's
    feedforward torque the torque reference of the cost.
    """

    horizon: int = setting(50, unit="samples", lo=1, hi=5000, doc="Prediction horizon N.")
    tip_bound: float | None = setting(None, unit="m", lo=0.0, lo_open=True, kind=float,
                                      doc="Soft bound on abs(v_tip) over the horizon; None: no bound.")
    tip_bound_weight: float = setting(1e8, unit="1/m^2", lo=0.0, lo_open=True,
                                      doc="Quadratic penalty on the bound's violation (same scale as "
                                          "the weights).")
    solver: str = setting("daqp", choices=QP_SOLVERS, doc="QP solver of CasADi's conic (QP_SOLVERS).")
    emf_torque_limit: float | None = setting(None, unit="N m", lo=0.0, lo_open=True, kind=float,
                                             doc="A DC drive's voltage limit as a torque: the torque per "
                                                 "volt times V_max. With emf_damping the plan keeps "
                                                 "abs(tau + emf_damping theta_dot) within it at every "
                                                 "step (the voltage limit through back-EMF); None: none.")
    emf_damping: float = setting(0.0, unit="N m s/rad", lo=0.0,
                                 doc="The drive's back-EMF torque per hub rate (torque per volt times k_e N).")
    warm_start: bool = setting(True, doc="Start each QP from the previous plan, shifted by one sample.")


def condensed_matrices(Ad: np.ndarray, Bd: np.ndarray, N: int):
    """Prediction matrices of ``X = Phi x0 + Gamma U`` over ``N`` steps.

    Parameters
    ----------
    Ad : ndarray (nx, nx)
        Discrete state matrix.
    Bd : ndarray (nx, 1)
        Discrete input matrix [per N m].
    N : int
        Horizon [samples], >= 1.

    Returns
    -------
    Phi : ndarray (N nx, nx)
    Gamma : ndarray (N nx, N)
        Block lower-triangular, block ``(i, j) = Ad^(i-j) Bd`` for ``j <= i``.
    """
    nx = Ad.shape[0]
    Phi = np.zeros((N * nx, nx))
    Gamma = np.zeros((N * nx, N))
    Ak = np.eye(nx)
    powers_B = []
    for i in range(N):
        powers_B.append(Ak @ Bd[:, 0])        # Ad^i Bd
        Ak = Ad @ Ak
        Phi[i * nx:(i + 1) * nx] = Ak
    for i in range(N):
        for j in range(i + 1):
            Gamma[i * nx:(i + 1) * nx, j] = powers_B[i - j]
    return Phi, Gamma


class MPC(Controller):
    """Linear MPC with a hard torque limit and an optional soft tip-deflection bound.

    Parameters
    ----------
    design : DesignModel
        Sampled SFOAM at the design spin rate; its ``Ad``, ``Bd`` predict the horizon.
    settings : MPCSettings, optional
        Horizon, QP solver and the soft tip bound, with the LQR's weights and torque limit.
    reference : Reference, optional
        Hub trajectory and feedforward torque over the horizon (default: rest at theta = 0).

    Attributes
    ----------
    K, P : ndarray
        LQR gain (fallback) and Riccati solution (terminal weight).
    solver : DirectDAQP or casadi.Function
        The QP solver, built once (DAQP's own workspace for ``solver="daqp"``, else a
        CasADi ``conic`` function).

    Examples
    --------
    >>> from controllers import DesignModel, MPC, MPCSettings
    >>> mpc = MPC(DesignModel.build(n_modes=2), MPCSettings(horizon=20))
    >>> mpc.reset(); x = np.zeros(6); x[0] = -0.01   # 10 mrad behind the reference
    >>> 0 < mpc(0.0, x) <= 200.0
    True
    """

    measurement = "state"

    def __init__(self, design: DesignModel, settings: MPCSettings | None = None,
                 reference: Reference | None = None):
        settings = settings or MPCSettings()
        model, self._weights = residual_design(design, settings.weights, settings.residual_modes) \
            if settings.residual_control \
            else (design, settings.weights)
        super().__init__(model, settings, reference)
        self.n_modes = design.n_modes           # the design's; the plan runs on model.n_modes
        design = model
        s = settings
        N = s.horizon
        self.K, self.P, H, self._Gx, self._Gr, Phi, Gamma, scale = self._condensed_qp(design)
        self._ff = 1.0 if s.feedforward else 0.0
        # g = Gx x0 - ref_term[k]: the reference part of the gradient for every sample
        self._prepare_reference(s.elastic_reference, extra=N + 1)
        self._ref_term = self._reference_terms()
        soft = s.tip_bound is not None
        nz = N + (1 if soft else 0)
        if soft:
            # Scaled for the active-set solvers (DAQP returns infeasible plans on badly
            # scaled QPs): the slack is measured in units that give it the Hessian entry
            # of an average torque, and every constraint row is normalised.
            c_tip = design.C_tip[0]
            Ct = np.kron(np.eye(N), c_tip[None, :])            # (N, N nx)
            CtG = Ct @ Gamma
            h_s = 2 * scale * s.tip_bound_weight
            sigma = math.sqrt(h_s / np.mean(np.diag(H)))        # s = s_scaled / sigma
            rows = np.hstack([CtG, np.full((N, 1), 1.0 / sigma)])
            self._row_scale = 1.0 / np.max(np.abs(rows), axis=1)
            self._CtPhi = (Ct @ Phi) * self._row_scale[:, None]   # (N, nx), scaled
            CtGs = CtG * self._row_scale[:, None]
            col = (self._row_scale / sigma)[:, None]
            A = np.block([[CtGs, -col], [CtGs, col]])
            self._sigma = sigma
            Hz = np.zeros((nz, nz))
            Hz[:N, :N] = H
            Hz[N, N] = h_s / sigma ** 2
            H = Hz
        elif s.solver == "qpoases":
            A = np.ones((1, nz))     # an always-inactive row: qpOASES keeps its factorisation
        else:
            A = np.zeros((0, nz))
        self._emf = None
        if s.emf_torque_limit is not None:
            # the voltage limit through back-EMF: |u_i + b theta_dot_i| <= g V_max, theta_dot_i the
            # rate at the start of step i (x0's for i = 0, the prediction's after)
            n, b = design.n_x // 2, float(s.emf_damping)
            rate = np.zeros((N, design.n_x * N))
            for i in range(1, N):
                rate[i, (i - 1) * design.n_x + n] = 1.0
            Av = np.eye(N) + b * rate @ Gamma
            scale_v = 1.0 / np.max(np.abs(Av), axis=1)
            Av *= scale_v[:, None]
            off_x = b * (rate @ Phi)
            off_x[0, n] = b
            self._emf = (off_x * scale_v[:, None], float(s.emf_torque_limit) * scale_v)
            if A.shape[0] == 1 and not soft:       # qpOASES's placeholder row is no longer needed
                A = np.zeros((0, nz))
            A = np.vstack([A, np.hstack([Av, np.zeros((N, nz - N))])])
        self._soft = soft
        self._H = ca.DM(H)
        self._A = ca.DM(A)
        self._n_a = A.shape[0]
        self._nz = nz
        lbx = np.full(nz, -self.tau_max)
        ubx = np.full(nz, self.tau_max)
        if soft:
            lbx[-1], ubx[-1] = 0.0, np.inf
        self._lbx, self._ubx = lbx, ubx
        if s.solver in DIRECT_SOLVERS:
            self.solver = DirectDAQP(H, A, lbx, ubx)
        else:
            self.solver = self._conic_solver(s.solver)
        self.reset()

    def feedback_matrices(self) -> tuple:
        """The unconstrained law as static state feedback ``u = -K_mpc e`` (no states).

        Without active bounds the plan's first move is ``-(H^-1 G_x)[0] x`` plus reference
        and feedforward terms; with the Riccati solution as terminal weight ``K_mpc`` equals
        the LQR gain. The torque limit and the soft tip bound are not part of it.
        """
        N, n = self.settings.horizon, self.design.n_x
        H = np.asarray(self._H.full(), dtype=float)[:N, :N]
        K = np.linalg.solve(H, self._Gx)[0]
        return (np.zeros((0, 0)), np.zeros((0, n)), np.zeros((1, 0)), -K[None, :], [],
                list(self.design.state_names))

    def _conic_solver(self, name: str) -> ca.Function:
        """CasADi ``conic`` solver of the QP's sparsity (built once)."""
        try:
            return ca.conic("mpc_qp", _CONIC_PLUGIN.get(name, name),
                            {"h": self._H.sparsity(), "a": self._A.sparsity()}, dict(QP_SOLVERS[name]))
        except RuntimeError as exc:
            raise ParameterError(f"solver {name!r} could not be created: "
                                 f"{str(exc).splitlines()[-1][:120]}") from None

    def _condensed_qp(self, design: DesignModel):
        """LQR gain and Riccati solution, the QP's Hessian and gradient matrices for ``design``.

        Returns ``(K, P, H, Gx, Gr, Phi, Gamma, scale)``: the gradient is
        ``Gx x0 - Gr X_r - 2 U_ff`` (cost scaled by ``scale = 1/R``).
        """
        s = self.settings
        N, nx = s.horizon, design.n_x
        K, P = dlqr_gain(design, self._weights)
        Q, R = self._weights.matrices(design)
        r = float(R[0, 0])
        Phi, Gamma = condensed_matrices(design.Ad, design.Bd, N)
        Qb = np.kron(np.eye(N), Q)
        Qb[-nx:, -nx:] = P
        scale = 1.0 / r                        # cost scaled so that the torque weight is 1
        GtQ = Gamma.T @ Qb
        H = 2 * scale * (GtQ @ Gamma + r * np.eye(N))
        H = 0.5 * (H + H.T)
        return K, P, H, 2 * scale * (GtQ @ Phi), 2 * scale * GtQ, Phi, Gamma, scale

    def _qp_data(self, k: int, y: np.ndarray):
        """Hessian and gradient of the QP at sample ``k`` for state ``y`` (a scheduled MPC
        interpolates them)."""
        return self._H, self._Gx @ y - self._reference_term(k)

    def _reference_terms(self, Gr: np.ndarray | None = None) -> np.ndarray:
        N, nx = self.settings.horizon, self.design.n_x
        X, U = self._xref, self._tff
        n_k = len(X) - N
        G3 = (self._Gr if Gr is None else Gr).reshape(N, N, nx)
        win = np.lib.stride_tricks.sliding_window_view(X[1:], N, axis=0)[:n_k]   # (k, nx, N)
        term = np.einsum("ijc,kcj->ki", G3, win, optimize=True)
        uwin = np.lib.stride_tricks.sliding_window_view(U, N)[:n_k]               # (k, N)
        return term + 2.0 * self._ff * uwin

    def _reference_term(self, k: int, table: np.ndarray | None = None, Gr: np.ndarray | None = None) -> np.ndarray:
        table = self._ref_term if table is None else table
        if k < len(table):
            return table[k]
        N = self.settings.horizon
        X = np.array([self._reference_at(k + 1 + i)[0] for i in range(N)])
        U = np.array([self._reference_at(k + i)[1] for i in range(N)])
        return (self._Gr if Gr is None else Gr) @ X.ravel() + 2.0 * self._ff * U

    def reset(self) -> None:
        """Forget the previous plan and multipliers (the next solve starts cold) and the counters."""
        self._z = np.zeros(self._nz)
        self._lam_x = np.zeros(self._nz)
        self._lam_a = np.zeros(self._n_a)
        self.n_solves = 0
        self.n_fallbacks = 0
        self.last_status = ""
        if isinstance(self.solver, DirectDAQP):
            self.solver.reset()

    @property
    def slack(self) -> float:
        """Violation of the soft tip bound in the last plan [m] (0 without a bound)."""
        return float(self._z[-1] / self._sigma) if self._soft else 0.0

    def stats(self) -> dict:
        """Counters of the run: QP solves, fallbacks to LQR and their fraction, solver status."""
        return {"qp_solves": self.n_solves, "qp_fallbacks": self.n_fallbacks,
                "fallback_fraction": self.n_fallbacks / self.n_solves if self.n_solves else 0.0,
                "solver": self.settings.solver, "horizon": self.settings.horizon}

    def plan(self, t: float, y) -> np.ndarray:
        """Solve the QP at time ``t`` [s] for state ``y``; return the planned torques [N m].

        Parameters
        ----------
        t : float
            Time [s] (selects the reference window).
        y : ndarray (nx,)
            Measured (or estimated) design-model state.

        Raises
        ------
        RuntimeError
            If the solver fails (the controller's call falls back to LQR instead).
        """
        s = self.settings
        N = s.horizon
        H, g, lba, uba = self._qp_at(t, y)
        if isinstance(self.solver, DirectDAQP):
            if H is not self._H:          # a scheduled design: the Hessian moves with the spin
                self.solver.update_hessian(H)
            z = self.solver.solve(g, lba, uba, warm_start=s.warm_start)
            self.last_status = self.solver.status
            self._z = z
            return z[:N]
        return self._plan_conic(H, g, lba, uba)

    def _qp_at(self, t: float, y: np.ndarray) -> tuple:
        """``(H, g, lba, uba)`` of the QP at time ``t`` [s] for state ``y``: Hessian, linear
        term (with the slack's), and the bounds of the constraint rows (None: no rows to
        bound). A multi-stage MPC (:mod:`controllers.msmpc`) stacks those of its scenarios."""
        s = self.settings
        N = s.horizon
        k = int(round(t / self.dt))
        H, g = self._qp_data(k, y)
        lba = uba = None
        if self._soft:
            g = np.append(g, 0.0)
            off = self._CtPhi @ y
            vmax = s.tip_bound * self._row_scale
            lba = np.concatenate([np.full(N, -np.inf), -vmax - off])
            uba = np.concatenate([vmax - off, np.full(N, np.inf)])
        elif self._n_a and self._emf is None:
            lba, uba = np.array([-np.inf]), np.array([np.inf])
        if self._emf is not None:
            off_x, limit = self._emf
            off = off_x @ y
            lo, hi = -limit - off, limit - off
            lba = lo if lba is None else np.concatenate([lba, lo])
            uba = hi if uba is None else np.concatenate([uba, hi])
        return H, g, lba, uba

    def _plan_conic(self, H, g, lba, uba) -> np.ndarray:
        """One solve through CasADi's ``conic``, warm-started with the shifted plan."""
        s = self.settings
        N = s.horizon
        args = {"h": H, "g": g, "a": self._A, "lbx": self._lbx, "ubx": self._ubx}
        if lba is not None:
            args["lba"], args["uba"] = lba, uba
        if s.warm_start:
            args["x0"] = np.append(self._z[1:], self._z[-1]) if not self._soft else \
                np.concatenate([self._z[1:N], [self._z[N - 1]], [self._z[N]]])
            args["lam_x0"] = self._lam_x
            if self._n_a:
                args["lam_a0"] = self._lam_a
        sol = self.solver(**args)
        st = self.solver.stats()
        self.last_status = str(st.get("return_status", ""))
        z = np.asarray(sol["x"]).ravel()
        if not st.get("success", False) or not np.all(np.isfinite(z)):
            raise RuntimeError(f"QP failed: {self.last_status}")
        self._z = z
        self._lam_x = np.asarray(sol["lam_x"]).ravel()
        if self._n_a:
            self._lam_a = np.asarray(sol["lam_a"]).ravel()
        return z[:N]

    def __call__(self, t: float, y) -> float:
        self.n_solves += 1
        y = np.asarray(y, dtype=float)
        try:
            u = self.plan(t, y)
            tau = float(u[0])
        except RuntimeError:
            self.n_fallbacks += 1
            self._z = np.zeros(self._nz)
            xr, tff = self._reference_at(int(round(t / self.dt)))
            tau = self._ff * tff - self.K @ (y - xr)
        return saturate(tau, self.tau_max)


class DirectDAQP:
    """DAQP's own workspace for a QP whose Hessian and constraint matrix never change.

    ``min 1/2 z' H z + g' z  s.t.  lbx <= z <= ubx,  lba <= A z <= uba``: set up once;
    each :meth:`solve` updates only the linear term ``g`` and the row bounds, and starts
    from the active set of the previous solve (DAQP's warm start).

    Parameters
    ----------
    H : ndarray (n, n)
        Positive definite Hessian.
    A : ndarray (m, n)
        Constraint rows (``m`` may be 0).
    lbx, ubx : ndarray (n,)
        Bounds of the variables (``inf`` allowed).

    Examples
    --------
    >>> qp = DirectDAQP(2 * np.eye(2), np.zeros((0, 2)), -np.ones(2), np.ones(2))
    >>> qp.solve(np.array([-1.0, 4.0])).round(6).tolist()
    [0.5, -1.0]
    """

    def __init__(self, H, A, lbx, ubx):
        import daqp

        self._H = np.ascontiguousarray(H, dtype=float)
        self._A = np.ascontiguousarray(A, dtype=float).reshape(-1, self._H.shape[0])
        n, m = self._H.shape[0], self._A.shape[0]
        self._n = n
        self._f = np.zeros(n)
        self._upper = np.concatenate([np.asarray(ubx, dtype=float), np.full(m, np.inf)])
        self._lower = np.concatenate([np.asarray(lbx, dtype=float), np.full(m, -np.inf)])
        self._model = daqp.Model()
        self._ready = False
        self.status = ""
        self.iterations = 0

    def reset(self) -> None:
        """Forget the previous active set: the next solve starts cold."""
        self._ready = False

    def update_hessian(self, H) -> None:
        """Replace the Hessian (a scheduled MPC's moves with the spin); the next solve starts cold.

        Parameters
        ----------
        H : array_like (n, n)
            Positive definite Hessian.
        """
        self._H = np.ascontiguousarray(np.asarray(H, dtype=float))
        self._ready = False

    def solve(self, g, lba=None, uba=None, warm_start: bool = True) -> np.ndarray:
        """Solve for the linear term ``g`` and row bounds ``lba``, ``uba`` (default: unchanged).

        Parameters
        ----------
        g : ndarray (n,)
        lba, uba : ndarray (m,), optional
        warm_start : bool
            Start from the previous active set (else DAQP starts cold).

        Returns
        -------
        ndarray (n,)
            The minimiser.

        Raises
        ------
        RuntimeError
            If DAQP reports a failure (infeasible, iteration limit, ...).
        """
        self._f[:] = g
        if lba is not None:
            self._lower[self._n:] = lba
            self._upper[self._n:] = uba
        if self._ready and warm_start:
            if lba is None:
                self._model.update(f=self._f)
            else:
                self._model.update(f=self._f, bupper=self._upper, blower=self._lower)
        else:
            self._model = type(self._model)()
            self._model.setup(self._H, self._f, self._A, self._upper, self._lower)
        x, _, flag, info = self._model.solve()
        self.iterations = int(info.get("iterations", 0))
        self.status = f"daqp exit flag {flag}"
        self._ready = flag > 0
        x = np.asarray(x, dtype=float)
        if flag <= 0 or not np.isfinite(x).all():
            raise RuntimeError(f"QP failed: {self.status}")
        return x
