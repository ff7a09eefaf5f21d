"""Derived outputs of a run (tip, Q_theta, energy, momentum, torque) in one vectorised call.

One CasADi function holds every output of a sample (common subexpressions shared), is
compiled on the compiled backend and is mapped over all samples at once, instead of one
call per output or per sample.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from hubbeam_ctrl.core.compiled import OPT_HOT, compile_function
from hubbeam_ctrl.plant.models import HubBeamModel, ParametricModel

__all__ = ["OUTPUT_NAMES", "outputs_function", "derived_outputs"]

#: Outputs of :func:`derived_outputs`, in the order of the function's rows, with units.
OUTPUT_NAMES = {"v_tip": "m", "u_tip": "m", "q_theta": "N m", "energy": "J", "angular_momentum": "kg m^2/s",
                "tau": "N m"}


def outputs_function(model: ParametricModel, with_tau: bool) -> ca.Function:
    """``(q, v[, a], p) -> [v_tip, u_tip, Q_theta, E, H(, tau)]`` of one sample.

    Built once per model family and mode counts; ``p`` is the model's parameter vector
    (:attr:`~hubbeam_ctrl.plant.models.HubBeamModel.p`).

    Parameters
    ----------
    model : ParametricModel
    with_tau : bool
        Also return the hub torque ``tau`` [N m] that produces the accelerations ``a``
        (first row of the inverse dynamics; for a prescribed hub).

    Returns
    -------
    casadi.Function
        Inputs ``q``, ``v`` (and ``a``), each ``(n_q,)``, and ``p``; one output stacking the
        rows of :data:`OUTPUT_NAMES` (without ``tau`` unless asked).
    """
    key = f"_outputs_function_{int(with_tau)}"
    cached = model.__dict__.get(key)
    if cached is not None:
        return cached
    n = model.n_q
    q, v, a = ca.SX.sym("q", n), ca.SX.sym("v", n), ca.SX.sym("a", n)
    p = ca.SX.sym("p", model.n_p)
    v_tip, u_tip = model.tip(q, p)
    rows = [v_tip, u_tip, model.q_theta(q, v, p), model.energy(q, v, p)[2], model.momentum(q, v, p)]
    inputs, names = [q, v], ["q", "v"]
    if with_tau:
        rows.append(model.inverse_dynamics(q, v, a, p)[0])
        inputs.append(a)
        names.append("a")
    f = ca.Function("outputs", inputs + [p], [ca.vertcat(*rows)], names + ["p"], ["y"], {"cse": True})
    model.__dict__[key] = f
    return f


def derived_outputs(model: HubBeamModel, q, v, a=None, backend=None) -> dict:
    """Every derived output of a run in one mapped call.

    Parameters
    ----------
    model : HubBeamModel
    q, v : ndarray (N, n_q)
        Coordinates [rad, m] and rates [rad/s, m/s] of the samples.
    a : ndarray (N, n_q), optional
        Accelerations; with them the hub torque ``tau`` is returned too.
    backend : {"auto", "compiled", "vm"}, optional
        See :mod:`hubbeam_ctrl.core.compiled`.

    Returns
    -------
    dict
        ``v_tip``, ``u_tip`` [m], ``q_theta`` [N m], ``energy`` [J], ``angular_momentum``
        [kg m^2/s] (and ``tau`` [N m]), arrays ``(N,)``.
    """
    f = compile_function(outputs_function(model.parametric, a is not None), backend, opt=OPT_HOT)
    N = len(q)
    names = list(OUTPUT_NAMES)[: f.size1_out(0)]
    if N == 0:
        return {k: np.zeros(0) for k in names}
    args = [np.asarray(x, dtype=float).T for x in ((q, v) if a is None else (q, v, a))]
    shared = [False] * len(args) + [True]          # p is the same for every sample: not repeated
    y = np.array(f.map(N, shared, [False])(*args, model.p))
    return dict(zip(names, y))
