"""Nonlinear MPC on the beam's own model by real-time iteration (issue 40, first slice).

The prediction model is FOAM itself (the energies of :mod:`hubbeam_ctrl.plant.parametric`,
Lagrange's equations by CasADi's automatic differentiation, the axial coordinates
quasi-static) with the bending modes of the design model that the sample rate resolves
(below the Nyquist frequency, :attr:`NMPCSettings.modes`), so the stiffening with the hub
rate and the tip mass's coupling are in the prediction, not linearised about one spin rate.

Each sample solves **one** Gauss-Newton SQP step (real-time iteration) of the multiple-shooting
problem over ``horizon`` samples:

* the shooting map ``x+ = F(x, u)`` is RK4 over ``substeps`` per sample (enough substeps that
  the fastest modelled mode stays inside RK4's stability region), built once as a CasADi
  function with its Jacobians;
* the cost is the LQR's: ``sum (x - x_ref)' Q (x - x_ref) + R (u - u_ff)^2`` along the task's
  reference and feedforward, and the terminal cost ``(x - x_ref)' P (x - x_ref)`` with ``P``
  the Riccati solution of the LQR of the same weights on the design model at rest (so the
  NMPC's linear form at the end point is that LQR: :meth:`NMPC.feedback_matrices`, which the
  certificate closes);
* the QP in the step's deltas (dynamics linearised at the shifted previous solution, the
  torque bounds ``|u| <= tau_max`` as simple bounds) is solved by a QP plugin of CasADi
  (:data:`QP_PLUGINS`; OSQP by default, linked through CasADi, not copied), warm-started by
  the shift.

The command is the first move. The NMPC reads the design model's state (``measurement ==
"state"``): on a rig the comparison closes it through the same Kalman filter as LQR and MPC.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import casadi as ca
import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.settings import setting

from .base import Controller, DesignModel, LQSettings, Reference, saturate

__all__ = ["NMPCSettings", "NMPC", "QP_PLUGINS", "NMPC_MODES", "rk4_substeps"]

#: Solvers of the step's condensed QP.
QP_PLUGINS = ("daqp",)
#: Bending modes of the prediction model by default (:attr:`NMPCSettings.modes`).
NMPC_MODES = 2
#: RK4 keeps ``|lambda h|`` below this for the fastest modelled mode (its stability limit on the
#: imaginary axis is 2.83).
RK4_REACH = 1.5


@dataclass(frozen=True)
class NMPCSettings(LQSettings):
    """Settings of :class:`NMPC` (weights, torque limit, feedforward shared with LQR and MPC)."""

    horizon: int = setting(20, lo=2, hi=400, doc="Prediction horizon [samples].")
    modes: int | None = setting(None, kind=int, lo=1, hi=20,
                                doc="Bending modes of the prediction model; None: the design model's modes "
                                    "below the Nyquist frequency, at most NMPC_MODES (a step's cost grows with "
                                    "the cube of the model's size: 3.4 ms with 2 modes, 6.4 ms with 3 on "
                                    "Table 1's beam, CasADi's virtual machine).")
    substeps: int | None = setting(None, kind=int, lo=1, hi=200,
                                   doc="RK4 substeps per sample; None: enough for the fastest modelled mode "
                                       "(rk4_substeps).")
    backend: str = setting("vm", choices=("auto", "compiled", "vm"),
                           doc="The shooting map on CasADi's virtual machine (vm, the default: no build) or as "
                               "generated C (auto/compiled: when a C compiler is there; built once and cached, "
                               "minutes for a large model).")
    @classmethod
    def for_scenario(cls, scenario, **options) -> "NMPCSettings":
        """The task's settings (as LQR's), keeping the NMPC's own horizon and QP solver: the study-wide
        ``horizon`` and ``solver`` are the linear MPC's (a 50-sample horizon would double the step).

        Parameters
        ----------
        scenario : Scenario
        **options
            Study-wide controller options; ``horizon`` and ``solver`` are left out.

        Returns
        -------
        NMPCSettings
        """
        options = {k: v for k, v in options.items() if k not in ("horizon", "solver")}
        return super().for_scenario(scenario, **options)

    qp_solver: str = setting("daqp", choices=QP_PLUGINS, doc="Solver of the step's condensed QP (DAQP, linked: "
                                                               "the daqp package).")


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


def _model_modes(design: DesignModel, modes: int | None) -> tuple:
    """``(modes, omega of each)``: the prediction model's bending modes and their frequencies [rad/s]."""
    lam = np.linalg.eigvals(design.A)
    w = np.sort(np.unique(np.round(np.abs(lam.imag[lam.imag > 1e-9]), 9)))
    if modes is None:
        modes = min(NMPC_MODES, max(1, int(np.sum(w < math.pi / design.dt))))
    modes = min(int(modes), design.n_modes)
    return modes, w[:modes]


