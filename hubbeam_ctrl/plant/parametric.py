"""The equations of a model family, symbolic in its parameters.

What defines each of the four models (:data:`MODEL_SPECS`: which terms of the kinetic energy
it keeps), the energies in the modal coordinates (:func:`kinetic_energy`,
:func:`potential_energy`) and the family's equations of motion with the parameters as an
input vector (:class:`ParametricModel`, built once per family and size by
:func:`parametric_model`). A model of one beam with its numbers is
:class:`~hubbeam_ctrl.plant.models.HubBeamModel` (:mod:`hubbeam_ctrl.plant.models`, which
re-exports these names and explains the models).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import casadi as ca
import numpy as np

from hubbeam_ctrl.core.errors import ParameterError

__all__ = ["MODEL_NAMES", "ModelSpec", "MODEL_SPECS", "kinetic_energy", "potential_energy", "ParametricModel",
           "parametric_model", "parameter_layout", "reduced_foreshortening", "pair_map", "AXIAL_TREATMENTS",
           "check_axial", "MX_FROM_TRANSVERSE"]

MODEL_NAMES = ("cfoam", "foam", "tlam", "sfoam")

#: CFOAM with at least this many transverse modes is built on MX (see :class:`ParametricModel`):
#: its SX graph grows as n^4 (67k instructions for the residual at 10 + 10, half a minute to
#: compile), the MX graph not at all; below it the SX code is the faster one.
MX_FROM_TRANSVERSE = 8

#: How the axial coordinates move: integrated with their inertia, or condensed out by their
#: static balance at every instant (see :meth:`ParametricModel._condensed_axial`).
AXIAL_TREATMENTS = ("dynamic", "quasi-static")


@dataclass(frozen=True)
class ModelSpec:
    """Which terms of the kinetic energy a model keeps.

    Attributes
    ----------
    name : str
        Model name (``sfoam``, ``foam``, ``cfoam``, ``tlam``).
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


def check_axial(axial, model: str, n_axial: int) -> str:
    """``axial`` checked: one of :data:`AXIAL_TREATMENTS`, and quasi-static only with axial modes.

    Parameters
    ----------
    axial : str
        ``"dynamic"`` or ``"quasi-static"``.
    model : str
        Model name (SFOAM has no axial coordinates).
    n_axial : int
        Number of axial modes.
    """
    if axial not in AXIAL_TREATMENTS:
        raise ParameterError(f"axial must be one of {', '.join(AXIAL_TREATMENTS)}, got {axial!r}")
    if axial == "quasi-static" and (not MODEL_SPECS[model].axial or n_axial < 1):
        raise ParameterError(f"axial = 'quasi-static' needs a model with axial modes "
                             f"(cfoam, foam, tlam and n_axial >= 1), got {model} with {n_axial}")
    return axial


def axial_modes(K1, M1) -> tuple:
    """Axial modes of the clamped beam with its tip mass: ``K1 Phi = M1 Phi diag(lam)``.

    Parameters
    ----------
    K1 : ndarray (n1, n1)
        Axial stiffness [N/m].
    M1 : ndarray (n1, n1)
        Axial mass [kg].

    Returns
    -------
    lam : ndarray (n1,)
        Squared natural frequencies [1/s^2], ascending.
    Phi : ndarray (n1, n1)
        Mode shapes (columns), ``Phi' M1 Phi = I`` [1/sqrt(kg)].
    """
    Lc = np.linalg.cholesky(np.asarray(M1, dtype=float))
    Li = np.linalg.inv(Lc)
    lam, Y = np.linalg.eigh(Li @ np.asarray(K1, dtype=float) @ Li.T)
    return lam, Li.T @ Y


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
    """``y = [q2_i q2_j]`` and ``yd = [(q2_i q2d_j + q2_j q2d_i) / 2]`` over the pairs ``i <= j``.

    MX: two outer products and one selection (a graph whose size does not grow with the
    modes); SX: one scalar product per pair. The same numbers either way.
    """
    pairs = _pairs(q2.shape[0])
    if isinstance(q2, ca.MX):
        index = [j * q2.shape[0] + i for i, j in pairs]      # column-major position of (i, j)
        outer = ca.mtimes(q2, q2d.T)
        return ca.vec(ca.mtimes(q2, q2.T))[index], ca.vec(0.5 * (outer + outer.T))[index]
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


