"""The rig's sensors on the beam: strain gauges anywhere along it and the tip accelerometer.

Two measured quantities beyond the hub's angle and rate (:mod:`hubbeam_ctrl.plant.sensors`):

Strain gauge at ``x``
    The bending moment ``M(x) = E I w2''(x) = E I f2''(x) q2`` [N m], from the model's
    curvature, derived like the root moment (at ``x = 0`` the row is the root sensor's,
    bit for bit). The surface strain is ``M(x) c / (E I)`` at a distance ``c`` from the
    neutral axis; the rig reports the moment, as the root gauge does.

Tip accelerometer
    The in-plane acceleration of the beam's tip (``x = L``) in the inertial frame, given in
    the hub frame: ``radial`` along the undeformed beam (outwards positive) and
    ``tangential`` (in the direction of positive hub rotation). The tip's inertial position
    ``R(theta) [r + L + u_tip(q), v_tip(q)]`` is differentiated twice by CasADi's automatic
    differentiation (``jtimes`` in ``(q, v)`` along ``(v, a)``), so every centripetal,
    Coriolis and Euler term of the model's kinematics is in it: at steady spin ``omega`` on
    a rigid beam it reads ``-omega^2 (r + L)`` radially.

Examples
--------
>>> from hubbeam_ctrl import Params
>>> p = Params(n_transverse=3)
>>> rows = moment_rows(p, [0.0], n_modes=3)
>>> from hubbeam_ctrl.plant.sensors import sensor_matrix
>>> bool((rows[0] == sensor_matrix(p, 3)[2]).all())
True
"""

from __future__ import annotations

from functools import lru_cache

import casadi as ca
import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.basis import transverse_shapes
from hubbeam_ctrl.plant.models import HubBeamModel
from hubbeam_ctrl.plant.params import Params

__all__ = ["SIGNAL_UNITS", "signal_names", "moment_rows", "tip_kinematics_function", "tip_acceleration"]

#: Units of the rig's signals by name prefix (``moment_<i>`` is the gauge ``i``, 1-based).
SIGNAL_UNITS = {"theta": "rad", "theta_dot": "rad/s", "moment": "N m", "accel_radial": "m/s^2",
                "accel_tangential": "m/s^2"}


def signal_names(n_gauges: int, accelerometer: bool) -> tuple:
    """Names of the signals of a rig's sensors, in the order of its measurement vector.

    Parameters
    ----------
    n_gauges : int
        Number of strain gauges (``moment_1`` .. ``moment_n``, in the order of their positions).
    accelerometer : bool
        A tip accelerometer (``accel_radial``, ``accel_tangential``).

    Returns
    -------
    tuple of str
        ``("theta", "theta_dot", "moment_1", ..., "accel_radial", "accel_tangential")``.
    """
    names = ("theta", "theta_dot") + tuple(f"moment_{i + 1}" for i in range(int(n_gauges)))
    return names + (("accel_radial", "accel_tangential") if accelerometer else ())


def moment_rows(params: Params, positions, n_modes: int, n_axial: int = 0) -> np.ndarray:
    """Rows giving the bending moment at each position on a plant state ``[q, v]``.

    ``M(x) = E I f2''(x) q2`` [N m]; the row at ``x = 0`` equals the root-moment row of
    :func:`~hubbeam_ctrl.plant.sensors.sensor_matrix` exactly.

    Parameters
    ----------
    params : Params
    positions : sequence of float
        Gauge positions from the beam's root [m], each in ``[0, L]``.
    n_modes : int
        Transverse modes in the state.
    n_axial : int
        Axial coordinates between ``theta`` and ``q2`` (0 for SFOAM).

    Returns
    -------
    ndarray (len(positions), 2 (1 + n_axial + n_modes))
    """
    x = np.asarray(positions, dtype=float).ravel()
    for k, xi in enumerate(x):
        if not (np.isfinite(xi) and 0.0 <= xi <= params.L):
            raise ParameterError(f"sensors.strain_gauges[{k}] must be in [0, L] = [0, {params.L:g}] [m] "
                                 f"(on the beam), got {xi:g}")
    n = 1 + n_axial + n_modes
    C = np.zeros((len(x), 2 * n))
    for k, xi in enumerate(x):
        C[k, 1 + n_axial:n] = params.EI * transverse_shapes(np.array([xi]), n_modes, params.L, 2)[0]
    return C