class NMPC(Controller):
    """Real-time-iteration NMPC on the reduced FOAM of the design (see the module docstring).

    Parameters
    ----------
    design : DesignModel
        The design model (its parameters, sample time and modes; spin 0: a slew).
    settings : NMPCSettings, optional
    reference : Reference, optional
        The task's reference and feedforward (default: rest at theta = 0).

    Attributes
    ----------
    K, P : ndarray
        The LQR gain and Riccati solution of the same weights on the design model (``P``, on the
        predicted states, is the terminal cost).
    K_end : ndarray
        The step's linear law at the end point (:meth:`feedback_matrices`).
    step_times_s : list of float
        Wall time of each step [s].
    """

    measurement = "state"

    def __init__(self, design: DesignModel, settings: NMPCSettings | None = None,
                 reference: Reference | None = None):
        from hubbeam_ctrl.plant.models import build_model
        settings = settings or NMPCSettings()
        if abs(design.spin) > 0.0:
            raise ParameterError(f"design spin must be 0 for the NMPC (it predicts the whole motion from rest), "
                                 f"got {design.spin:g} rad/s")
        # the LQR of the same settings (its gain on the plant's modes when residual_control asks for
        # them): the modes the prediction leaves out get its action (K_res), added to the first move
        from .lqr import LQR, LQRSettings
        common = {f: getattr(settings, f) for f in LQRSettings.__dataclass_fields__ if hasattr(settings, f)}
        lqr = LQR(design, LQRSettings(**common), reference)
        super().__init__(lqr.design, settings, reference)
        self.n_modes = design.n_modes
        self.K, self.P = lqr.K, lqr.P
        self._ff = 1.0 if settings.feedforward else 0.0
        self._prepare_reference(settings.elastic_reference, extra=settings.horizon + 1)
        m, w = _model_modes(design, settings.modes)
        self.model_modes = m
        self.substeps = settings.substeps or rk4_substeps(float(w.max()) if w.size else 0.0, self.dt)
        model = build_model("foam", design.params.replace(n_transverse=m), axial="quasi-static")
        n = model.n_q                       # theta and m modal coordinates
        self._n, self._nx = n, 2 * n
        # the (residual) design state's rows this model uses: theta, q2_1..m, theta_dot, q2_dot_1..m
        h = self.design.n_x // 2
        self._pick = np.r_[0, 1:1 + m, h, h + 1:h + 1 + m]
        # the LQR's gain on the states the prediction leaves out (the residual modes): added to the move
        self._K_res = self.K.copy()
        self._K_res[self._pick] = 0.0
        Q, R = settings.weights.matrices(design)            # the stage weights on the design model's states
        hd = design.n_x // 2
        pick_d = np.r_[0, 1:1 + m, hd, hd + 1:hd + 1 + m]
        self._Q = Q[np.ix_(pick_d, pick_d)]
        self._R = float(np.asarray(R).reshape(-1)[0])
        self._Pt = np.asarray(self.P)[np.ix_(self._pick, self._pick)]
        from hubbeam_ctrl.core.compiled import compile_function
        self._F = compile_function(self._shooting(model), settings.backend)      # C when a compiler is there
        self._build_qp(settings)
        self.K_end = self._end_gain()
        self.step_times_s = []
        self.reset()

    # -- construction -------------------------------------------------------------
    def _shooting(self, model) -> ca.Function:
        """``(x, u) -> (x+, dx+/dx, dx+/du)``: RK4 over the sample in ``substeps`` steps."""
        n, nx = self._n, self._nx
        x, u = ca.SX.sym("x", nx), ca.SX.sym("u")      # scalar expressions: no linear-solver call inside
        Mf, cf = model.mass_matrix_function, model.bias_function
        B = np.zeros(n)
        B[0] = 1.0

        def f(z):
            q, v = z[:n], z[n:]
            return ca.vertcat(v, ca.solve(Mf(q, v), B * u - cf(q, v)))

        h = self.dt / self.substeps
        z = x
        for _ in range(self.substeps):
            k1 = f(z)
            k2 = f(z + h / 2 * k1)
            k3 = f(z + h / 2 * k2)
            k4 = f(z + h * k3)
            z = z + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        return ca.Function("nmpc_shoot", [x, u], [z, ca.jacobian(z, x), ca.jacobian(z, u)], {"cse": True})

    def _build_qp(self, s: NMPCSettings) -> None:
        """The per-stage weights of the condensed QP and the stages' map (built once)."""
        N = s.horizon
        self._W = [self._Q] * N + [self._Pt]          # stage weights on x_0 .. x_N
        self._F_map = self._F.map(N)

    def reset(self) -> None:
        """Start from the reference: the previous solution is the planned motion."""
        N = self.settings.horizon
        X = np.array([self._xref[min(k, len(self._xref) - 1)][self._pick] for k in range(N + 1)])
        self._X = X.T.copy()                                  # (nx, N + 1)
        self._U = np.array([self._reference_at(k)[1] * self._ff for k in range(N)], dtype=float)
        self._k_last = None

    # -- the step ------------------------------------------------------------------
    def __call__(self, t: float, y) -> float:
        """Hub torque [N m] at time ``t`` [s] from the design-ordered state ``y``."""
        start = time.perf_counter()
        s = self.settings
        N, nx = s.horizon, self._nx
        k = int(round(t / self.dt))
        if self._k_last is not None and k > self._k_last:        # shift the previous solution
            shift = min(k - self._k_last, N)
            self._X = np.hstack([self._X[:, shift:], np.repeat(self._X[:, -1:], shift, axis=1)])
            self._U = np.r_[self._U[shift:], np.repeat(self._U[-1:], shift)]
        self._k_last = k
        x_meas = np.asarray(y, dtype=float)[self._pick]
        xr = np.array([self._reference_at(k + j)[0][self._pick] for j in range(N + 1)])
        ur = np.array([self._reference_at(k + j)[1] * self._ff for j in range(N)])
        Xn, Ax, Bu = (np.asarray(M) for M in self._F_map(self._X[:, :N], self._U[None, :]))
        # condense: dX_j = S_j dU + c_j, with dX_0 = x_meas - X_0 and the stages' defects
        S = np.zeros((nx, N))
        c = x_meas - self._X[:, 0]
        H = self._R * np.eye(N)
        g = self._R * (self._U - ur)
        for j in range(N + 1):
            z = self._X[:, j] - xr[j] + c
            if j > 0:
                WS = self._W[j] @ S
                H += S.T @ WS
                g += WS.T @ z
            if j < N:
                Aj, Bj = Ax[:, nx * j:nx * (j + 1)], Bu[:, j]
                S = Aj @ S
                S[:, j] += Bj
                c = Aj @ c + Xn[:, j] - self._X[:, j + 1]
        dU = self._box_qp(0.5 * (H + H.T), g, -self.tau_max - self._U, self.tau_max - self._U)
        if dU is not None:
            U = self._U + dU
            X = np.empty_like(self._X)             # the new plan: the stages rolled out with U (one more pass)
            X[:, 0] = x_meas
            S = np.zeros((nx, N))
            c = x_meas - self._X[:, 0]
            X[:, 0] = self._X[:, 0] + c
            for j in range(N):
                Aj, Bj = Ax[:, nx * j:nx * (j + 1)], Bu[:, j]
                c = Aj @ c + Bj * dU[j] + Xn[:, j] - self._X[:, j + 1]
                X[:, j + 1] = self._X[:, j + 1] + c
            self._X, self._U = X, U
        e = np.asarray(y, dtype=float) - self._reference_at(k)[0]
        u0 = saturate(float(self._U[0] - self._K_res @ e), self.tau_max)
        self.step_times_s.append(time.perf_counter() - start)
        return u0

    def _end_gain(self) -> np.ndarray:
        """The step's unconstrained law at the end point, ``u = -K e`` on the design state: the
        condensed QP of :meth:`__call__` with the plan at rest on the target (no defects), its
        dynamics linearised there, on the predicted states; the LQR's gain on the others."""
        N, nx = self.settings.horizon, self._nx
        x_end = np.asarray(self._xref[-1], dtype=float)[self._pick].copy()
        x_end[self._n:] = 0.0
        _, A, B = (np.asarray(M) for M in self._F(x_end, 0.0))
        B = B.ravel()
        S, Phi = np.zeros((nx, N)), np.eye(nx)
        H, G = self._R * np.eye(N), np.zeros((N, nx))
        for j in range(N + 1):
            if j > 0:
                H += S.T @ self._W[j] @ S
                G += S.T @ self._W[j] @ Phi
            if j < N:
                S = A @ S
                S[:, j] += B
                Phi = A @ Phi
        k_pick = np.linalg.solve(0.5 * (H + H.T), G)[0]
        K = self._K_res.copy()
        K[self._pick] = k_pick
        return K

    def _box_qp(self, H, g, lo, hi):
        """``min 1/2 dU' H dU + g' dU`` within ``lo <= dU <= hi`` (DAQP, dense); None if it fails."""
        import daqp
        n = len(g)
        x, _, flag, _ = daqp.solve(np.ascontiguousarray(H), np.ascontiguousarray(g), np.zeros((0, n)),
                                   np.ascontiguousarray(hi), np.ascontiguousarray(lo), np.zeros(n, dtype=np.int32))
        self.qp_status = int(flag)
        x = np.asarray(x, dtype=float)
        return x if flag > 0 and np.all(np.isfinite(x)) else None

    def feedback_matrices(self) -> tuple:
        """The NMPC's linear form at the end point (:attr:`K_end`: its step's unconstrained law there,
        the dynamics linearised at rest on the target), a static state feedback ``u = -K e`` on the
        design model's states; the modes it does not predict get no gain (what the certificate closes)."""
        n = self.design.n_x
        return (np.zeros((0, 0)), np.zeros((0, n)), np.zeros((1, 0)), -self.K_end[None, :], [],
                list(self.design.state_names))
