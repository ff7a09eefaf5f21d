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

from functools import lru_cache

import casadi as ca
import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.basis import modal_basis

# the model families' symbolic equations; their names stay importable from here
from hubbeam_ctrl.plant.parametric import (  # noqa: F401
    AXIAL_TREATMENTS,
    MODEL_NAMES,
    MODEL_SPECS,
    MX_FROM_TRANSVERSE,
    ModelSpec,
    ParametricModel,
    axial_modes,
    check_axial,
    kinetic_energy,
    pair_map,
    parameter_layout,
    parametric_model,
    potential_energy,
    reduced_foreshortening,
)
from hubbeam_ctrl.plant.params import Params

__all__ = ["MODEL_NAMES", "ModelSpec", "MODEL_SPECS", "HubBeamModel", "build_model", "resolve_model",
           "kinetic_energy", "potential_energy", "ParametricModel", "parametric_model", "parameter_layout",
           "reduced_foreshortening", "pair_map", "AXIAL_TREATMENTS", "check_axial",
           "jacobian_columns", "MX_FROM_TRANSVERSE"]

def jacobian_columns(function: ca.Function, args: list, wrt: int, out: int = 0):
    """Jacobian of output ``out`` in input ``wrt`` at ``args``, one forward derivative per column.

    For MX functions: CasADi's ``jacobian`` of an MX graph copies it once per direction (1 MB
    of C for CFOAM 10+10); this calls the one forward-derivative function ``n`` times instead
    (exact, 94 kB).

    Parameters
    ----------
    function : casadi.Function
    args : list
        Symbolic arguments, one per input.
    wrt, out : int
        Input and output indices.

    Returns
    -------
    casadi.MX or casadi.SX
        With the structural zeros of the derivatives.
    """
    forward = function.forward(1)
    nominal = function.call(args)
    zero = [ca.DM.zeros(function.sparsity_in(i)) for i in range(function.n_in())]
    eye = ca.DM.eye(function.nnz_in(wrt))
    columns = []
    for j in range(function.nnz_in(wrt)):
        seeds = list(zero)
        seeds[wrt] = eye[:, j]
        columns.append(forward.call(list(args) + nominal + seeds)[out])
    return ca.horzcat(*columns)


def _bound_function(name: str, doc: str) -> property:
    """A property: the parametric function ``name`` with the model's parameters bound in (cached)."""
    return property(lambda self: self._bound(name), doc=doc)


def _state_scalar(name: str, index: int | None, doc: str):
    """A method ``(q, v) -> float``: output ``name`` (its element ``index``) of the parametric model."""
    def method(self, q, v) -> float:
        out = getattr(self.parametric, name)(q, v, self.p)
        return float(out if index is None else out[index])
    method.__doc__ = doc + """

        Parameters
        ----------
        q, v : array_like (n_q,)
            Coordinates and velocities, as :meth:`bias` takes them.
        """
    return method


