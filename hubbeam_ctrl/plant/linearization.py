"""Linearisation of any model about steady rotation, by automatic differentiation.

About the steady state ``theta_dot = spin``, ``q1 = q1*(spin)`` (axial stretch),
``q2 = 0``, ``tau = 0`` the equations ``M(q) a + c(q, v) = B tau`` give

    M0 da + G dv + K dq = B dtau,    G = dc/dv,  K = dc/dq,

with ``G`` holding the gyroscopic and damping terms and ``K`` the spin-dependent stiffness.
The first-order form has state ``[dq, dv]``. With the hub prescribed, only the elastic
rows and columns are kept (the hub's motion is given).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import casadi as ca
import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.models import HubBeamModel

__all__ = ["SecondOrderLinearization", "second_order_linearization", "first_order_matrices",
           "velocity_name"]


@dataclass(frozen=True)
class SecondOrderLinearization:
    """``M da + G dv + K dq = B dtau`` about steady spin.

    Attributes
    ----------
    M, G, K : ndarray (n, n)
        Mass, gyroscopic+damping and stiffness matrices (SI units).
    B : ndarray (n,)
        Input vector of the hub torque (zero row-sum for a prescribed hub).
    coordinate_names : list of str
    spin : float
        Spin rate [rad/s].
    hub : str
    q_eq : ndarray
        Coordinates of the steady state (``theta = 0``).
    """

    M: np.ndarray
    G: np.ndarray
    K: np.ndarray
    B: np.ndarray
    coordinate_names: list
    spin: float
    hub: str
    q_eq: np.ndarray


@lru_cache(maxsize=None)
def _jacobian_functions(model):
    """``(q, v, p) -> (dc/dq, dc/dv)`` of a :class:`ParametricModel` (once per family and size)."""
    q = model.sym.sym("q", model.n_q)
    v = model.sym.sym("v", model.n_q)
    p = model.sym.sym("p", model.n_p)
    c = model.bias(q, v, p)
    return ca.Function("dc", [q, v, p], [ca.jacobian(c, q), ca.jacobian(c, v)])


def second_order_linearization(model: HubBeamModel, spin: float = 0.0,
                               hub: str = "free") -> SecondOrderLinearization:
    """Linearise ``model`` about steady rotation at ``spin`` [rad/s].

    Parameters
    ----------
    model : HubBeamModel
    spin : float
        Steady hub rate [rad/s].
    hub : {"free", "prescribed"}

    Returns
    -------
    SecondOrderLinearization
    """
    if hub not in ("free", "prescribed"):
        raise ParameterError(f"hub must be 'free' or 'prescribed', got {hub!r}")
    if not np.isfinite(spin):
        raise ParameterError(f"spin must be finite [rad/s], got {spin}")
    x = model.steady_state(spin)
    q, v = x[: model.n_q], x[model.n_q:]
    M = model.mass_matrix(q, v)
    Kf, Gf = (np.array(a) for a in _jacobian_functions(model.parametric)(q, v, model.p))
    B = np.zeros(model.n_q)
    B[0] = 1.0
    names = model.coordinate_names
    if hub == "prescribed":
        keep = slice(1, model.n_q)
        M, Kf, Gf, B, names, q = M[keep, keep], Kf[keep, keep], Gf[keep, keep], B[keep] * 0, names[1:], q[keep]
    return SecondOrderLinearization(M=M, G=Gf, K=Kf, B=B, coordinate_names=list(names),
                                    spin=float(spin), hub=hub, q_eq=q)


def first_order_matrices(lin: SecondOrderLinearization):
    """State matrices of ``d/dt [dq, dv] = A [dq, dv] + B dtau``.

    Parameters
    ----------
    lin : SecondOrderLinearization
        ``M``, ``G``, ``K``, ``B`` of the second-order model.

    Returns
    -------
    A : ndarray (2n, 2n)
    B : ndarray (2n, 1)
    state_names : list of str
        ``[coordinate names..., coordinate names + "_dot"...]``.
    """
    n = lin.M.shape[0]
    Minv = np.linalg.inv(lin.M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ lin.K, -Minv @ lin.G]])
    B = np.concatenate([np.zeros(n), Minv @ lin.B])[:, None]
    names = list(lin.coordinate_names) + [velocity_name(c) for c in lin.coordinate_names]
    return A, B, names


def velocity_name(coordinate: str) -> str:
    """Name of a coordinate's rate: ``theta -> theta_dot``, ``q2_3 -> q2_dot_3``.

    Parameters
    ----------
    coordinate : str
        A coordinate's name (``theta``, ``q1_2``, ``q2_3``).
    """
    if "_" in coordinate and coordinate.rsplit("_", 1)[1].isdigit():
        base, index = coordinate.rsplit("_", 1)
        return f"{base}_dot_{index}"
    return f"{coordinate}_dot"
