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
  torque bounds ``|u| <= tau_max`` as simple bounds) is condensed and solved by CasADi's
  active-set ``qrqp`` (:data:`QP_PLUGINS`) inside one CasADi function of the whole step
  (:func:`rti_step_function`), warm-started by the shift: the Python step calls it, and its
  generated C (:func:`hubbeam_ctrl.deploy.nmpc_c.nmpc_to_c`) is the same step.

**Unknown payload** (``learn_payload``): each sample the payload is fitted to the hub's
angular-momentum balance (:class:`controllers.payload_estimate.PayloadMomentum`: the torque's
impulse against the momentum of the measured state, exact whatever the modes the prediction
leaves out), the shooting map predicts with that payload's parameter vector (a table over the
range, no model built during the slew) and the reference is the task planned again for it
(:func:`controllers.planning.replanned` on :data:`REFERENCE_POINTS` payloads over the range
before the slew, interpolated at the estimate). No separate re-planning step: the estimate
converges in the slew's first 0.05-0.2 s (``benchmarks/bench_nmpc_payload.py``).

The command is the first move. The NMPC reads the design model's state (``measurement ==
"state"``): on a rig the comparison closes it through the same Kalman filter as LQR and MPC.

With a rig's DC drive (``hardware=``) the command is in volts and the drive, viscous friction, current
limit and delay are in the prediction (:mod:`controllers.nmpc_drive`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import NamedTuple

import casadi as ca
import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.settings import setting

from .base import Controller, DesignModel, LQSettings, Reference, saturate
from .nmpc_drive import DrivePrediction
from .nmpc_rti import RK4_REACH, rk4, rk4_substeps, rti_step_function, shooting_function

__all__ = ["NMPCSettings", "NMPC", "QP_PLUGINS", "NMPC_MODES", "rk4_substeps", "rti_step_function", "RK4_REACH"]

#: Solvers of the step's condensed QP.
QP_PLUGINS = ("daqp", "qrqp")
#: A step whose QP answer violates the QP's optimality conditions by more than this share of the
#: command limit (``qp_residual`` of :func:`rti_step_function`) keeps the shifted plan.
QP_RESIDUAL_TOL = 1e-6
#: Bending modes of the prediction model by default (:attr:`NMPCSettings.modes`).
NMPC_MODES = 2
#: Payloads over the range on which a learning NMPC plans its task again before the slew (the
#: reference is interpolated between them at the estimate).
REFERENCE_POINTS = 17


@dataclass(frozen=True)
class NMPCSettings(LQSettings):
    """Settings of :class:`NMPC` (weights, torque limit, feedforward shared with LQR and MPC)."""

    horizon: int = setting(20, lo=2, hi=400, doc="Prediction horizon [samples].")
    modes: int | None = setting(None, kind=int, lo=1, hi=20,
                                doc="Bending modes of the prediction model; None: the design model's modes "
                                    "below the Nyquist frequency, at most NMPC_MODES (a step's cost grows with "
                                    "the cube of the model's size: 3.4 ms with 2 modes, 6.4 ms with 3 on "
                                    "Table 1's beam, CasADi's virtual machine).")
    axial_modes: int | None = setting(None, kind=int, lo=1, hi=20,
                                      doc="Axial assumed modes of the prediction model's quasi-static axial "
                                          "condensation; None: as many as its bending modes (with 2 of 5 the "
                                          "stiffened bending frequencies at 0-10 rad/s are unchanged to 1e-5 and "
                                          "a stage costs a third of the instructions).")
    substeps: int | None = setting(None, kind=int, lo=1, hi=200,
                                   doc="RK4 substeps per sample; None: enough for the fastest modelled mode "
                                       "(rk4_substeps).")
    backend: str = setting("vm", choices=("auto", "compiled", "vm"),
                           doc="The step (rti_step_function) on CasADi's virtual machine (vm, the default: no "
                               "build) or as its generated C (auto/compiled: when a C compiler is there; built "
                               "once and cached: 30 s for Table 1's 2-mode model).")
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

    jacobian: str = setting("linearised", choices=("linearised", "exact"),
                            doc="The shooting map's Jacobians in the step's QP: RK4 of the model linearised at the "
                                "stage's start (linearised: a quarter of the instructions, the C step 2.2 x faster "
                                "on servo_link) or the exact derivative of the RK4 map (exact). The map itself, "
                                "the defects and the prediction, is RK4 of the nonlinear model either way.")
    qp_solver: str = setting("daqp", choices=QP_PLUGINS,
                             doc="Solver of the step's condensed QP, through CasADi's conic inside the step's "
                                 "function: DAQP (a dual active set for dense QPs; the generated C links the "
                                 "static library in CasADi's wheel) or CasADi's own qrqp (which cycled on a rig).")
    tip_limit_m: float | None = setting(None, unit="m", lo=0.0, lo_open=True, kind=float,
                                        doc="Largest tip deflection (absolute value of v(L, t)) the prediction "
                                            "allows [m]: a constraint of the step's QP on every predicted state "
                                            "(the prediction model's modes); None: none.")
    rate_limit: float | None = setting(None, unit="rad/s", lo=0.0, lo_open=True, kind=float,
                                       doc="Largest hub rate (absolute value) the prediction allows [rad/s]: a "
                                           "constraint of the step's QP on every predicted state; None: none.")
    current_limit: str = setting("path", choices=("path", "first"),
                                 doc="A DC drive's current limit: a linear constraint at every stage (path), or a "
                                     "bound on the first move only (first: a box QP; the prediction clips it).")
    learn_payload: bool = setting(False, doc="Estimate the payload online from the hub's momentum balance "
                                             "(controllers.payload_estimate.PayloadMomentum), predict with it and "
                                             "follow the task planned for it; payload_min_kg..payload_max_kg.")
    payload_min_kg: float = setting(0.0, unit="kg", lo=0.0, doc="Lightest payload the estimate may take.")
    payload_max_kg: float | None = setting(None, unit="kg", lo=0.0, hi=1e6,
                                           doc="Heaviest payload the estimate may take; None: the design's payload "
                                               "plus the beam's mass.")
    payload_momentum_error: float = setting(1e-7, lo=1e-12, hi=1.0,
                                            doc="Standard deviation of the momentum balance per sample, as a share "
                                                "of the reference's peak momentum (J_total times its peak rate; "
                                                "controllers.payload_estimate.PayloadMomentum): how much the "
                                                "estimator trusts each sample.")

    def __post_init__(self):
        super().__post_init__()
        if (self.learn_payload and self.payload_max_kg is not None
                and not self.payload_max_kg > self.payload_min_kg):
            raise ParameterError(f"payload_max_kg must be > payload_min_kg = {self.payload_min_kg:g} kg, "
                                 f"got {self.payload_max_kg:g}")


def _model_modes(design: DesignModel, modes: int | None) -> tuple:
    """``(modes, omega of each)``: the prediction model's bending modes and their frequencies [rad/s]."""
    lam = np.linalg.eigvals(design.A)
    w = np.sort(np.unique(np.round(np.abs(lam.imag[lam.imag > 1e-9]), 9)))
    if modes is None:
        modes = min(NMPC_MODES, max(1, int(np.sum(w < math.pi / design.dt))))
    modes = min(int(modes), design.n_modes)
    return modes, w[:modes]


class _PayloadGrid(NamedTuple):
    """What a learning NMPC interpolates at its estimate, on payloads over the range: stage and
    terminal weights and residual-mode gain of each payload's LQR, the task planned for each
    (design states and feedforward torques; None when the reference is not a plan)."""

    masses: np.ndarray
    stage: np.ndarray
    terminal: np.ndarray
    residual_gain: np.ndarray
    states: np.ndarray | None
    torques: np.ndarray | None


class NMPC(DrivePrediction, Controller):
    """Real-time-iteration NMPC on the reduced FOAM of the design (see the module docstring).

    Parameters
    ----------
    design : DesignModel
        The design model (its parameters, sample time and modes; spin 0: a slew).
    settings : NMPCSettings, optional
    reference : Reference, optional
        The task's reference and feedforward (default: rest at theta = 0).
    hardware : Hardware, optional
        A rig with a DC drive: the command is in volts and the drive, viscous friction, current
        limit and computation delay are in the prediction (:mod:`controllers.nmpc_drive`); None (or
        an ideal torque drive): the beam alone's NMPC, its commands bit for bit.

    Attributes
    ----------
    K, P : ndarray
        The LQR gain and Riccati solution of the same weights on the design model (``P``, on the
        predicted states, is the terminal cost).
    K_end : ndarray
        The step's linear law at the end point (:meth:`feedback_matrices`), at the design's payload.
    step_times_s : list of float
        Wall time of each step [s].
    symbolic_step, step_function : casadi.Function
        The step (:func:`rti_step_function`) as built, and as called (its generated C with
        ``backend="compiled"``).
    prediction_states : ndarray of int
        The design state's entries the prediction model holds, in its order (then the command in
        flight with a drive and a delay).
    drive : PredictionDrive or None
        The drive stage of the prediction.
    u_max : float
        The command's limit [N m, or V with a drive].
    command : str
        ``"torque"`` or ``"voltage"``.
    """

    measurement = "state"

    def __init__(self, design: DesignModel, settings: NMPCSettings | None = None,
                 reference: Reference | None = None, hardware=None):
        from hubbeam_ctrl.plant.models import build_model
        settings = settings or NMPCSettings()
        self.built_on = (design, reference)         # what with_hardware builds again from
        self.drive = None
        if hardware is not None and hardware.command == "voltage":
            from .nmpc_drive import PredictionDrive
            self.drive = PredictionDrive.from_hardware(hardware)
            if settings.learn_payload:
                raise ParameterError("learn_payload does not apply with a DC drive in the prediction yet")
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
        self.axial_modes = min(settings.axial_modes or m, design.params.n_axial)
        model = build_model("foam", design.params.replace(n_transverse=m, n_axial=self.axial_modes),
                            axial="quasi-static")
        n = model.n_q                       # theta and m modal coordinates
        self._n, self._nx = n, 2 * n
        # the (residual) design state's rows this model uses: theta, q2_1..m, theta_dot, q2_dot_1..m
        h = self.design.n_x // 2
        self._pick = self.prediction_states = np.r_[0, 1:1 + m, h, h + 1:h + 1 + m]
        # the LQR's gain on the states the prediction leaves out (the residual modes): added to the move
        self._K_res = self.K.copy()
        self._K_res[self._pick] = 0.0
        self._K_res0 = self._K_res.copy()
        Q, R = settings.weights.matrices(design)            # the stage weights on the design model's states
        hd = design.n_x // 2
        pick_d = np.r_[0, 1:1 + m, hd, hd + 1:hd + 1 + m]
        self._Q = Q[np.ix_(pick_d, pick_d)]
        self._R = float(np.asarray(R).reshape(-1)[0])
        self._Pt = np.asarray(self.P)[np.ix_(self._pick, self._pick)]
        self.u_max, self.command, self._lag = self.tau_max, "torque", False
        if self.drive is not None:
            self.drive = self.drive.resolved(self.dt / self.substeps, design.params.J_h)
            self._drive_setup(settings, design)
        self.payload = None
        if settings.learn_payload:
            self._learning_setup(model, settings)
        elif self.drive is not None:
            self._F = self._drive_shooting(model)
        else:
            self._F = self._shooting(model)
        self._build_qp(settings)
        self.K_end = self._end_gain()
        self.step_times_s = []
        self.reset()

    # -- construction -------------------------------------------------------------
    def _rhs(self, model, p, torque=None):
        """``f(z, u)``: the prediction model's state derivative, the model's parameter vector ``p``
        (a symbol, or its numbers); with ``torque(u, thd)`` the hub torque of the command (a drive)."""
        n = self._n
        M, c = model.parametric.mass_matrix, model.parametric.bias
        B = np.zeros(n)
        B[0] = 1.0

        def f(z, u):
            q, v = z[:n], z[n:]
            tau = u if torque is None else torque(u, v[0])
            return ca.vertcat(v, ca.solve(M(q, v, p), B * tau - c(q, v, p)))
        return f

    def _rk4(self, model, x, u, p, torque=None, span=None, steps=None):
        """The state after one sample from ``x`` under ``u``: RK4 in ``substeps`` steps (:meth:`_rhs`),
        over ``span`` [s] in ``steps`` steps."""
        return rk4(self._rhs(model, p, torque), x, u, self.dt if span is None else span,
                   self.substeps if steps is None else steps)

    def _shooting_function(self, name: str, model, p, torque=None) -> ca.Function:
        """``(x, u[, p]) -> (x+, dx+/dx, dx+/du)`` over one sample: ``x+`` by RK4 of the model, its
        Jacobians by :attr:`NMPCSettings.jacobian` (:func:`controllers.nmpc_rti.shooting_function`)."""
        x, u = ca.SX.sym("x", self._nx), ca.SX.sym("u")      # scalar expressions: no linear-solver call inside
        extra = [p] if isinstance(p, ca.SX) else []
        return shooting_function(name, self._rhs(model, p, torque), x, u, extra, self.dt, self.substeps,
                                 self.settings.jacobian)

    def _shooting(self, model) -> ca.Function:
        """``(x, u) -> (x+, dx+/dx, dx+/du)``: RK4 over the sample in ``substeps`` steps."""
        return self._shooting_function("nmpc_shoot", model, ca.DM(model.p))

    def _learning_setup(self, model, s: NMPCSettings) -> None:
        """The shooting map with the parameter vector as an input, and the payload's estimator
        (:class:`controllers.payload_estimate.PayloadMomentum`)."""
        from hubbeam_ctrl.plant.models import build_model

        from .payload_estimate import PayloadMomentum, payload_table
        params = self.design.params
        hi = s.payload_max_kg if s.payload_max_kg is not None else params.m_t + params.rho * params.A * params.L
        lo = s.payload_min_kg
        if not lo <= params.m_t <= hi:
            raise ParameterError(f"payload range {lo:g}..{hi:g} kg must hold the design's payload m_t = "
                                 f"{params.m_t:g} kg")
        self._F = self._shooting_function("nmpc_shoot_p", model, ca.SX.sym("p", model.parametric.n_p))
        table = payload_table(params.replace(n_axial=self.axial_modes), self.model_modes, lo, hi)
        # the balance on every mode the design state carries (the prediction's 2 leave 0.5 % of the
        # momentum early in Table 1's slew out: a 0.03 kg bias)
        whole = build_model("foam", params.replace(n_transverse=self.design.n_modes), axial="quasi-static")
        peak_rate = float(np.max(np.abs(self.reference.theta_dot))) or 1.0
        noise = s.payload_momentum_error * params.total_inertia * peak_rate
        self.payload = PayloadMomentum(whole.parametric.momentum,
                                       payload_table(params, self.design.n_modes, lo, hi, points=2),
                                       params.m_t, self.dt, noise)
        self._table = table
        # the reference follows the estimate: the task planned again on payloads over the range
        # (controllers.planning.replanned), interpolated at the estimate (a reference that is not
        # a reference that is not a plan on the design model stays as it is); the terminal cost and the
        # gain on the modes the prediction leaves out are the LQR's of each payload's design model
        from .base import DesignModel
        from .lqr import LQR, LQRSettings
        masses = np.linspace(lo, hi, REFERENCE_POINTS)
        common = {f: getattr(s, f) for f in LQRSettings.__dataclass_fields__ if hasattr(s, f)}
        from .scaling import first_mode
        w1 = first_mode(self.design)
        stage, terminal, residual, refs = [], [], [], []
        for m in masses:
            own = params.replace(m_t=float(m))
            ref = self.reference
            if ref.plan is not None:
                from .planning import replanned
                ref = replanned(ref, own)
                X, tff = self._tabulate(ref, s.elastic_reference, s.horizon + 1)
                refs.append((X, tff))
            design = DesignModel.build(own, 0.0, self.dt, self.design.n_modes)
            # the rate weights follow the first mode, as Bryson's rule of the task sets them
            # (controllers.scaling.bryson_weights: a rate error of the allowed deflection times w1)
            scale = (w1 / first_mode(design)) ** 2
            wts = s.weights.replace(tip_rate=s.weights.tip_rate * scale,
                                    modal_rate=None if s.weights.modal_rate is None else s.weights.modal_rate * scale)
            lqr = LQR(design, LQRSettings(**{**common, "weights": wts}), ref)
            Q = np.asarray(wts.matrices(design)[0])
            hd, mm = design.n_x // 2, self.model_modes
            pick = np.r_[0, 1:1 + mm, hd, hd + 1:hd + 1 + mm]
            stage.append(Q[np.ix_(pick, pick)])
            terminal.append(np.asarray(lqr.P)[np.ix_(self._pick, self._pick)])
            k_res = lqr.K.copy()
            k_res[self._pick] = 0.0
            residual.append(k_res)
        self._grid = _PayloadGrid(masses, np.array(stage), np.array(terminal), np.array(residual),
                                  np.array([X for X, _ in refs]) if refs else None,
                                  np.array([t for _, t in refs]) if refs else None)

    def _grid_at(self, mass: float) -> tuple:
        """``(a, w)``: ``mass`` [kg] lies at ``(1 - w)`` of grid point ``a`` and ``w`` of ``a + 1``."""
        masses = self._grid.masses
        m = float(np.clip(mass, masses[0], masses[-1]))
        a = int(np.clip(np.searchsorted(masses, m, side="right") - 1, 0, len(masses) - 2))
        return a, (m - masses[a]) / (masses[a + 1] - masses[a])

    def _reference_window(self, k: int, N: int) -> tuple:
        """``(x_ref, u_ff)`` on the predicted states over samples ``k .. k + N``: the table's, and with
        a learnt payload moved by what the estimate changes in the reference's quasi-static motion."""
        if self.drive is not None:
            return self._drive_window(k, N)
        xr = np.array([self._reference_at(k + j)[0][self._pick] for j in range(N + 1)])
        ur = np.array([self._reference_at(k + j)[1] * self._ff for j in range(N)])
        if self.payload is not None and self._grid.states is not None:
            a, w = self._grid_at(self.payload.mass)
            X, T = self._grid.states, self._grid.torques
            idx = np.minimum(np.arange(k, k + N + 1), X.shape[1] - 1)
            xr = ((1.0 - w) * X[a, idx] + w * X[a + 1, idx])[:, self._pick]
            ur = self._ff * ((1.0 - w) * T[a, idx[:N]] + w * T[a + 1, idx[:N]])
        return xr, ur

    def _build_qp(self, s: NMPCSettings) -> None:
        """The step as one CasADi function (:attr:`step_function`, built once)."""
        self._W = [self._Q] * s.horizon + [self._Pt]          # stage weights on x_0 .. x_N
        from hubbeam_ctrl.core.compiled import compile_function
        if not ca.has_conic(s.qp_solver):
            have = ", ".join(p for p in QP_PLUGINS if ca.has_conic(p))
            raise ParameterError(f"qp_solver {s.qp_solver!r} is not among the QP plugins of this CasADi "
                                 f"({ca.__version__}); choose one of {have}")
        current = None if self.drive is None else (self._n, self.drive.emf, self.drive.current_bound,
                                                    s.horizon if s.current_limit == "path" else 1)
        self.symbolic_step = rti_step_function(self._F, s.horizon, self._nx, self._R, self.u_max,
                                               parametric=self.payload is not None, current=current,
                                               in_flight=getattr(self, "_G", None), qp_solver=s.qp_solver,
                                               state_limits=self._state_limits(s))
        self.step_function = compile_function(self.symbolic_step, s.backend)    # C when asked and a compiler is there

    def _state_limits(self, s: NMPCSettings) -> tuple | None:
        """``(C, b)`` of :attr:`NMPCSettings.tip_limit_m` and :attr:`NMPCSettings.rate_limit` on the
        prediction state (the tip: the design model's tip row on the states it predicts), or None."""
        rows, bounds = [], []
        if s.tip_limit_m is not None:
            rows.append(np.asarray(self.design.C_tip, dtype=float)[0][self._pick])
            bounds.append(s.tip_limit_m)
        if s.rate_limit is not None:
            row = np.zeros(self._nx)
            row[self._n] = 1.0
            rows.append(row)
            bounds.append(s.rate_limit)
        return (np.array(rows), np.array(bounds)) if rows else None

    def reset(self) -> None:
        """Start from the reference: the previous solution is the planned motion."""
        N = self.settings.horizon
        if self.drive is not None:
            xr, ur = self._reference_window(0, N)
            self._X, self._U = xr.T.copy(), ur.copy()
        else:
            X = np.array([self._xref[min(k, len(self._xref) - 1)][self._pick] for k in range(N + 1)])
            self._X = X.T.copy()                                  # (nx, N + 1)
            self._U = np.array([self._reference_at(k)[1] * self._ff for k in range(N)], dtype=float)
        self._k_last = None
        self.qp_solves = self.qp_failures = 0   # steps, and those whose QP failed (the shifted plan kept)
        self._u_last = None                 # the command applied at the previous sample [N m]
        if self.drive is not None:
            self._u_last = 0.0              # at rest before the first sample [V]
        if self.payload is not None:            # the design's payload until the first estimate
            self.payload.reset()
            self._W = [self._Q] * self.settings.horizon + [self._Pt]
            self._K_res = self._K_res0.copy()

    def applied(self, tau: float) -> None:
        """Record the command the plant got at this sample [N m] (what the payload's estimator
        predicts with).

        Parameters
        ----------
        tau : float
            The command applied [N m].
        """
        if self._u_last is not None:
            self._u_last = float(tau)

    # -- the step ------------------------------------------------------------------
    def __call__(self, t: float, y) -> float:
        """Hub torque [N m] (volts [V] with a drive) at time ``t`` [s] from the design-ordered state ``y``
        (at the sample; with a drive and a delay the NMPC adds the command in flight itself)."""
        start = time.perf_counter()
        s = self.settings
        N = s.horizon
        k = int(round(t / self.dt))
        consecutive = self._k_last is not None and k == self._k_last + 1
        if self._k_last is not None and k > self._k_last:        # shift the previous solution
            shift = min(k - self._k_last, N)
            self._X = np.hstack([self._X[:, shift:], np.repeat(self._X[:, -1:], shift, axis=1)])
            self._U = np.r_[self._U[shift:], np.repeat(self._U[-1:], shift)]
        self._k_last = k
        x_meas = np.asarray(y, dtype=float)[self._pick]
        extra = ()
        if self.payload is not None:                 # the payload from the momentum the last command gave
            self.payload.update(y, self._u_last if consecutive else None)
            extra = (self._table.at(self.payload.mass)[0],)
            a, w = self._grid_at(self.payload.mass)
            g = self._grid
            Q = (1.0 - w) * g.stage[a] + w * g.stage[a + 1]
            self._W[:-1] = [Q] * N
            self._W[-1] = (1.0 - w) * g.terminal[a] + w * g.terminal[a + 1]
            self._K_res = (1.0 - w) * g.residual_gain[a] + w * g.residual_gain[a + 1]
        xr, ur = self._reference_window(k, N)
        try:
            X, U, residual = (np.asarray(a) for a in self.step_function(
                x_meas, self._X, self._U[None, :], xr.T, ur[None, :], self._W[0], self._W[-1], *extra,
                *((self._u_last,) if self._lag else ())))
        except RuntimeError:                           # the generated C reports a solver's error
            X = U = residual = np.full(1, np.nan)
        # a QP answer that does not solve the QP (a solver at its iteration limit, cycling) shows in
        # its optimality residual on both backends: the shifted plan is kept and the sample counted
        self.qp_residual = float(residual.ravel()[0])
        self.qp_status = int(np.all(np.isfinite(U)) and np.all(np.isfinite(X))
                             and self.qp_residual <= QP_RESIDUAL_TOL * self.u_max)
        self.qp_solves += 1
        if self.qp_status:
            self._X, self._U = X, U.ravel()
        else:
            self.qp_failures += 1
        if self.payload is not None and self._grid.states is not None:     # the estimate's own plan
            a, w = self._grid_at(self.payload.mass)
            X = self._grid.states
            j = min(k, X.shape[1] - 1)
            e = np.asarray(y, dtype=float) - ((1.0 - w) * X[a, j] + w * X[a + 1, j])
        else:
            e = np.asarray(y, dtype=float) - self._reference_at(k)[0]
        if self.drive is None:
            u0 = saturate(float(self._U[0] - self._K_res @ e), self.tau_max)
        else:                  # where the command acts, within the voltage box and the current limit
            e, rate = self._acting_error(k, y)
            u0 = self.drive.clip(float(self._U[0] - self._K_res @ e), rate)
        self._u_last = u0
        self.step_times_s.append(time.perf_counter() - start)
        return u0

    def stats(self) -> dict:
        """Counters since :meth:`reset`: steps, QP failures (the shifted plan kept) and their fraction."""
        n = self.qp_solves
        return {"qp_solves": n, "qp_fallbacks": self.qp_failures,
                "fallback_fraction": self.qp_failures / n if n else 0.0, "horizon": self.settings.horizon}

    def _end_gain(self) -> np.ndarray:
        """The step's unconstrained law at the end point, ``u = -K e`` on the design state: the
        condensed QP of :meth:`__call__` with the plan at rest on the target (no defects), its
        dynamics linearised there, on the predicted states; the LQR's gain on the others."""
        N, nx = self.settings.horizon, self._nx
        x_end = np.asarray(self._xref[-1], dtype=float)[self._pick].copy()
        x_end[self._n:] = 0.0
        estimate = (self._table.at(self.payload.mass)[0],) if self.payload is not None else ()
        _, A, B = (np.asarray(M) for M in self._F(x_end, 0.0, *estimate))
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
        if self._lag:                  # on the state where the command acts: on [x, u_prev] at the sample
            Phi, G = self.in_flight_map()
            K = np.r_[K @ Phi, K @ G]
        return K

    def feedback_matrices(self) -> tuple:
        """The NMPC's linear form at the end point (:attr:`K_end`: its step's unconstrained law there,
        the dynamics linearised at rest on the target), a static state feedback ``u = -K e`` on the
        design model's states; the modes it does not predict get no gain (what the certificate closes).
        A learning NMPC's law is at its current estimate of the payload (after a run: the one it
        learnt), with that payload's weights and residual-mode gain."""
        K = self._end_gain() if self.payload is not None else self.K_end
        return (np.zeros((0, 0)), np.zeros((0, len(K))), np.zeros((1, 0)), -K[None, :], [],
                list(self.design.state_names) + (["u_prev"] if self._lag else []))
