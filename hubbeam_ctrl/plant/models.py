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
           "kinetic_energy", "potential_energy", "ParametricModel", "parametric_model", "parameter_layout",
           "reduced_foreshortening", "pair_map"]

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
    description : str
        One line on what the model keeps (for help texts and docs).
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


def _as_ca(A):
    """A CasADi matrix from a NumPy array (symbolic matrices pass through)."""
    return A if isinstance(A, (ca.SX, ca.MX, ca.DM)) else ca.DM(np.asarray(A, dtype=float))


def _quad(A, u, v=None):
    """``u' A v`` for a numeric or symbolic matrix ``A`` and CasADi vectors."""
    v = u if v is None else v
    return ca.dot(u, ca.mtimes(_as_ca(A), v))


def _pairs(n2: int) -> list:
    """Index pairs ``(i, j)``, ``i <= j``, of the independent entries of a symmetric n2 x n2 matrix."""
    return [(i, j) for i in range(n2) for j in range(i, n2)]


def pair_map(n2: int) -> np.ndarray:
    """``W`` (n2^2, n2 (n2+1)/2) with ``vec(A) = W z`` for symmetric ``A``, ``z_k = A_ij`` of pair k.

    ``vec`` is row-major (NumPy's ``reshape``), as the moments ``E``, ``G``, ``F`` are stored.

    Parameters
    ----------
    n2 : int
        Transverse modes.
    """
    pairs = _pairs(n2)
    W = np.zeros((n2 * n2, len(pairs)))
    for k, (i, j) in enumerate(pairs):
        W[i * n2 + j, k] = 1.0
        W[j * n2 + i, k] = 1.0
    return W


def reduced_foreshortening(m) -> dict:
    """The foreshortening moments on the independent pairs: ``E_r``, ``G_r``, ``F_r``.

    Every term with ``E``, ``G`` or ``F`` contracts them with ``vec(q2 q2')`` or
    ``vec(q2 q2d')``, and they are symmetric in the index pair of ``S``; so with
    ``y_k = q2_i q2_j`` and ``yd_k = (q2_i q2d_j + q2_j q2d_i) / 2`` over the pairs ``i <= j``
    (:func:`pair_map`), ``E_r = E W``, ``G_r = W' G`` and ``F_r = W' F W`` carry them exactly.
    The quartic term becomes a dense ``r x r`` form (``r = n2 (n2+1)/2``) whose structure
    does not depend on the parameters.

    Parameters
    ----------
    m : MassMoments

    Returns
    -------
    dict
        ``E_r`` (n1, r) [kg/m], ``G_r`` (r, n2) [kg/m], ``F_r`` (r, r) [kg/m^2].
    """
    n2 = m.M2.shape[0]
    W = pair_map(n2)
    n1 = m.E.shape[0]
    return {"E_r": m.E.reshape(n1, n2 * n2) @ W, "G_r": W.T @ m.G.reshape(n2 * n2, n2),
            "F_r": W.T @ m.F.reshape(n2 * n2, n2 * n2) @ W}


def _pair_products(q2, q2d):
    """``y = [q2_i q2_j]`` and ``yd = [(q2_i q2d_j + q2_j q2d_i) / 2]`` over the pairs ``i <= j``."""
    pairs = _pairs(q2.shape[0])
    y = ca.vertcat(*[q2[i] * q2[j] for i, j in pairs])
    yd = ca.vertcat(*[q2[i] * q2d[i] if i == j else 0.5 * (q2[i] * q2d[j] + q2[j] * q2d[i])
                      for i, j in pairs])
    return y, yd


