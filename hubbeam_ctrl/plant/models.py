"""The four hub-beam models, each defined once by its kinetic and potential energy.

A point of the beam at ``x`` moves, in the hub frame, to ``(a, b)`` with
``a = r + x + w1 + wc`` and ``b = w2``; its inertial speed squared is (the paper's Eq. 8; docs/physics.md)::

    |r_P'|^2 = thd^2 (a^2 + b^2) + ad^2 + bd^2 + 2 thd (a bd - ad b)

with ``w1 = f1 q1``, ``w2 = f2 q2``, ``wc = -1/2 q2' S(x) q2``. The kinetic energy is
``T = 1/2 J_h thd^2 + 1/2 int |r_P'|^2 dmu`` over the mass measure of beam plus tip mass
and ``U = 1/2 q1' K1 q1 + 1/2 q2' K2 q2``. The models differ only in which terms of
``int |r_P'|^2 dmu`` they keep (:data:`MODEL_SPECS`):

* ``cfoam``: every term, every order (``wc`` inside the squares);
* ``foam``: second order in the elastic coordinates, ``wc`` counted second order;
* ``tlam``: FOAM with ``wc = 0`` (no dynamic stiffening);
* ``sfoam``: FOAM without ``q1``, and with the hub row's velocity terms (``Q_theta``)
  dropped, as in the paper's Eq. (40). A design model, not a plant: it does not conserve
  energy.

Lagrange's equations are formed by CasADi's automatic differentiation: the mass matrix
is the Hessian of ``T`` in the velocities, the bias vector
``c = (d^2T/dv dq) v - dT/dq + dU/dq + C v``, so that ``M(q) a + c(q, v) = B tau``.
``Q_theta`` (the paper's inertia force on the hub) is ``-c_theta`` without the damping.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import casadi as ca
import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.basis import modal_basis
from hubbeam_ctrl.plant.params import Params

__all__ = ["MODEL_NAMES", "ModelSpec", "MODEL_SPECS", "HubBeamModel", "build_model", "resolve_model",
           "kinetic_energy", "potential_energy"]

MODEL_NAMES = ("cfoam", "foam", "tlam", "sfoam")


@dataclass(frozen=True)
class ModelSpec:
    """Which terms of the kinetic energy a model keeps.

    Attributes
    ----------
    name : str
    axial : bool
        Whether the axial coordinates ``q1`` exist.
    foreshortening : {"none", "first", "complete"}
        ``none``: ``wc = 0`` (TLAM); ``first``: ``wc`` only where it is of second order
        (FOAM, SFOAM); ``complete``: every term (CFOAM).
    hub_velocity_terms : bool
        ``False`` drops the velocity-dependent terms of the hub equation (SFOAM).
    """

    name: str
    axial: bool
    foreshortening: str
    hub_velocity_terms: bool
    description: str


MODEL_SPECS = {
    "cfoam": ModelSpec("cfoam", True, "complete", True,
                       "complete first-order approximated model (all orders of wc kept)"),
    "foam": ModelSpec("foam", True, "first", True,
                      "first-order approximated model (second order in q, dynamic stiffening)"),
    "tlam": ModelSpec("tlam", True, "none", True,
                      "traditional linear approximated model (no foreshortening, no stiffening)"),
    "sfoam": ModelSpec("sfoam", False, "first", False,
                       "simplified FOAM: no axial modes, no Q_theta (design model)"),
}


def _quad(A, u, v=None):
    """``u' A v`` for numeric matrix ``A`` and CasADi vectors."""
    v = u if v is None else v
    return ca.dot(u, ca.mtimes(ca.DM(A), v))


def _foreshortening_factors(F):
    """Eigen-factors ``F = U diag(lam) U'`` of the quartic moment (as an n2^2 square)."""
    n2 = F.shape[0]
    Fm = F.reshape(n2 * n2, n2 * n2)
    lam, U = np.linalg.eigh(0.5 * (Fm + Fm.T))
    keep = lam > 1e-13 * max(lam.max(), 1e-300)
    return ca.DM(lam[keep]), U[:, keep]