@lru_cache(maxsize=32)
def _kinematics(parametric) -> ca.Function:
    """``(q, v, a, p, rL) -> (pos, vel, acc)``: the tip's inertial kinematics in hub-frame components."""
    sym = parametric.sym
    nq = parametric.n_q
    q, v, a = sym.sym("q", nq), sym.sym("v", nq), sym.sym("a", nq)
    p, rL = sym.sym("p", parametric.n_p), sym.sym("rL")
    v_tip, u_tip = parametric.tip(q, p)
    c, s = ca.cos(q[0]), ca.sin(q[0])
    along, across = rL + u_tip, v_tip
    pos = ca.vertcat(c * along - s * across, s * along + c * across)       # inertial frame
    vel = ca.jtimes(pos, q, v)
    acc = ca.jtimes(vel, ca.vertcat(q, v), ca.vertcat(v, a))
    to_hub = ca.vertcat(ca.horzcat(c, s), ca.horzcat(-s, c))              # R(theta)'
    return ca.Function("tip_kinematics", [q, v, a, p, rL],
                       [ca.mtimes(to_hub, pos), ca.mtimes(to_hub, vel), ca.mtimes(to_hub, acc)],
                       ["q", "v", "a", "p", "rL"], ["pos", "vel", "acc"], {"cse": True})


def tip_kinematics_function(model: HubBeamModel) -> ca.Function:
    """The tip's inertial position, velocity and acceleration, in hub-frame components.

    Built by automatic differentiation of the tip's inertial position
    ``R(theta) [r + L + u_tip(q), v_tip(q)]`` (module docstring).

    Parameters
    ----------
    model : HubBeamModel
        A model with dynamic axial coordinates (the tip position is a function of ``q``).

    Returns
    -------
    casadi.Function
        ``(q, v, a) -> (pos [m], vel [m/s], acc [m/s^2])``, each ``[radial, tangential]``;
        ``q``, ``v``, ``a`` are coordinates [rad, m], velocities and accelerations.
    """
    if not isinstance(model, HubBeamModel):
        raise ParameterError(f"model must be a HubBeamModel, got {type(model).__name__}")
    if model.axial != "dynamic":
        raise ParameterError("sensors.tip_accelerometer needs a model with dynamic axial coordinates "
                             f"(axial = 'dynamic'), got axial = {model.axial!r}")
    f = _kinematics(model.parametric)
    nq = model.n_q
    q, v, a = ca.MX.sym("q", nq), ca.MX.sym("v", nq), ca.MX.sym("a", nq)
    rL = float(model.params.r + model.params.L)
    return ca.Function("tip_kinematics", [q, v, a], list(f(q, v, a, ca.DM(model.p), rL)),
                       ["q", "v", "a"], ["pos", "vel", "acc"])


def tip_acceleration(model: HubBeamModel, q, v, a) -> np.ndarray:
    """In-plane tip acceleration ``[radial, tangential]`` [m/s^2] of one or many samples.

    Parameters
    ----------
    model : HubBeamModel
    q, v, a : array_like (n_q,) or (N, n_q)
        Coordinates [rad, m], velocities [rad/s, m/s] and accelerations [rad/s^2, m/s^2].

    Returns
    -------
    ndarray (2,) or (N, 2)
    """
    q, v, a = (np.asarray(z, dtype=float) for z in (q, v, a))
    rows = [np.atleast_2d(z) for z in (q, v, a)]
    f = _kinematics(model.parametric)
    rL = float(model.params.r + model.params.L)
    out = np.array(f.map(len(rows[0]))(rows[0].T, rows[1].T, rows[2].T, model.p, rL)[2]).T
    return out if q.ndim == 2 else out[0]