def kinetic_energy(spec: ModelSpec, m, J_h, thd, q1, q2, q1d, q2d):
    """Kinetic energy ``T`` of a model [J] as a CasADi expression.

    Parameters
    ----------
    spec : ModelSpec
        Which terms to keep.
    m : MassMoments or mapping
        Inertia integrals of beam plus tip mass: a :class:`MassMoments` (numbers), or a
        mapping with ``J, V1, V2, M1, M2, R, D`` and, for complete foreshortening,
        ``E_r, G_r, F_r`` (see :func:`reduced_foreshortening`), numeric or symbolic.
    J_h : float or casadi scalar
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
    if not isinstance(m, dict):
        fields = {k: getattr(m, k) for k in ("J", "V1", "V2", "M1", "M2", "R", "D")}
        if spec.foreshortening == "complete":
            fields.update(reduced_foreshortening(m))
        m = fields
    full = spec.foreshortening == "complete"
    has_wc = spec.foreshortening != "none"
    V1, V2, R = _as_ca(m["V1"]), _as_ca(m["V2"]), _as_ca(m["R"])
    # int a^2, with a = r + x + w1 + wc
    int_a2 = m["J"] + 2 * ca.dot(V1, q1) + _quad(m["M1"], q1)
    int_ad2 = _quad(m["M1"], q1d)                          # int ad^2, ad = w1d + wcd
    int_a_bd = ca.dot(V2, q2d) + ca.dot(q1, ca.mtimes(R, q2d))
    int_ad_b = ca.dot(q1d, ca.mtimes(R, q2))
    if has_wc:
        int_a2 += -_quad(m["D"], q2)                       # 2 (r+x) wc
    if full:
        # The quartic and cubic foreshortening terms all contract q2 q2' (or q2 q2d') with
        # E, G or F, which are symmetric in the index pair of S: on the independent pairs
        # (y, yd) they are dense products with E_r, G_r, F_r (reduced_foreshortening).
        y, yd = _pair_products(q2, q2d)
        F_r, G_r = _as_ca(m["F_r"]), _as_ca(m["G_r"])
        if q1.shape[0]:
            E_r = _as_ca(m["E_r"])
            int_a2 += -ca.dot(q1, ca.mtimes(E_r, y))           # 2 w1 wc
            int_ad2 += -2 * ca.dot(q1d, ca.mtimes(E_r, yd))    # 2 w1d wcd
        int_a2 += 0.25 * _quad(F_r, y)                         # wc^2
        int_ad2 += _quad(F_r, yd)                              # wcd^2
        int_a_bd += -0.5 * ca.dot(y, ca.mtimes(G_r, q2d))      # wc w2d
        int_ad_b += -ca.dot(yd, ca.mtimes(G_r, q2))            # wcd w2
    int_b2 = _quad(m["M2"], q2)
    int_bd2 = _quad(m["M2"], q2d)
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
        """Return ``(theta, q1, q2)`` views of a coordinate vector (NumPy or CasADi).

        Parameters
        ----------
        q : array_like (n_q,)
            Coordinates ``[theta, q1, q2]`` [rad, m].
        """
        return q[0], q[self.axial_slice], q[self.transverse_slice]

    # -- parameters and functions ----------------------------------------------
    def _build(self):
        self.parametric = parametric_model(self.name, self.n_axial, self.n_transverse)
        self.p = self.parametric.values(self._parameter_fields())

    def _parameter_fields(self) -> dict:
        """Every parameter-dependent number of the equations, by the names of the layout."""
        b, m = self.basis, self.basis.total
        n1 = self.n_axial
        fields = {"J_h": self.params.J_h, "J": m.J, "V1": m.V1[:n1], "V2": m.V2,
                  "M1": m.M1[:n1, :n1], "M2": m.M2, "R": m.R[:n1], "D": m.D,
                  "K1": b.K1[:n1, :n1], "K2": b.K2, "C": self._damping_diagonal(),
                  "f1_tip": b.f1_tip[:n1], "f2_tip": b.f2_tip, "S_tip": b.S_tip}
        if self.spec.foreshortening == "complete":
            red = reduced_foreshortening(m)
            fields.update(E_r=red["E_r"][:n1], G_r=red["G_r"], F_r=red["F_r"])
        return fields

    def _damping_diagonal(self) -> np.ndarray:
        """Modal damping ``2 zeta sqrt(K_ii M_ii)`` of the clamped modes, ``[q1, q2]`` [N s/m]."""
        zeta = self.params.damping_ratio
        b = self.basis
        out = []
        for n, K, Mm in ((self.n_axial, b.K1, b.beam.M1), (self.n_transverse, b.K2, b.beam.M2)):
            out.append(2 * zeta * np.sqrt(np.diag(K)[:n] * np.diag(Mm)[:n]))
        return np.concatenate(out)

    def bind(self, function: ca.Function) -> ca.Function:
        """A parametric function (last input ``p``) with this model's parameters built in.

        Parameters
        ----------
        function : casadi.Function
            One of :attr:`parametric`'s functions.

        Returns
        -------
        casadi.Function
            The same function without the input ``p`` (SX, callable on SX, MX or numbers).
        """
        names = function.name_in()[:-1]
        args = [ca.SX.sym(n, function.sparsity_in(i)) for i, n in enumerate(names)]
        outs = function.call(args + [ca.SX(ca.DM(self.p))])
        return ca.Function(function.name(), args, outs, names, function.name_out(), {"cse": True})

    @property
    def mass_matrix_function(self) -> ca.Function:
        """``M(q)``: the mass matrix (built on first use)."""
        return self._bound("mass_matrix")

    @property
    def bias_function(self) -> ca.Function:
        """``c(q, v)``: velocity, stiffness and damping terms (built on first use)."""
        return self._bound("bias")

    @property
    def inverse_dynamics_function(self) -> ca.Function:
        """``f(q, v, a) = M(q) a + c(q, v)`` (built on first use)."""
        return self._bound("inverse_dynamics")

    @property
    def energy_function(self) -> ca.Function:
        """``(q, v) -> (T, U, E)`` [J] (built on first use)."""
        return self._bound("energy")

    @property
    def momentum_function(self) -> ca.Function:
        """``(q, v) -> H``, the angular momentum [kg m^2/s] (built on first use)."""
        return self._bound("momentum")

    @property
    def q_theta_function(self) -> ca.Function:
        """``(q, v) -> Q_theta`` [N m] (built on first use)."""
        return self._bound("q_theta")

    @property
    def tip_function(self) -> ca.Function:
        """``q -> (v_tip, u_tip)`` [m] (built on first use)."""
        return self._bound("tip")

    def _bound(self, name: str) -> ca.Function:
        cache = self.__dict__.setdefault("_bound_functions", {})
        if name not in cache:
            cache[name] = self.bind(getattr(self.parametric, name))
        return cache[name]

    # -- symbolic access for integrators / linearisation ------------------------

    # -- numeric conveniences -----------------------------------------------------
    def mass_matrix(self, q) -> np.ndarray:
        """Mass matrix ``M(q)`` [kg, kg m, kg m^2 blocks].

        Parameters
        ----------
        q : array_like (n_q,)
            Coordinates ``[theta, q1, q2]`` [rad, m].
        """
        return np.array(self.parametric.mass_matrix(q, self.p))

    def bias(self, q, v) -> np.ndarray:
        """Bias vector ``c(q, v)`` (velocity, stiffness and damping terms) [N m, N].

        Parameters
        ----------
        q : array_like (n_q,)
            Coordinates ``[theta, q1, q2]`` [rad, m].
        v : array_like (n_q,)
            Velocities [rad/s, m/s].
        """
        return np.array(self.parametric.bias(q, v, self.p)).ravel()

    def accelerations(self, q, v, tau: float = 0.0) -> np.ndarray:
        """Free-hub accelerations ``M^-1 (B tau - c)`` [rad/s^2, m/s^2].

        Parameters
        ----------
        q : array_like (n_q,)
            Coordinates ``[theta, q1, q2]`` [rad, m].
        v : array_like (n_q,)
            Velocities [rad/s, m/s].
        tau : float
            Hub torque [N m].
        """
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

        Parameters
        ----------
        q : array_like (n_q,)
            Coordinates ``[theta, q1, q2]`` [rad, m].
        v : array_like (n_q,)
            Velocities [rad/s, m/s].
        a : array_like (n_q,)
            Accelerations [rad/s^2, m/s^2].
        """
        return float(self.parametric.inverse_dynamics(q, v, a, self.p)[0])

    def energy(self, q, v) -> float:
        """Total energy ``T + U`` [J].

        Parameters
        ----------
        q : array_like (n_q,)
            Coordinates ``[theta, q1, q2]`` [rad, m].
        v : array_like (n_q,)
            Velocities [rad/s, m/s].
        """
        return float(self.parametric.energy(q, v, self.p)[2])

    def angular_momentum(self, q, v) -> float:
        """Angular momentum about the hub axis ``dT/d thd`` [kg m^2/s].

        Parameters
        ----------
        q : array_like (n_q,)
            Coordinates ``[theta, q1, q2]`` [rad, m].
        v : array_like (n_q,)
            Velocities [rad/s, m/s].
        """
        return float(self.parametric.momentum(q, v, self.p))

    def q_theta(self, q, v) -> float:
        """The paper's inertia force on the hub ``Q_theta`` [N m].

        Parameters
        ----------
        q : array_like (n_q,)
            Coordinates ``[theta, q1, q2]`` [rad, m].
        v : array_like (n_q,)
            Velocities [rad/s, m/s].
        """
        return float(self.parametric.q_theta(q, v, self.p))

    def tip(self, q) -> tuple:
        """Tip displacements ``(v_tip, u_tip)`` in the hub frame [m].

        Parameters
        ----------
        q : array_like (n_q,)
            Coordinates ``[theta, q1, q2]`` [rad, m].
        """
        v_tip, u_tip = self.parametric.tip(q, self.p)
        return float(v_tip), float(u_tip)

    def tip_series(self, q) -> tuple:
        """Tip displacements of many samples at once, in NumPy (the same formulas as :meth:`tip`).

        ``v_tip = f2(l) q2`` and ``u_tip = f1(l) q1 - q2' S(l) q2 / 2`` (without the second
        term for TLAM), vectorised over the samples: no CasADi call per run.

        Parameters
        ----------
        q : array_like (N, n_q)
            Coordinates ``[theta, q1, q2]`` [rad, m], one row per sample.

        Returns
        -------
        v_tip, u_tip : ndarray (N,)
            Transverse and axial tip displacements in the hub frame [m].
        """
        q = np.asarray(q, dtype=float)
        b = self.basis
        q1, q2 = q[:, self.axial_slice], q[:, self.transverse_slice]
        v_tip = q2 @ b.f2_tip
        u_tip = q1 @ b.f1_tip[:self.n_axial] if self.n_axial else np.zeros(len(q))
        if self.spec.foreshortening != "none":
            u_tip = u_tip - 0.5 * np.einsum("ki,ij,kj->k", q2, b.S_tip, q2)
        return v_tip, u_tip

    def static_axial_stretch(self, spin: float) -> np.ndarray:
        """Steady axial coordinates ``q1`` under a constant spin with ``q2 = 0`` [m].

        Solves ``(K1 - spin^2 M1) q1 = spin^2 V1`` (exact for FOAM, CFOAM and TLAM at
        ``q2 = 0``). Empty for SFOAM.

        Parameters
        ----------
        spin : float
            Spin rate [rad/s].
        """
        if not self.n_axial:
            return np.zeros(0)
        m = self.basis.total
        return np.linalg.solve(self.basis.K1 - spin ** 2 * m.M1, spin ** 2 * m.V1)

    def steady_state(self, spin: float, theta: float = 0.0) -> np.ndarray:
        """State ``[q, v]`` of steady rotation at ``spin`` [rad/s] with the beam undeflected.

        Parameters
        ----------
        spin : float
            Spin rate [rad/s].
        theta : float
            Hub angle [rad].
        """
        x = np.zeros(2 * self.n_q)
        x[0] = theta
        x[self.axial_slice] = self.static_axial_stretch(spin)
        x[self.n_q] = spin
        return x

    def __repr__(self):
        return (f"HubBeamModel({self.name!r}, n_axial={self.n_axial}, "
                f"n_transverse={self.n_transverse}, m_t={self.params.m_t})")