class HubBeamModel:
    """A hub-beam model with its equations of motion, built by automatic differentiation.

    Generalised coordinates ``q = [theta, q1 (n1), q2 (n2)]`` (SFOAM, or quasi-static axial
    coordinates: ``[theta, q2]``), velocities ``v = dq/dt``; the state is ``x = [q, v]``.
    Units: rad, m; rad/s, m/s.

    Use :func:`build_model` (cached) rather than the constructor.

    Parameters
    ----------
    name : {"cfoam", "foam", "tlam", "sfoam"}
    params : Params
    axial : {"dynamic", "quasi-static"}
        See :func:`build_model`.

    Attributes
    ----------
    name : str
    params : Params
    basis : ModalBasis
    axial : str
        ``"dynamic"`` or ``"quasi-static"``.
    n_q : int
        Number of generalised coordinates.
    n_axial, n_transverse : int
        Axial and transverse coordinates in ``q`` (``n_axial`` is 0 with quasi-static axial
        coordinates).
    n_axial_modes : int
        Axial modes of the model (in ``q`` or condensed).
    """

    def __init__(self, name: str, params: Params, axial: str = "dynamic"):
        if name not in MODEL_SPECS:
            raise ParameterError(f"model must be one of {', '.join(MODEL_NAMES)}, got {name!r}")
        self.name = name
        self.spec = MODEL_SPECS[name]
        self.params = params
        self.basis = modal_basis(params)
        self.n_axial_modes = params.n_axial if self.spec.axial else 0
        self.axial = check_axial(axial, name, self.n_axial_modes)
        self.n_axial = self.n_axial_modes if self.axial == "dynamic" else 0
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
        self.parametric = parametric_model(self.name, self.n_axial_modes, self.n_transverse, self.axial)
        self.p = self.parametric.values(self._parameter_fields())

    def _parameter_fields(self) -> dict:
        """Every parameter-dependent number of the equations, by the names of the layout."""
        b, m = self.basis, self.basis.total
        n1 = self.n_axial_modes
        fields = {"J_h": self.params.J_h, "J": m.J, "V1": m.V1[:n1], "V2": m.V2,
                  "M1": m.M1[:n1, :n1], "M2": m.M2, "R": m.R[:n1], "D": m.D,
                  "K1": b.K1[:n1, :n1], "K2": b.K2, "C": self._damping_diagonal(),
                  "f1_tip": b.f1_tip[:n1], "f2_tip": b.f2_tip, "S_tip": b.S_tip}
        if self.spec.foreshortening == "complete":
            red = reduced_foreshortening(m)
            fields.update(E_r=red["E_r"][:n1], G_r=red["G_r"], F_r=red["F_r"])
        if self.axial == "quasi-static":
            fields.update(zip(("lam1", "Phi1"), axial_modes(fields["K1"], fields["M1"])))
        return fields

    def _damping_diagonal(self) -> np.ndarray:
        """Modal damping ``2 zeta sqrt(K_ii M_ii)`` of the clamped modes, ``[q1, q2]`` [N s/m]
        (axial: ``damping_ratio``; transverse: :meth:`Params.transverse_damping`)."""
        b = self.basis
        out = []
        zetas = (self.params.damping_ratio, self.params.transverse_damping(self.n_transverse))
        for zeta, n, K, Mm in zip(zetas, (self.n_axial_modes, self.n_transverse), (b.K1, b.K2),
                                  (b.beam.M1, b.beam.M2)):
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
            The same function without the input ``p`` (SX or MX as ``function``; callable on
            symbols of its type or on numbers).
        """
        names = function.name_in()[:-1]
        sym = self.parametric.sym
        args = [sym.sym(n, function.sparsity_in(i)) for i, n in enumerate(names)]
        outs = function.call(args + [sym(ca.DM(self.p))])
        return ca.Function(function.name(), args, outs, names, function.name_out(), {"cse": True})

    mass_matrix_function = _bound_function("mass_matrix", "``M(q)``: the mass matrix (quasi-static axial: "
                                                          "``M(q, v)``; built on first use).")
    bias_function = _bound_function("bias", "``c(q, v)``: velocity, stiffness and damping terms (built on "
                                            "first use).")
    inverse_dynamics_function = _bound_function("inverse_dynamics", "``f(q, v, a) = M(q) a + c(q, v)`` (built on "
                                                                    "first use).")
    energy_function = _bound_function("energy", "``(q, v) -> (T, U, E)`` [J] (built on first use).")
    momentum_function = _bound_function("momentum", "``(q, v) -> H``, the angular momentum [kg m^2/s] (built on "
                                                    "first use).")
    q_theta_function = _bound_function("q_theta", "``(q, v) -> Q_theta`` [N m] (built on first use).")
    tip_function = _bound_function("tip", "``q -> (v_tip, u_tip)`` [m] (quasi-static axial: ``(q, v) -> ...``; "
                                          "built on first use).")

    def _bound(self, name: str) -> ca.Function:
        cache = self.__dict__.setdefault("_bound_functions", {})
        if name not in cache:
            cache[name] = self.bind(getattr(self.parametric, name))
        return cache[name]

    # -- numeric conveniences -----------------------------------------------------
    def mass_matrix(self, q, v=None) -> np.ndarray:
        """Mass matrix ``M(q)`` [kg, kg m, kg m^2 blocks].

        Parameters
        ----------
        q : array_like (n_q,)
            Coordinates ``[theta, q1, q2]`` [rad, m].
        v : array_like (n_q,), optional
            Velocities [rad/s, m/s]: needed with quasi-static axial coordinates, whose
            condensed Lagrangian is not quadratic in the velocities (``M(q, v)``).
        """
        return np.array(self.parametric.mass_matrix(*self._state(q, v), self.p))

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
        q, v : array_like (n_q,)
            The state, as :meth:`bias` takes it.
        tau : float
            Hub torque [N m].
        """
        rhs = -self.bias(q, v)
        rhs[0] += tau
        return np.linalg.solve(self.mass_matrix(q, v), rhs)

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
        """Hub torque that produces accelerations ``a`` [rad/s^2, m/s^2] in state ``(q, v)`` [N m]
        (as :meth:`bias` takes it).

        With the hub prescribed this is the torque the motion takes (the first row of the
        inverse dynamics ``M(q) a + c(q, v)``).

        Parameters
        ----------
        q, v, a : array_like (n_q,)
        """
        return float(self.parametric.inverse_dynamics(q, v, a, self.p)[0])

    energy = _state_scalar("energy", 2, "Total energy ``T + U`` [J].")
    angular_momentum = _state_scalar("momentum", None, "Angular momentum about the hub axis ``dT/d thd`` "
                                                       "[kg m^2/s].")
    q_theta = _state_scalar("q_theta", None, "The paper's inertia force on the hub ``Q_theta`` [N m].")

    def tip(self, q, v=None) -> tuple:
        """Tip displacements ``(v_tip, u_tip)`` in the hub frame [m].

        Parameters
        ----------
        q : array_like (n_q,)
            Coordinates [rad, m].
        v : array_like (n_q,), optional
            Velocities; needed with quasi-static axial coordinates, whose stretch depends on
            the spin and the bending rates (see :meth:`mass_matrix`).
        """
        v_tip, u_tip = self.parametric.tip(*self._state(q, v), self.p)
        return float(v_tip), float(u_tip)

    def _state(self, q, v) -> list:
        """The arguments before ``p`` of ``mass_matrix`` and ``tip``: ``q``, and ``v`` when the
        axial coordinates are condensed (they depend on the velocities)."""
        return [q] if self.axial == "dynamic" else [q, self._velocities(v, 1)]

    def _velocities(self, v, samples: int) -> np.ndarray:
        if v is None:
            raise ParameterError("v (the velocities) is needed for the tip and axial coordinates "
                                 "of a model with quasi-static axial coordinates")
        v = np.asarray(v, dtype=float)
        if v.size != samples * self.n_q:
            raise ParameterError(f"v must hold {samples} x {self.n_q} velocities, got shape {v.shape}")
        return v

    def axial_coordinates(self, q, v=None) -> np.ndarray:
        """Axial coordinates ``q1`` [m] of one or many samples.

        With dynamic axial coordinates they are part of ``q``; with quasi-static ones they
        solve the static balance at ``(q, v)`` (:meth:`ParametricModel._condensed_axial`).

        Parameters
        ----------
        q : array_like (n_q,) or (N, n_q)
            Coordinates [rad, m].
        v : array_like, same shape as ``q``, optional
            Velocities [rad/s, m/s] (needed with quasi-static axial coordinates).

        Returns
        -------
        ndarray (n_axial_modes,) or (N, n_axial_modes)
        """
        q = np.asarray(q, dtype=float)
        if self.axial == "dynamic":
            return q[..., self.axial_slice].copy()
        rows = np.atleast_2d(q)
        v = self._velocities(v, len(rows)).reshape(rows.shape)
        out = np.array(self._bound("axial_coordinates").map(len(rows))(rows.T, v.T)).T
        return out if q.ndim == 2 else out[0]

    def tip_series(self, q, v=None) -> tuple:
        """Tip displacements of many samples at once, in NumPy (the same formulas as :meth:`tip`).

        ``v_tip = f2(l) q2`` and ``u_tip = f1(l) q1 - q2' S(l) q2 / 2`` (without the second
        term for TLAM), vectorised over the samples: no CasADi call per run.

        Parameters
        ----------
        q : array_like (N, n_q)
            Coordinates ``[theta, q1, q2]`` [rad, m], one row per sample.
        v : array_like (N, n_q), optional
            Velocities [rad/s, m/s] (needed with quasi-static axial coordinates).

        Returns
        -------
        v_tip, u_tip : ndarray (N,)
            Transverse and axial tip displacements in the hub frame [m].
        """
        q = np.asarray(q, dtype=float)
        b = self.basis
        q1, q2 = self.axial_coordinates(q, v), q[:, self.transverse_slice]
        v_tip = q2 @ b.f2_tip
        u_tip = q1 @ b.f1_tip[:self.n_axial_modes] if self.n_axial_modes else np.zeros(len(q))
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
        axial = "" if self.axial == "dynamic" else f", axial={self.axial!r}"
        return (f"HubBeamModel({self.name!r}, n_axial={self.n_axial_modes}, "
                f"n_transverse={self.n_transverse}, m_t={self.params.m_t}{axial})")