def kinetic_energy(spec: ModelSpec, m, J_h, thd, q1, q2, q1d, q2d):
    """Kinetic energy ``T`` of a model [J] as a CasADi expression.

    Parameters
    ----------
    spec : ModelSpec
        Which terms to keep.
    m : MassMoments
        Inertia integrals of beam plus tip mass.
    J_h : float
        Hub inertia [kg m^2].
    thd : casadi scalar
        Hub rate [rad/s].
    q1, q2, q1d, q2d : casadi vectors
        Axial and transverse modal coordinates [m] and rates [m/s] (``q1`` may be empty).

    Returns
    -------
    casadi expression
        ``1/2 J_h thd^2 + 1/2 int |r_P'|^2 dmu``.
    """
    n2 = q2.shape[0]
    full = spec.foreshortening == "complete"
    has_wc = spec.foreshortening != "none"
    # int a^2, with a = r + x + w1 + wc
    int_a2 = m.J + 2 * ca.dot(ca.DM(m.V1), q1) + _quad(m.M1, q1)
    int_ad2 = _quad(m.M1, q1d)                          # int ad^2, ad = w1d + wcd
    int_a_bd = ca.dot(ca.DM(m.V2), q2d) + ca.dot(q1, ca.mtimes(ca.DM(m.R), q2d))
    int_ad_b = ca.dot(q1d, ca.mtimes(ca.DM(m.R), q2))
    if has_wc:
        int_a2 += -_quad(m.D, q2)                       # 2 (r+x) wc
    if full:
        # The quartic and cubic foreshortening terms all contract q2 q2' (or q2 q2d')
        # with F, E or G, whose rows lie in the span of vec(S(x)). With F = U diag(lam) U'
        # (rank <= n2 (n2+1)/2), y = U' vec(q2 q2') and yd = U' vec(q2 q2d') carry them
        # all, which keeps the derivative expressions small.
        lam, U = _foreshortening_factors(m.F)
        P = [ca.DM(U[:, k].reshape(n2, n2)) for k in range(U.shape[1])]
        y = ca.vertcat(*[_quad(Pk, q2) for Pk in P])
        yd = ca.vertcat(*[_quad(Pk, q2, q2d) for Pk in P])
        if q1.shape[0]:
            E = ca.DM(m.E.reshape(m.E.shape[0], n2 * n2) @ U)
            int_a2 += -ca.dot(q1, ca.mtimes(E, y))         # 2 w1 wc
            int_ad2 += -2 * ca.dot(q1d, ca.mtimes(E, yd))  # 2 w1d wcd
        G = ca.DM(U.T @ m.G.reshape(n2 * n2, n2))
        int_a2 += 0.25 * ca.dot(y, lam * y)                # wc^2
        int_ad2 += ca.dot(yd, lam * yd)                    # wcd^2
        int_a_bd += -0.5 * ca.dot(y, ca.mtimes(G, q2d))    # wc w2d
        int_ad_b += -ca.dot(yd, ca.mtimes(G, q2))          # wcd w2
    int_b2 = _quad(m.M2, q2)
    int_bd2 = _quad(m.M2, q2d)
    beam = thd ** 2 * (int_a2 + int_b2) + int_ad2 + int_bd2 + 2 * thd * (int_a_bd - int_ad_b)
    return 0.5 * J_h * thd ** 2 + 0.5 * beam


def potential_energy(K1, K2, q1, q2):
    """Strain energy ``U = 1/2 q1' K1 q1 + 1/2 q2' K2 q2`` [J] as a CasADi expression.

    Parameters
    ----------
    K1, K2 : ndarray
        Axial [N/m] and bending [N/m] modal stiffness matrices.
    q1, q2 : casadi vectors
        Modal coordinates [m].
    """
    return 0.5 * _quad(K1, q1) + 0.5 * _quad(K2, q2)


