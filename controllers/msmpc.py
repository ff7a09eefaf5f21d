"""Multi-stage (scenario-tree) MPC over a payload's scenarios: one QP, one prediction per payload.

A tip payload the controller does not know moves the beam's frequencies, its rigid inertia and
the deflection a hub acceleration causes. The plain :class:`~controllers.mpc.MPC` predicts with
one model; the multi-stage MPC (do-mpc's ``n_robust``, Lucia et al., *Multi-stage nonlinear
model predictive control applied to a semi-batch polymerization reactor under uncertainty*,
J. Process Control 23, 2013) predicts the horizon once per **scenario**, each payload of
:attr:`MultiStageMPCSettings.payloads` with its own linearised SFOAM design model, in one QP:

* the first torque is **shared** by every scenario (robust horizon 1, non-anticipativity: it
  is applied before the plant reveals which payload it carries); the later ``N - 1`` torques
  are each scenario's own (the tree branches once, at the root, and each branch keeps its
  payload to the end of the horizon, as do-mpc's tree with ``n_robust = 1``);
* the cost is the weighted sum of the scenarios' MPC costs (:attr:`scenario_weights`, equal by
  default and normalised to sum 1): each scenario tracks the reference's states on its own
  model (the quasi-static deflection of its payload) and its terminal weight is its own LQR
  Riccati solution;
* every torque of every scenario has the MPC's torque box; the soft tip bound and the drive's
  back-EMF voltage limit (:class:`~controllers.mpc.MPCSettings`), when set, hold on every
  scenario's prediction (each scenario with its own slack).

Each scenario's condensed QP is the plain MPC's (:class:`~controllers.mpc.MPC` built on that
scenario's model: the same prediction matrices, reference terms, residual modes and scaling;
:meth:`MPC._qp_at`); this module only places their variables in the tree and adds their
Hessians, gradients and constraint rows. With one scenario the QP is the plain MPC's, and so
is the command. Without active constraints the first move is a linear state feedback
(:meth:`MultiStageMPC.feedback_matrices`), the law the loop certificate judges.

Variables ``z = [u_0, U_1, .., U_S, s_1, .., s_S]``: the shared first torque, each scenario's
``N - 1`` later torques [N m], and (with a tip bound) each scenario's scaled slack.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.settings import setting

from .base import Controller, DesignModel, Reference, saturate
from .mpc import MPC, DirectDAQP, MPCSettings
from .residual import estimator_modes

__all__ = ["MultiStageMPCSettings", "MultiStageMPC", "scenario_models", "scenario_range_design", "scaled_vibration",
           "MAX_SCENARIOS", "VIBRATION_WEIGHTS"]

#: Most scenarios a tree may hold (the QP has ``1 + S (N - 1)`` torques).
MAX_SCENARIOS = 9
#: Multipliers of the deflection-rate weights a design for a payload range tries
#: (:func:`scenario_range_design`).
VIBRATION_WEIGHTS = (1.0, 0.5, 0.25, 0.125)


@dataclass(frozen=True)
class MultiStageMPCSettings(MPCSettings):
    """Settings of :class:`MultiStageMPC`: those of MPC plus the scenarios.

    ``payloads`` are the tip masses of the scenarios; a design for a payload range gives the
    range's ends and the nominal payload (:func:`scenario_range_design`). ``solver`` is
    ``"daqp"`` only (the tree's QP is held in DAQP's own workspace).
    """

    solver: str = setting("daqp", choices=("daqp",), doc="QP solver: DAQP's own workspace (the tree's QP "
                                                           "is set up once and warm-started).")
    payloads: tuple | None = setting(None, kind=tuple, unit="kg",
                                     doc="Tip payloads of the scenarios, each >= 0, at most 9 "
                                         "different; None: the design model's payload alone (the plain "
                                         "MPC).")
    scenario_weights: tuple | None = setting(None, kind=tuple,
                                             doc="Weight of each scenario's cost, one positive number per "
                                                 "payload (normalised to sum 1); None: equal weights.")

    @classmethod
    def for_scenario(cls, scenario, **options) -> "MultiStageMPCSettings":
        """MPC's defaults for a scenario (:meth:`MPCSettings.for_scenario`); the study-wide
        ``solver`` option (the plain MPC's) is not taken: the tree's QP is DAQP's.

        Parameters
        ----------
        scenario : object
            A :class:`hubbeam_ctrl.study.scenarios.Scenario`.
        **options
            Study-wide controller options (``horizon``...).
        """
        options.pop("solver", None)
        return super().for_scenario(scenario, **options)


def _check_scenarios(settings: MultiStageMPCSettings, nominal: float) -> tuple:
    """``(payloads, weights)`` validated: payloads sorted and unique [kg], weights summing to 1."""
    payloads = (nominal,) if settings.payloads is None else settings.payloads
    try:
        values = [float(m) for m in payloads]
    except (TypeError, ValueError):
        raise ParameterError(f"payloads must be numbers [kg], got {payloads!r}") from None
    if not values or not all(math.isfinite(m) and m >= 0.0 for m in values):
        raise ParameterError(f"payloads must be finite numbers >= 0 [kg], at least one, got {payloads!r}")
    if len(set(values)) != len(values):
        raise ParameterError(f"payloads must be different from each other [kg], got {payloads!r}")
    if len(values) > MAX_SCENARIOS:
        raise ParameterError(f"payloads must hold 1..{MAX_SCENARIOS} scenarios, got {len(values)}")
    weights = settings.scenario_weights
    if weights is None:
        w = [1.0] * len(values)
    else:
        try:
            w = [float(x) for x in weights]
        except (TypeError, ValueError):
            raise ParameterError(f"scenario_weights must be numbers, got {weights!r}") from None
        if len(w) != len(values) or not all(math.isfinite(x) and x > 0.0 for x in w):
            raise ParameterError(f"scenario_weights must be {len(values)} finite numbers > 0 (one per payload), "
                                 f"got {weights!r}")
    order = np.argsort(values, kind="stable")
    total = float(sum(w))
    return tuple(values[i] for i in order), tuple(w[i] / total for i in order)


def scenario_models(design: DesignModel, payloads) -> list:
    """The design model of each scenario: ``design`` with that tip payload.

    The same spin, sample time, transverse modes, sensors and delay as ``design``; the
    design's own payload gives ``design`` itself.

    Parameters
    ----------
    design : DesignModel
        The nominal design model.
    payloads : sequence of float
        Tip masses [kg].

    Returns
    -------
    list of DesignModel

    Examples
    --------
    >>> d = DesignModel.build(n_modes=2)                 # Table 1: 0.1 kg at the tip
    >>> models = scenario_models(d, (0.0, 0.1, 0.5))
    >>> [m.params.m_t for m in models], models[1] is d
    ([0.0, 0.1, 0.5], True)
    """
    out = []
    for m in payloads:
        if m == design.params.m_t:
            out.append(design)
            continue
        d = DesignModel.build(design.params.replace(m_t=float(m)), design.spin, design.dt, design.n_modes)
        out.append(d.like(design))
    return out


class MultiStageMPC(Controller):
    """Multi-stage MPC: one QP over the payload scenarios, the first torque shared (module docstring).

    Parameters
    ----------
    design : DesignModel
        The nominal design model (spin, sample time, modes, sensors; its payload is the
        default single scenario).
    settings : MultiStageMPCSettings, optional
    reference : Reference, optional

    Attributes
    ----------
    payloads : tuple of float
        The scenarios' payloads [kg], sorted.
    weights : tuple of float
        Their cost weights (summing to 1).
    stages : list of MPC
        Each scenario's plain MPC (its condensed QP; never solved on its own).
    K : ndarray (nx,)
        The unconstrained law's gain: ``u_0 = tau_ff-terms - K x`` when no bound is active.
    solver : DirectDAQP
        The tree's QP in DAQP's workspace, built once.

    Examples
    --------
    >>> from controllers import DesignModel
    >>> ms = MultiStageMPC(DesignModel.build(n_modes=2), MultiStageMPCSettings(horizon=20,
    ...                    payloads=(0.0, 0.1, 0.5)))
    >>> ms.reset(); x = np.zeros(6); x[0] = -0.01     # 10 mrad behind the reference
    >>> 0 < ms(0.0, x) <= 200.0, ms.plan(0.0, x).shape
    (True, (3, 20))
    """

    measurement = "state"

    def __init__(self, design: DesignModel, settings: MultiStageMPCSettings | None = None,
                 reference: Reference | None = None):
        settings = settings or MultiStageMPCSettings()
        if not isinstance(settings, MultiStageMPCSettings):
            raise ParameterError(f"settings must be a MultiStageMPCSettings, got {type(settings).__name__}")
        if settings.solver != "daqp":
            raise ParameterError(f"solver must be 'daqp' for the multi-stage MPC, got {settings.solver!r}")
        self.payloads, self.weights = _check_scenarios(settings, design.params.m_t)
        if settings.residual_control and settings.residual_modes is None:
            # every scenario's model with the same residual modes (the nominal design's count)
            settings = settings.replace(residual_modes=estimator_modes(design))
        models = scenario_models(design, self.payloads)
        self.stages = [MPC(d, settings, reference) for d in models]
        nominal = int(np.argmin([abs(m - design.params.m_t) for m in self.payloads]))
        super().__init__(self.stages[nominal].design, settings, reference)
        self.n_modes = design.n_modes
        self._nominal = nominal
        # the nominal scenario's reference tables and feedforward switch: what a wrapper reads
        # (the rig's observer starts its filter at the reference, controllers.integral)
        own = self.stages[nominal]
        self._xref, self._tff, self._ff = own._xref, own._tff, own._ff
        if any(st.design.n_x != self.design.n_x for st in self.stages):
            raise ParameterError("payloads: the scenarios' models have different state sizes")
        self._build_tree()
        self.reset()

    # -- the tree's QP -------------------------------------------------------------------------
    def _build_tree(self) -> None:
        """Place each scenario's variables in the tree and sum its Hessian, rows and bounds."""
        N, S = self.settings.horizon, len(self.stages)
        soft = self.stages[0]._soft
        n_u = 1 + S * (N - 1)
        nz = n_u + (S if soft else 0)
        self._index = []
        H = np.zeros((nz, nz))
        lbx, ubx = np.zeros(nz), np.zeros(nz)
        rows, Gx = [], np.zeros((nz, self.design.n_x))
        for j, (st, w) in enumerate(zip(self.stages, self.weights)):
            idx = np.r_[0, 1 + j * (N - 1) + np.arange(N - 1)]
            if soft:
                idx = np.r_[idx, n_u + j]
            self._index.append(idx)
            Hj = np.asarray(st._H.full(), dtype=float)
            H[np.ix_(idx, idx)] += w * Hj
            Gx[idx[:N]] += w * st._Gx
            lbx[idx], ubx[idx] = st._lbx, st._ubx
            Aj = np.asarray(st._A.full(), dtype=float)
            if Aj.shape[0]:
                A = np.zeros((Aj.shape[0], nz))
                A[:, idx] = Aj
                rows.append(A)
        self._H = 0.5 * (H + H.T)
        self._A = np.vstack(rows) if rows else np.zeros((0, nz))
        self._nz, self._n_u, self._soft = nz, n_u, soft
        u = np.arange(n_u)
        self._Hu = self._H[np.ix_(u, u)]
        self._Gx = Gx[:n_u]
        self._chol = np.linalg.cholesky(self._Hu)
        # the unconstrained first move: z_u = -Hu^-1 g_u, so u_0 = -K x + (reference terms)
        self.K = self._solve_u(self._Gx)[0]
        self.solver = DirectDAQP(self._H, self._A, lbx, ubx)

    def _solve_u(self, rhs: np.ndarray) -> np.ndarray:
        """``Hu^-1 rhs`` by the Cholesky factor of the torques' Hessian."""
        import scipy.linalg
        return scipy.linalg.cho_solve((self._chol, True), rhs)

    def qp_at(self, t: float, y) -> tuple:
        """The tree's QP at time ``t`` [s] for state ``y``: ``(g, lba, uba)`` (Hessian :attr:`hessian`).

        Parameters
        ----------
        t : float
            Time [s].
        y : ndarray (nx,)
            Measured design-model state.

        Returns
        -------
        tuple
            Linear term (nz,), lower and upper bounds of the constraint rows (None: no rows).
        """
        g = np.zeros(self._nz)
        lba, uba = [], []
        for st, w, idx in zip(self.stages, self.weights, self._index):
            _, gj, lo, hi = st._qp_at(t, y)
            g[idx] += w * np.asarray(gj, dtype=float)
            if lo is not None:
                lba.append(lo)
                uba.append(hi)
        if not lba:
            return g, None, None
        return g, np.concatenate(lba), np.concatenate(uba)

    @property
    def hessian(self) -> np.ndarray:
        """The tree QP's Hessian (nz, nz), fixed (cost scaled so that the torque weight is 1)."""
        return self._H

    def feedback_matrices(self) -> tuple:
        """The unconstrained law as static state feedback ``u = -K e`` (no states).

        Without active bounds the shared first move is ``-(Hu^-1 G_x)[0] x`` plus reference and
        feedforward terms (``Hu``, ``G_x`` the tree's Hessian and state gradient over the
        torques). The torque box, the tip bound and the voltage limit are not part of it.
        """
        n = self.design.n_x
        return (np.zeros((0, 0)), np.zeros((0, n)), np.zeros((1, 0)), -self.K[None, :], [],
                list(self.design.state_names))

    # -- running -------------------------------------------------------------------------------
    def reset(self) -> None:
        """Forget the previous active set (the next solve starts cold) and the counters."""
        self._z = np.zeros(self._nz)
        self.n_solves = 0
        self.n_fallbacks = 0
        self.last_status = ""
        self.solver.reset()

    def stats(self) -> dict:
        """Counters of the run: QP solves, fallbacks to the unconstrained law, the scenarios."""
        return {**MPC.stats(self), "scenarios_kg": list(self.payloads), "scenario_weights": list(self.weights)}

    def plan(self, t: float, y) -> np.ndarray:
        """Solve the tree's QP; return each scenario's planned torques [N m].

        Parameters
        ----------
        t : float
            Time [s] (selects the reference window).
        y : ndarray (nx,)
            Measured (or estimated) design-model state.

        Returns
        -------
        ndarray (S, N)
            Row ``j``: scenario ``j``'s torques; column 0 (the shared first torque) is the same
            in every row.

        Raises
        ------
        RuntimeError
            If DAQP fails (the controller's call then applies the unconstrained law, saturated).
        """
        g, lba, uba = self.qp_at(t, np.asarray(y, dtype=float))
        z = self.solver.solve(g, lba, uba, warm_start=self.settings.warm_start)
        self.last_status = self.solver.status
        self._z = z
        N = self.settings.horizon
        return np.array([z[idx[:N]] for idx in self._index])

    def __call__(self, t: float, y) -> float:
        """Hub torque [N m] at time ``t`` [s] from the SFOAM-ordered state ``y``: the shared first move."""
        self.n_solves += 1
        y = np.asarray(y, dtype=float)
        try:
            tau = float(self.plan(t, y)[0, 0])
        except RuntimeError:
            self.n_fallbacks += 1
            g, _, _ = self.qp_at(t, y)
            tau = float(-self._solve_u(g[:self._n_u])[0])
        return saturate(tau, self.tau_max)


def scaled_vibration(weights, factor: float):
    """``weights`` with the tip and modal deflection-rate weights scaled by ``factor`` [-].

    Parameters
    ----------
    weights : Weights
        Scalar weights (a full ``state_matrix`` is returned unchanged).
    factor : float
        Multiplier of ``tip_rate`` and the modal rates, > 0.

    Returns
    -------
    Weights
    """
    if weights.state_matrix is not None or factor == 1.0:
        return weights
    rate = weights.modal if weights.modal_rate is None else weights.modal_rate
    return weights.replace(tip_rate=factor * weights.tip_rate, modal_rate=factor * rate)


def scenario_range_design(design: DesignModel, settings: MultiStageMPCSettings, reference: Reference,
                          payload_range, *, t_f: float, t_end: float, delay: float, baseline, score=None,
                          vibration_weights=VIBRATION_WEIGHTS):
    """The multi-stage MPC's design for a payload range: one scenario per payload of the grid.

    The scenarios are the range's ends and the nominal payload
    (:func:`controllers.robust.payload_grid`). One knob is measured, as
    :func:`controllers.robust.design_for_range` measures its candidates: the weight on the
    deflection rates (:data:`VIBRATION_WEIGHTS`; a tree that damps less hard leaves the angle
    error a wrong payload's feedforward causes less to fight). A candidate whose linear loop
    with a scenario's model is unstable is dropped; the others are scored by their worst
    residual over the grid relative to the open loop's on the same plant, by ``score`` (the
    study passes nonlinear runs) or on the sampled linear SFOAM models.

    Parameters
    ----------
    design : DesignModel
        The nominal design model (its ``params.m_t`` is the nominal payload).
    settings : MultiStageMPCSettings
        The controller's settings (``payloads`` and the deflection-rate weights are replaced).
    reference : Reference
        The task's reference.
    payload_range : tuple of float
        ``(m_min, m_max)`` [kg], holding the nominal payload.
    t_f, t_end, delay : float
        Maneuver time, run length and residual-window delay of the task [s].
    baseline : callable
        Open-loop torque ``baseline(t)`` [N m] whose residual the linear score is relative to.
    score : callable, optional
        ``score(ctrl, payload) -> float``: the candidate's residual on the plant with that
        payload relative to the open loop's there (default: the linear measure).
    vibration_weights : sequence of float
        Multipliers of the deflection-rate weights tried, each > 0.

    Returns
    -------
    RangeDesign
    """
    from .analysis import closed_loop_poles
    from .robust import (
        RangeDesign,
        check_payload_range,
        linear_openloop_residual,
        linear_task_residual,
        payload_grid,
    )
    grid = payload_grid(check_payload_range(payload_range, design.params.m_t), design.params.m_t)
    scenarios = "scenarios " + ", ".join(f"{m:g}" for m in grid) + " kg"
    plants = scenario_models(design, grid)
    open_loop = {}
    best, scores = None, {}
    for factor in vibration_weights:
        if not (isinstance(factor, (int, float)) and math.isfinite(factor) and factor > 0):
            raise ParameterError(f"vibration_weights must be numbers > 0, got {factor!r}")
        st = settings.replace(payloads=tuple(float(m) for m in grid),
                              weights=scaled_vibration(settings.weights, float(factor)))
        ctrl = MultiStageMPC(design, st, reference)
        label = scenarios + ("" if factor == 1.0 else f", deflection rates x{factor:g}")
        radius = max(float(np.max(np.abs(closed_loop_poles(ctrl, stage.design)))) for stage in ctrl.stages)
        if radius >= 1.0:
            scores[label] = math.inf
            continue
        per = []
        for m, plant in zip(grid, plants):
            if score is not None:
                per.append(float(score(ctrl, m)))
                continue
            if m not in open_loop:
                open_loop[m] = linear_openloop_residual(plant, baseline, t_f, t_end, delay)
            r = linear_task_residual(design, plant, ctrl, t_f, t_end, delay)
            per.append(r / open_loop[m] if open_loop[m] > 0 else r)
        scores[label] = max(per)
        if best is None or scores[label] < best[0]:
            best = (scores[label], label, st)
    if best is None:
        raise ParameterError(f"payload_range: no multi-stage design over {grid} kg has a stable linear loop "
                             "with every scenario's model")
    return RangeDesign(design=design, settings=best[2], design_mass=design.params.m_t, choice=best[1],
                       score=best[0], scores=scores, grid=grid)