def parameter_layout(name: str, n_axial: int, n_transverse: int, axial: str = "dynamic") -> tuple:
    """Names and shapes of the parameter vector ``p`` of a model family and size.

    ``p`` holds every number of the equations that depends on :class:`Params` (the modal
    mass moments of beam plus tip mass, the hub inertia, the stiffness and damping, the
    tip shape values), each matrix flattened column by column, in this order.

    Parameters
    ----------
    name : {"cfoam", "foam", "tlam", "sfoam"}
    n_axial, n_transverse : int
        Mode counts (``n_axial`` is 0 for SFOAM).
    axial : {"dynamic", "quasi-static"}
        Quasi-static axial coordinates add the axial modes ``Phi1`` (n1, n1) [1/sqrt(kg)]
        and their squared frequencies ``lam1`` (n1,) [1/s^2].

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
    if axial == "quasi-static":
        layout += [("Phi1", (n1, n1)), ("lam1", (n1, 1))]
    return tuple(layout)


class ParametricModel:
    """A model family's equations of motion with the parameters as an input vector.

    Built once per ``(name, n_axial, n_transverse)`` (:func:`parametric_model`) and valid
    for any tip mass, tip position, material or geometry: a :class:`HubBeamModel` only
    computes its parameter vector :attr:`HubBeamModel.p` and passes it as the last input.
    Every function has its common subexpressions shared. CFOAM's from
    :data:`MX_FROM_TRANSVERSE` transverse modes on are MX (:attr:`sym`), so that the quartic
    foreshortening terms stay dense matrix products on the pair moments (the graph, its build
    and its generated C do not grow with the modes); the others are SX:

    ``mass_matrix(q, p)``, ``bias(q, v, p)``, ``inverse_dynamics(q, v, a, p)``,
    ``energy(q, v, p) -> (T, U, E)``, ``momentum(q, v, p)``, ``q_theta(q, v, p)`` and
    ``tip(q, p) -> (v_tip, u_tip)`` (:attr:`FUNCTIONS`), each built on first use. With
    ``axial="quasi-static"`` (:meth:`_condensed_axial`) ``mass_matrix`` and ``tip`` also
    take ``v`` after ``q``, and ``axial_coordinates(q, v, p) -> q1`` gives the condensed
    coordinates.

    Parameters
    ----------
    name : {"cfoam", "foam", "tlam", "sfoam"}
    n_axial, n_transverse : int
        Axial and transverse modes.
    axial : {"dynamic", "quasi-static"}
        How the axial coordinates move (:data:`AXIAL_TREATMENTS`).
    symbols : {"SX", "MX"}, optional
        Force the symbol type (default: MX for CFOAM from :data:`MX_FROM_TRANSVERSE` transverse
        modes on, else SX).

    Attributes
    ----------
    name : str
    axial : str
    n_axial, n_transverse, n_q, n_p : int
        ``n_axial`` counts the axial coordinates in ``q`` (0 when quasi-static).
    n_axial_modes : int
    layout : tuple
        See :func:`parameter_layout`.
    sym : type
        ``casadi.MX`` (CFOAM) or ``casadi.SX``: the symbols to compose its functions with.
    """

    #: The functions, by attribute name (``axial`` only for ``axial="quasi-static"``).
    FUNCTIONS = ("mass_matrix", "bias", "inverse_dynamics", "energy", "momentum", "q_theta", "tip",
                 "axial_coordinates")

    def __init__(self, name: str, n_axial: int, n_transverse: int, axial: str = "dynamic",
                 symbols: str | None = None):
        self.name, self.spec = name, MODEL_SPECS[name]
        self.axial = check_axial(axial, name, n_axial)
        self.n_axial_modes = n_axial
        self.n_axial = n_axial if self.axial == "dynamic" else 0
        self.n_transverse = n_transverse
        self.n_q = 1 + self.n_axial + n_transverse
        if symbols is None:
            large = self.spec.foreshortening == "complete" and n_transverse >= MX_FROM_TRANSVERSE
            symbols = "MX" if large else "SX"
        if symbols not in ("SX", "MX"):
            raise ParameterError(f"symbols must be 'SX' or 'MX', got {symbols!r}")
        self.sym = ca.MX if symbols == "MX" else ca.SX
        self.layout = parameter_layout(name, n_axial, n_transverse, self.axial)
        self.n_p = sum(r * c for _, (r, c) in self.layout)
        # the expressions are built on the first function asked for (__getattr__): a process whose
        # compiled functions come from the build cache by their recipes never needs them

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
        """Lagrange's equations of ``L = T - U`` by AD, with the axial coordinates integrated
        or condensed (:meth:`_condensed_axial`); each CasADi function is created on first use."""
        nq, spec = self.n_q, self.spec
        q, v, a = self.sym.sym("q", nq), self.sym.sym("v", nq), self.sym.sym("a", nq)
        p = self.sym.sym("p", self.n_p)
        f = self._unpack(p)
        n1 = self.n_axial
        q2, q2d = q[1 + n1:], v[1 + n1:]
        if self.axial == "dynamic":
            q1 = q[1:1 + n1]
            T = kinetic_energy(spec, f, f["J_h"], v[0], q1, q2, v[1:1 + n1], q2d)
        else:
            q1, T = self._condensed_axial(f, v[0], q2, q2d)
        U = potential_energy(f["K1"], f["K2"], q1, q2)
        L = T - U
        M = ca.hessian(L, v)[0]
        dL_dv, dL_dq = ca.gradient(L, v), ca.gradient(L, q)
        inertial = ca.jtimes(dL_dv, q, v) - dL_dq               # velocity and elastic terms
        q_theta = -inertial[0]
        if not spec.hub_velocity_terms:
            inertial[0] = 0
        damping = ca.vertcat(0, f["C"][self.n_axial_modes - n1:] * v[1:])
        # d/dt dL/dv - dL/dq in one forward sweep over (q, v) in the direction (v, a): the
        # foreshortening products are differentiated once, not once per direction (18 % fewer
        # instructions for CFOAM 10+10 than M a + c as two sweeps)
        generalized_force = ca.jtimes(dL_dv, ca.vertcat(q, v), ca.vertcat(v, a)) - dL_dq + damping
        if not spec.hub_velocity_terms:                         # SFOAM: the hub row keeps M a only
            generalized_force[0] = ca.jtimes(dL_dv[0], v, a)
        if self.axial == "dynamic":
            energies = [T, U, T + U]
        else:                       # L is not quadratic in v: Jacobi's energy is the conserved one
            h = ca.dot(v, dL_dv) - L
            energies = [h - U, U, h]
        v_tip = ca.dot(f["f2_tip"], q2)
        u_tip = ca.dot(f["f1_tip"], q1) if self.n_axial_modes else 0 * v_tip
        if spec.foreshortening != "none":
            u_tip = u_tip - 0.5 * _quad(f["S_tip"], q2)
        # condensed axial coordinates depend on the velocities: so do M and the tip
        state, names = ([q], ["q"]) if self.axial == "dynamic" else ([q, v], ["q", "v"])
        # the expressions are built here; each Function on first use (creating one costs about as
        # much as the expression graph is large: 0.3-0.9 s each for CFOAM 10+10, and the plant step
        # needs only inverse_dynamics)
        self._definitions = {
            "mass_matrix": ("M", state + [p], [M], names + ["p"], ["M"]),
            "bias": ("c", [q, v, p], [inertial + damping], ["q", "v", "p"], ["c"]),
            "inverse_dynamics": ("inverse_dynamics", [q, v, a, p], [generalized_force],
                                 ["q", "v", "a", "p"], ["f"]),
            "energy": ("energy", [q, v, p], energies, ["q", "v", "p"], ["T", "U", "E"]),
            "momentum": ("momentum", [q, v, p], [dL_dv[0]], ["q", "v", "p"], ["H"]),
            "q_theta": ("q_theta", [q, v, p], [q_theta], ["q", "v", "p"], ["Q_theta"]),
            "tip": ("tip", state + [p], [v_tip, u_tip], names + ["p"], ["v_tip", "u_tip"]),
        }
        if self.axial == "quasi-static":
            self._definitions["axial_coordinates"] = ("axial_coordinates", [q, v, p], [q1],
                                                      ["q", "v", "p"], ["q1"])

    def _condensed_axial(self, f: dict, thd, q2, q2d) -> tuple:
        """``(q1*, T(q1*))``: the axial coordinates from their static balance, and ``T`` there.

        Without the axial velocities in ``T`` the Lagrangian ``L = T - U`` is quadratic in
        ``q1`` and ``dL/dq1 = 0`` gives ``q1*(q, v) = -H^-1 g`` with ``H = d2L/dq1^2`` and
        ``g = dL/dq1`` at ``q1 = 0`` (both by AD). Substituting ``q1*`` leaves a Lagrangian
        ``L*(q, v)`` of ``q = [theta, q2]`` alone whose Euler-Lagrange equations are those of
        the quasi-static system (``dL/dq1 = 0`` at ``q1*``, so the chain rule adds nothing).
        ``L*`` is not quadratic in the velocities: the conserved energy is Jacobi's
        ``h = v dL*/dv - L*``, returned as ``E``; ``U`` is the strain energy at ``q1*`` and
        ``T = h - U``.

        ``H = thd^2 M1 - K1`` is inverted through the axial modes of the clamped beam with its
        tip mass (parameters ``Phi1``, ``lam1``: ``K1 Phi1 = M1 Phi1 diag(lam1)``,
        ``Phi1' M1 Phi1 = I``): ``H^-1 = Phi1 diag(1 / (thd^2 - lam1)) Phi1'``, so the
        condensation costs two small products instead of a symbolic factorisation.
        """
        n1 = self.n_axial_modes
        s1, none = self.sym.sym("q1", n1), self.sym.zeros(n1)
        T_s = kinetic_energy(self.spec, f, f["J_h"], thd, s1, q2, none, q2d)
        g = ca.substitute(ca.gradient(T_s - potential_energy(f["K1"], f["K2"], s1, q2), s1), s1, none)
        q1 = -ca.mtimes(f["Phi1"], ca.mtimes(f["Phi1"].T, g) / (thd ** 2 - f["lam1"]))   # -H^-1 g
        return q1, ca.substitute(T_s, s1, q1)

    def __getattr__(self, name: str):
        """Build one of the functions (:attr:`FUNCTIONS`) on first use and keep it."""
        if name not in self.FUNCTIONS:
            raise AttributeError(f"{type(self).__name__!s} has no attribute {name!r}")
        if "_definitions" not in self.__dict__:
            self._build()
        definitions = self.__dict__["_definitions"]
        if name not in definitions:
            raise AttributeError(f"{type(self).__name__!s} has no attribute {name!r}")
        f = ca.Function(*definitions[name], {"cse": True})
        setattr(self, name, f)
        return f

    def __repr__(self):
        return f"ParametricModel({self.name!r}, n_axial={self.n_axial}, n_transverse={self.n_transverse})"


def parametric_model(name: str, n_axial: int, n_transverse: int, axial: str = "dynamic") -> ParametricModel:
    """Build (and cache) a model family's parametric equations (see :class:`ParametricModel`).

    Parameters
    ----------
    name : {"cfoam", "foam", "tlam", "sfoam"}
    n_axial, n_transverse : int
        Mode counts (``n_axial`` 0 for SFOAM).
    axial : {"dynamic", "quasi-static"}
        How the axial coordinates move (:data:`AXIAL_TREATMENTS`).

    Returns
    -------
    ParametricModel
    """
    return _parametric_model(name, n_axial, n_transverse, axial)


@lru_cache(maxsize=32)
def _parametric_model(name: str, n_axial: int, n_transverse: int, axial: str) -> ParametricModel:
    return ParametricModel(name, n_axial, n_transverse, axial)


# the cache behind the factory, as functools would expose it
parametric_model.cache_clear, parametric_model.cache_info = _parametric_model.cache_clear, _parametric_model.cache_info
