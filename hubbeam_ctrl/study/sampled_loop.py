"""The sampled loop as it runs, as matrices: the evaluation plant's linear SFOAM (zero-order hold,
the rig's drive, delay and sensors) closed with a controller's linear form. The certificate
(:mod:`hubbeam_ctrl.study.certificate`), the loop frozen at a bent beam
(:mod:`hubbeam_ctrl.study.frozen`) and the noise rule (:func:`hubbeam_ctrl.study.rig_loop.noise_chatter`)
build on it (split from the certificate, whose private helpers the other two imported)."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import scipy.linalg

from controllers import Controller
from controllers.loop_plant import sampled_rig_plant
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.linear.statespace import linear_matrices
from hubbeam_ctrl.plant.params import Params

__all__ = ["SENSORS", "AS_DESIGNED", "linear_plant", "measurement_rows", "loop_parts", "closed_loop_matrix",
           "loop_matrix"]

#: The plant's outputs a controller may read besides its design states (rad, rad/s, N m).
SENSORS = ("theta", "theta_dot", "root_moment")


@lru_cache(maxsize=32)
def linear_plant(params: Params, spin: float):
    """Continuous matrices of the linear SFOAM with its damping as a parameter.

    Parameters
    ----------
    params : Params
        The plant (``n_transverse`` its modes).
    spin : float
        Spin rate of the linearisation [rad/s].

    Returns
    -------
    tuple of ndarray
        ``(A0, A1, B, C)``: ``A = A0 + zeta A1`` for a modal damping ratio ``zeta`` [-] of every
        bending mode, the torque input [per N m] and the rows of :data:`SENSORS` (rad, rad/s, N m).
    """
    outputs = SENSORS
    A0, B, C, _ = linear_matrices("sfoam", spin, params.replace(damping_ratio=0.0), outputs)
    zeta = 0.01
    A1 = (np.asarray(linear_matrices("sfoam", spin, params.replace(damping_ratio=zeta), outputs)[0], dtype=float)
          - np.asarray(A0, dtype=float)) / zeta
    return np.asarray(A0, dtype=float), A1, np.asarray(B, dtype=float), np.asarray(C, dtype=float)



def _zoh(A: np.ndarray, B: np.ndarray, dt: float):
    n, m = B.shape
    E = scipy.linalg.expm(np.block([[A, B], [np.zeros((m, n + m))]]) * dt)
    return E[:n, :n], E[:n, n:]



def measurement_rows(controller: Controller, inputs, C_sensors: np.ndarray, n_plant: int) -> np.ndarray:
    """Rows of the plant state giving the controller's inputs.

    Parameters
    ----------
    controller : Controller
        Named in the error.
    inputs : sequence of str
        The signals it reads: :data:`SENSORS`, or the design model's states (``theta``,
        ``theta_dot``, ``q2_i``, ``q2_dot_i``).
    C_sensors : ndarray
        The plant's rows of :data:`SENSORS` (from :func:`linear_plant`).
    n_plant : int
        Plant states.

    Returns
    -------
    ndarray
        ``(len(inputs), n_plant)``.

    Raises
    ------
    ParameterError
        A signal the linear plant does not give.
    """
    m = n_plant // 2 - 1
    rows = []
    for label in inputs:
        if label in SENSORS:
            rows.append(C_sensors[SENSORS.index(label)])
            continue
        row = np.zeros(n_plant)
        if label == "theta":
            row[0] = 1.0
        elif label == "theta_dot":
            row[m + 1] = 1.0
        elif label.startswith("q2_dot_"):
            row[m + 1 + int(label[7:])] = 1.0
        elif label.startswith("q2_"):
            row[int(label[3:])] = 1.0
        else:
            raise ParameterError(f"controller {controller.name!r} reads {label!r}, which the linear plant "
                                 "does not give")
        rows.append(row)
    return np.array(rows).reshape(len(inputs), n_plant)



#: ``loop_matrix(hardware=AS_DESIGNED)``: the plant carries the hardware the controller was put on.
AS_DESIGNED = "as designed"


def loop_parts(controller: Controller, params: Params, spin: float, damping_ratio: float, hardware) -> tuple:
    """The pieces of the sampled loop of ``controller`` on the linear SFOAM of ``params``.

    Parameters
    ----------
    controller : Controller
        With a linear form; its ``rig_hardware`` and design's ``sensors`` and ``delay`` are the loop's.
    params : Params
        The plant, with at least the modes the controller's gain acts on.
    spin : float
        Spin rate of the linearisation [rad/s].
    damping_ratio : float
        Modal damping ratio of every bending mode [-].
    hardware : Hardware, None or AS_DESIGNED
        As :func:`loop_matrix`'s.

    Returns
    -------
    tuple
        ``(Ad, Bd, Cm, (Ak, Bk, Ck, Dk), A)``: the sampled plant as the loop sees it (with the
        rig's drive, delay and sensors when it has them), the controller's matrices
        (:meth:`~controllers.Controller.feedback_matrices`) and the continuous plant matrix [1/s].

    Raises
    ------
    ParameterError
        ``params`` with fewer modes than the controller's gain acts on (named ``plant_modes``).
    """
    needed = int(getattr(controller, "state_modes", controller.n_modes))
    if params.n_transverse < needed:
        raise ParameterError(f"plant_modes must be at least the {needed} modes the controller's gain "
                             f"acts on, got {params.n_transverse}")
    dt = float(controller.dt)
    A0, A1, B, C = linear_plant(params, float(spin))
    A = A0 + damping_ratio * A1
    Ak, Bk, Ck, Dk, _, inputs = controller.feedback_matrices()
    Ak, Bk, Ck, Dk = (np.atleast_2d(np.asarray(M, dtype=float)) for M in (Ak, Bk, Ck, Dk))
    hw = getattr(controller, "rig_hardware", None) if hardware is AS_DESIGNED else hardware
    design = getattr(controller, "design", None)
    layout = getattr(design, "sensors", None)
    if hw is None and layout is None:
        Ad, Bd = _zoh(A, B, dt)
        Cm = measurement_rows(controller, list(inputs), C, Ad.shape[0])
    else:
        Ad, Bd, Cm, A = sampled_rig_plant(A, B, dt, list(inputs),
                                          lambda n: measurement_rows(controller, list(inputs), C, n), hardware=hw,
                                          command=getattr(controller, "command", "torque"),
                                          delay=float(getattr(design, "delay", 0.0)), layout=layout, params=params,
                                          spin=float(spin))
    return Ad, Bd, Cm, (Ak, Bk, Ck, Dk), A



def closed_loop_matrix(Ad, Bd, Cm, laws) -> np.ndarray:
    """The sampled closed-loop matrix of :func:`loop_parts`' pieces.

    Parameters
    ----------
    Ad, Bd, Cm : ndarray
        The sampled plant and its measured rows.
    laws : tuple of ndarray
        The controller's ``(Ak, Bk, Ck, Dk)``.

    Returns
    -------
    ndarray
        The loop matrix (plant state, then the controller's).
    """
    Ak, Bk, Ck, Dk = laws
    nk = Ak.shape[0] if Ak.size else 0
    if nk == 0:
        return Ad + Bd @ Dk @ Cm
    return np.block([[Ad + Bd @ Dk @ Cm, Bd @ Ck], [Bk @ Cm, Ak]])



def loop_matrix(controller: Controller, params: Params, spin: float, damping_ratio: float = 0.0,
                hardware=AS_DESIGNED) -> tuple:
    """The sampled closed-loop matrix of ``controller`` on the linear SFOAM of ``params``.

    Parameters
    ----------
    controller : Controller
        With a linear form (:meth:`~controllers.Controller.feedback_matrices`).
    params : Params
        The plant (``n_transverse`` its modes, at least the controller's).
    spin : float
        Spin rate of the linearisation [rad/s].
    damping_ratio : float
        Modal damping ratio of every bending mode [-], >= 0.
    hardware : Hardware or None, optional
        The plant's drive, friction and delay (default :data:`AS_DESIGNED`: the
        ``rig_hardware`` the controller was put on; a robust certificate passes the hardware
        of another point of an uncertainty set).

    Returns
    -------
    tuple
        ``(A_loop, plant_poles_s)``: the loop matrix (plant state, then the controller's) and
        the continuous-time poles of the plant [1/s].
    """
    Ad, Bd, Cm, laws, A = loop_parts(controller, params, spin, damping_ratio, hardware)
    return closed_loop_matrix(Ad, Bd, Cm, laws), np.linalg.eigvals(A)