class HubBeamModel:
    """A hub-beam model with its equations of motion, built by automatic differentiation.

    Generalised coordinates ``q = [theta, q1 (n1), q2 (n2)]`` (SFOAM: ``[theta, q2]``),
    velocities ``v = dq/dt``; the state is ``x = [q, v]``. Units: rad, m; rad/s, m/s.

    Use :func:`build_model` (cached) rather than the constructor.

    Attributes
    ----------
    name : str
    params : Params
    basis : ModalBasis
    n_q : int
        Number of generalised coordinates.
    n_axial, n_transverse : int
    """

    def __init__(self, name: str, params: Params):
        if name not in MODEL_SPECS:
            raise ParameterError(f"model must be one of {', '.join(MODEL_NAMES)}, got {name!r}")
        self.name = name
        self.spec = MODEL_SPECS[name]
        self.params = params
        self.basis = modal_basis(params)
        self.n_axial = params.n_axial if self.spec.axial else 0
        self.n_transverse = params.n_transverse
        self.n_q = 1 + self.n_axial + self.n_transverse
        self._build()

    # -- index helpers -------------------------------------------------------
    @property
    def axial_slice(self) -> slice:
        """Slice of ``q1`` in ``q``."""
        return slice(1, 1 + self.n_axial)

    @property
    def transverse_slice(self) -> slice:
        """Slice of ``q2`` in ``q``."""
        return slice(1 + self.n_axial, self.n_q)

    @property
    def coordinate_names(self) -> list:
        """Names of the generalised coordinates."""
        return (["theta"] + [f"q1_{i + 1}" for i in range(self.n_axial)]
                + [f"q2_{i + 1}" for i in range(self.n_transverse)])

    def split(self, q):
        """Return ``(theta, q1, q2)`` views of a coordinate vector (NumPy or CasADi)."""
        return q[0], q[self.axial_slice], q[self.transverse_slice]

    # -- symbolic construction -------------------------------------------------
    def _build(self):
        p, spec = self.params, self.spec
        nq = self.n_q
        q = ca.SX.sym("q", nq)
        v = ca.SX.sym("v", nq)
        _, q1, q2 = self.split(q)
        _, q1d, q2d = self.split(v)
        T = kinetic_energy(spec, self._moments(), p.J_h, v[0], q1, q2, q1d, q2d)
        K1 = self.basis.K1 if spec.axial else np.zeros((0, 0))
        U = potential_energy(K1, self.basis.K2, q1, q2)
        M = ca.hessian(T, v)[0]
        dT_dv = ca.gradient(T, v)
        inertial = ca.jtimes(dT_dv, q, v) - ca.gradient(T, q)   # velocity terms
        q_theta = -inertial[0]
        if not spec.hub_velocity_terms:
            inertial[0] = 0
        bias = inertial + ca.gradient(U, q) + ca.mtimes(ca.DM(self._damping_matrix()), v)
        a = ca.SX.sym("a", nq)
        generalized_force = ca.jtimes(dT_dv, v, a) + bias     # M(q) a + c(q, v)
        tip = self._tip_outputs(q1, q2)
        self._sym = dict(q=q, v=v, T=T, U=U, M=M, bias=bias)
        opts = {"cse": True}
        self.mass_matrix_function = ca.Function("M", [q], [M], ["q"], ["M"], opts)
        self.bias_function = ca.Function("c", [q, v], [bias], ["q", "v"], ["c"], opts)
        self.inverse_dynamics_function = ca.Function(
            "inverse_dynamics", [q, v, a], [generalized_force], ["q", "v", "a"], ["f"], opts)
        self.energy_function = ca.Function("energy", [q, v], [T, U, T + U], ["q", "v"],
                                           ["T", "U", "E"], opts)
        self.momentum_function = ca.Function("momentum", [q, v], [dT_dv[0]], ["q", "v"], ["H"], opts)
        self.q_theta_function = ca.Function("q_theta", [q, v], [q_theta], ["q", "v"], ["Q_theta"], opts)
        self.tip_function = ca.Function("tip", [q], list(tip), ["q"], ["v_tip", "u_tip"], opts)

    def _moments(self):
        m = self.basis.total
        if self.spec.axial:
            return m
        # drop the axial family: zero-size arrays keep the energy expression unchanged
        n2 = self.n_transverse
        return type(m)(J=m.J, V1=np.zeros(0), V2=m.V2, M1=np.zeros((0, 0)), M2=m.M2,
                       R=np.zeros((0, n2)), D=m.D, E=np.zeros((0, n2, n2)), G=m.G, F=m.F)

    def _damping_matrix(self) -> np.ndarray:
        """Modal damping ``C = 2 zeta sqrt(K M)`` of the non-rotating clamped modes [N s/m]."""
        zeta = self.params.damping_ratio
        C = np.zeros((self.n_q, self.n_q))
        if zeta == 0:
            return C
        b = self.basis
        for sl, K, Mm in ((self.axial_slice, b.K1, b.beam.M1), (self.transverse_slice, b.K2, b.beam.M2)):
            if sl.start == sl.stop:  # SFOAM has no axial modes
                continue
            C[sl, sl] = np.diag(2 * zeta * np.sqrt(np.diag(K) * np.diag(Mm)))
        return C

    def _tip_outputs(self, q1, q2):
        b = self.basis
        v_tip = ca.dot(ca.DM(b.f2_tip), q2)
        u_tip = ca.dot(ca.DM(b.f1_tip[: self.n_axial]), q1) if self.n_axial else 0 * v_tip
        if self.spec.foreshortening != "none":
            u_tip = u_tip - 0.5 * _quad(b.S_tip, q2)
        return v_tip, u_tip

    # -- symbolic access for integrators / linearisation ------------------------
    def acceleration_expr(self, q, v, tau):
        """Accelerations of the free-hub model as an MX expression (numeric solve of ``M``)."""
        M = self.mass_matrix_function(q)
        rhs = -self.bias_function(q, v)
        rhs[0] += tau
        return ca.solve(M, rhs)

    # -- numeric conveniences -----------------------------------------------------
    def mass_matrix(self, q) -> np.ndarray:
        """Mass matrix ``M(q)`` [kg, kg m, kg m^2 blocks]."""
        return np.array(self.mass_matrix_function(q))

    def bias(self, q, v) -> np.ndarray:
        """Bias vector ``c(q, v)`` (velocity, stiffness and damping terms) [N m, N]."""
        return np.array(self.bias_function(q, v)).ravel()

    def accelerations(self, q, v, tau: float = 0.0) -> np.ndarray:
        """Free-hub accelerations ``M^-1 (B tau - c)`` [rad/s^2, m/s^2]."""
        rhs = -self.bias(q, v)
        rhs[0] += tau
        return np.linalg.solve(self.mass_matrix(q), rhs)

    def state_derivative(self, x, tau: float = 0.0) -> np.ndarray:
        """Free-hub state derivative ``d/dt [q, v] = [v, M^-1 (B tau - c)]``.

        Parameters
        ----------
        x : array_like (2 n_q,)
            State ``[q, v]`` [rad, m, rad/s, m/s].
        tau : float
            Hub torque [N m].

        Returns
        -------
        ndarray (2 n_q,)
        """
        x = np.asarray(x, dtype=float)
        q, v = x[: self.n_q], x[self.n_q:]
        return np.concatenate([v, self.accelerations(q, v, tau)])

    def hub_torque(self, q, v, a) -> float:
        """Hub torque that produces accelerations ``a`` in state ``(q, v)`` [N m].

        With the hub prescribed this is the torque the motion takes (the first row of the
        inverse dynamics ``M(q) a + c(q, v)``).
        """
        return float(self.inverse_dynamics_function(q, v, a)[0])

    def energy(self, q, v) -> float:
        """Total energy ``T + U`` [J]."""
        return float(self.energy_function(q, v)[2])

    def angular_momentum(self, q, v) -> float:
        """Angular momentum about the hub axis ``dT/d thd`` [kg m^2/s]."""
        return float(self.momentum_function(q, v))

    def q_theta(self, q, v) -> float:
        """The paper's inertia force on the hub ``Q_theta`` [N m]."""
        return float(self.q_theta_function(q, v))

    def tip(self, q) -> tuple:
        """Tip displacements ``(v_tip, u_tip)`` in the hub frame [m]."""
        v_tip, u_tip = self.tip_function(q)
        return float(v_tip), float(u_tip)

    def static_axial_stretch(self, spin: float) -> np.ndarray:
        """Steady axial coordinates ``q1`` under a constant spin with ``q2 = 0`` [m].

        Solves ``(K1 - spin^2 M1) q1 = spin^2 V1`` (exact for FOAM, CFOAM and TLAM at
        ``q2 = 0``). Empty for SFOAM.
        """
        if not self.n_axial:
            return np.zeros(0)
        m = self.basis.total
        return np.linalg.solve(self.basis.K1 - spin ** 2 * m.M1, spin ** 2 * m.V1)

    def steady_state(self, spin: float, theta: float = 0.0) -> np.ndarray:
        """State ``[q, v]`` of steady rotation at ``spin`` [rad/s] with the beam undeflected."""
        x = np.zeros(2 * self.n_q)
        x[0] = theta
        x[self.axial_slice] = self.static_axial_stretch(spin)
        x[self.n_q] = spin
        return x

    def __repr__(self):
        return (f"HubBeamModel({self.name!r}, n_axial={self.n_axial}, "
                f"n_transverse={self.n_transverse}, m_t={self.params.m_t})")