def parameter_layout(name: str, n_axial: int, n_transverse: int) -> tuple:
    """Names and shapes of the parameter vector ``p`` of a model family and size.

    ``p`` holds every number of the equations that depends on :class:`Params` (the modal
    mass moments of beam plus tip mass, the hub inertia, the stiffness and damping, the
    tip shape values), each matrix flattened column by column, in this order.

    Parameters
    ----------
    name : {"cfoam", "foam", "tlam", "sfoam"}
    n_axial, n_transverse : int
        Mode counts (``n_axial`` is 0 for SFOAM).

    Returns
    -------
    tuple of (str, (rows, cols))
    """
    n1, n2 = n_axial, n_transverse
    r = n2 * (n2 + 1) // 2
    layout = [("J_h", (1, 1)), ("J", (1, 1)), ("V1", (n1, 1)), ("V2", (n2, 1)), ("M1", (n1, n1)),
              ("M2", (n2, n2)), ("R", (n1, n2)), ("D", (n2, n2)), ("K1", (n1, n1)), ("K2", (n2, n2)),
              ("C", (n1 + n2, 1)), ("f1_tip", (n1, 1)), ("f2_tip", (n2, 1)), ("S_tip", (n2, n2))]
    if MODEL_SPECS[name].foreshortening == "complete":
        layout += [("E_r", (n1, r)), ("G_r", (r, n2)), ("F_r", (r, r))]
    return tuple(layout)