def build_model(name: str, params: Params = Params(), axial: str = "dynamic") -> HubBeamModel:
    """Build (and cache) a model's equations of motion.

    Parameters
    ----------
    name : {"cfoam", "foam", "tlam", "sfoam"}
        Which model (see :data:`MODEL_SPECS`).
    params : Params
        System parameters.
    axial : {"dynamic", "quasi-static"}
        ``"dynamic"`` integrates the axial coordinates with their inertia;
        ``"quasi-static"`` solves them from their static balance at every instant (CFOAM,
        FOAM, TLAM), which removes the stiff axial modes from the state.

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
    return _build_model(name.lower(), params, axial)


@lru_cache(maxsize=32)
def _build_model(name: str, params: Params, axial: str) -> HubBeamModel:
    """The cache of :func:`build_model`, keyed by all three arguments however they were passed."""
    return HubBeamModel(name, params, axial)


# the cache behind the factory, as functools would expose it (parametric_model's: plant/parametric.py)
build_model.cache_clear, build_model.cache_info = _build_model.cache_clear, _build_model.cache_info


def resolve_model(model, params: Params | None = None, axial: str | None = None) -> HubBeamModel:
    """A built model from a name plus parameters, or a model passed through.

    Parameters
    ----------
    model : str or HubBeamModel
    params : Params, optional
        With a name: the parameters (default Table 1). With a model: must be ``None`` or
        equal to the model's own.
    axial : {"dynamic", "quasi-static"}, optional
        With a name: how the axial coordinates move (default dynamic). With a model: must
        be ``None`` or the model's own.

    Returns
    -------
    HubBeamModel
    """
    if isinstance(model, HubBeamModel):
        if params is not None and params != model.params:
            raise ParameterError("params differ from the model's own; pass one or the other")
        if axial is not None and axial != model.axial:
            raise ParameterError(f"axial = {axial!r} differs from the model's own ({model.axial!r})")
        return model
    if params is not None and not isinstance(params, Params):
        raise ParameterError(f"params must be a Params, got {type(params).__name__}")
    return build_model(model, params if params is not None else Params(), axial or "dynamic")