@lru_cache(maxsize=32)
def build_model(name: str, params: Params = Params()) -> HubBeamModel:
    """Build (and cache) a model's equations of motion.

    Parameters
    ----------
    name : {"cfoam", "foam", "tlam", "sfoam"}
        Which model (see :data:`MODEL_SPECS`).
    params : Params
        System parameters.

    Returns
    -------
    HubBeamModel

    Examples
    --------
    >>> m = build_model("foam", Params(m_t=0.0))
    >>> m.n_q
    11
    """
    if not isinstance(name, str) or name.lower() not in MODEL_SPECS:
        raise ParameterError(f"model must be one of {', '.join(MODEL_NAMES)}, got {name!r}")
    return HubBeamModel(name.lower(), params)


def resolve_model(model, params: Params | None = None) -> HubBeamModel:
    """A built model from a name plus parameters, or a model passed through.

    Parameters
    ----------
    model : str or HubBeamModel
    params : Params, optional
        With a name: the parameters (default Table 1). With a model: must be ``None`` or
        equal to the model's own.

    Returns
    -------
    HubBeamModel
    """
    if isinstance(model, HubBeamModel):
        if params is not None and params != model.params:
            raise ParameterError("params differ from the model's own; pass one or the other")
        return model
    if params is not None and not isinstance(params, Params):
        raise ParameterError(f"params must be a Params, got {type(params).__name__}")
    return build_model(model, params if params is not None else Params())