class ParametricModel:
    """A model family's equations of motion with the parameters as an input vector.

    Built once per ``(name, n_axial, n_transverse)`` (:func:`parametric_model`) and valid
    for any tip mass, tip position, material or geometry: a :class:`HubBeamModel` only
    computes its parameter vector :attr:`HubBeamModel.p` and passes it as the last input.
    Every function is SX with common subexpressions shared:

    ``mass_matrix(q, p)``, ``bias(q, v, p)``, ``inverse_dynamics(q, v, a, p)``,
    ``energy(q, v, p) -> (T, U, E)``, ``momentum(q, v, p)``, ``q_theta(q, v, p)`` and
    ``tip(q, p) -> (v_tip, u_tip)`` (:attr:`FUNCTIONS`), each built on first use.

    Attributes
    ----------
    name : str
    n_axial, n_transverse, n_q, n_p : int
    layout : tuple
        See :func:`parameter_layout`.
    """

    #: The functions, by attribute name.
    FUNCTIONS = ("mass_matrix", "bias", "inverse_dynamics", "energy", "momentum", "q_theta", "tip")

    def __init__(self, name: str, n_axial: int, n_transverse: int):
        self.name, self.spec = name, MODEL_SPECS[name]
        self.n_axial, self.n_transverse = n_axial, n_transverse
        self.n_q = 1 + n_axial + n_transverse
        self.layout = parameter_layout(name, n_axial, n_transverse)
        self.n_p = sum(r * c for _, (r, c) in self.layout)
        self._build()

    def values(self, fields: dict) -> np.ndarray:
        """The parameter vector from numbers named as in :attr:`layout`.

        Parameters
        ----------
        fields : dict
            Name -> value of every entry of :attr:`layout` (SI units).
        """
        parts = []
        for key, shape in self.layout:
            a = np.asarray(fields[key], dtype=float)
            if a.size != shape[0] * shape[1]:
                raise ParameterError(f"parameter {key} must have shape {shape}, got {a.shape}")
            parts.append(a.reshape(shape).ravel(order="F"))
        return np.concatenate(parts) if parts else np.zeros(0)

    def _unpack(self, p) -> dict:
        out, k = {}, 0
        for key, (r, c) in self.layout:
            out[key] = ca.reshape(p[k:k + r * c], r, c)
            k += r * c
        return out

    def _build(self):
        n1, nq, spec = self.n_axial, self.n_q, self.spec
        q, v, a = ca.SX.sym("q", nq), ca.SX.sym("v", nq), ca.SX.sym("a", nq)
        p = ca.SX.sym("p", self.n_p)
        f = self._unpack(p)
        q1, q2 = q[1:1 + n1], q[1 + n1:]
        q1d, q2d = v[1:1 + n1], v[1 + n1:]
        T = kinetic_energy(spec, f, f["J_h"], v[0], q1, q2, q1d, q2d)
        U = potential_energy(f["K1"], f["K2"], q1, q2)
        M = ca.hessian(T, v)[0]
        dT_dv = ca.gradient(T, v)
        dT_dq = ca.gradient(T, q)
        inertial = ca.jtimes(dT_dv, q, v) - dT_dq               # velocity terms
        q_theta = -inertial[0]
        if not spec.hub_velocity_terms:
            inertial[0] = 0
        elastic = ca.gradient(U, q) + ca.vertcat(0, f["C"] * v[1:])
        bias = inertial + elastic
        # d/dt dT/dv - dT/dq in one forward sweep over (q, v) in the direction (v, a): the
        # foreshortening products are differentiated once, not once per direction (18 % fewer
        # instructions for CFOAM 10+10 than M a + c as two sweeps)
        generalized_force = ca.jtimes(dT_dv, ca.vertcat(q, v), ca.vertcat(v, a)) - dT_dq + elastic
        if not spec.hub_velocity_terms:                         # SFOAM: the hub row keeps M a only
            generalized_force[0] = ca.jtimes(dT_dv[0], v, a)
        v_tip = ca.dot(f["f2_tip"], q2)
        u_tip = ca.dot(f["f1_tip"], q1) if n1 else 0 * v_tip
        if spec.foreshortening != "none":
            u_tip = u_tip - 0.5 * _quad(f["S_tip"], q2)
        # the expressions are built here; each Function on first use (creating one costs about as
        # much as the expression graph is large: 0.3-0.9 s each for CFOAM 10+10, and the plant step
        # needs only inverse_dynamics)
        self._definitions = {
            "mass_matrix": ("M", [q, p], [M], ["q", "p"], ["M"]),
            "bias": ("c", [q, v, p], [bias], ["q", "v", "p"], ["c"]),
            "inverse_dynamics": ("inverse_dynamics", [q, v, a, p], [generalized_force],
                                 ["q", "v", "a", "p"], ["f"]),
            "energy": ("energy", [q, v, p], [T, U, T + U], ["q", "v", "p"], ["T", "U", "E"]),
            "momentum": ("momentum", [q, v, p], [dT_dv[0]], ["q", "v", "p"], ["H"]),
            "q_theta": ("q_theta", [q, v, p], [q_theta], ["q", "v", "p"], ["Q_theta"]),
            "tip": ("tip", [q, p], [v_tip, u_tip], ["q", "p"], ["v_tip", "u_tip"]),
        }

    def __getattr__(self, name: str):
        """Build one of the functions (:attr:`FUNCTIONS`) on first use and keep it."""
        definitions = self.__dict__.get("_definitions", {})
        if name not in definitions:
            raise AttributeError(f"{type(self).__name__!s} has no attribute {name!r}")
        f = ca.Function(*definitions[name], {"cse": True})
        setattr(self, name, f)
        return f

    def __repr__(self):
        return f"ParametricModel({self.name!r}, n_axial={self.n_axial}, n_transverse={self.n_transverse})"


@lru_cache(maxsize=32)
def parametric_model(name: str, n_axial: int, n_transverse: int) -> ParametricModel:
    """Build (and cache) a model family's parametric equations (see :class:`ParametricModel`).

    Parameters
    ----------
    name : {"cfoam", "foam", "tlam", "sfoam"}
    n_axial, n_transverse : int
        Mode counts (``n_axial`` 0 for SFOAM).

    Returns
    -------
    ParametricModel
    """
    return ParametricModel(name, n_axial, n_transverse)


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
