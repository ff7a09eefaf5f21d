"""The sampled plant of a loop as it runs on a rig: the linear SFOAM with the drive, the viscous
friction, the sensors the controller reads, the computation delay and the anti-alias filter.

One assembly (:func:`sampled_rig_plant`) serves the margins and the filter's model
(:func:`rig_plant`, from a :class:`~controllers.DesignModel`) and the certificate
(:func:`hubbeam_ctrl.study.certificate.loop_matrix`, from the linear plant of any parameters).
"""

from __future__ import annotations

import numpy as np

from .base import DesignModel
from .sensing import with_anti_alias

__all__ = ["hardware_plant", "rig_plant", "sampled_rig_plant"]

#: Signals a controller may read besides the sensors and the states, with their row of ``C_tip``.
_TIP_ROWS = {"tip_deflection": 0, "tip_rate": 1}
#: The beam alone's signal names (its sensors and the tip's rows).
_SENSOR_ROWS = ("theta", "theta_dot", "root_moment", *_TIP_ROWS)


def _measurement_matrix(design, names) -> np.ndarray:
    """Rows of the design model's state giving the signals ``names`` (sensors or states).

    A sensor signal is the design's own row for it (:attr:`DesignModel.signals`: the beam alone's
    theta, theta_dot and root moment, or the rig's layout); the tip's deflection and rate are its
    ``C_tip`` rows; a state name (``theta``, ``theta_dot`` among them when no sensor of the rig gives
    them) is that state. The rows were once taken at the beam alone's fixed places in ``C_sensors``,
    so on a rig without a rate sensor a state feedback's ``theta_dot`` read the tip accelerometer's row
    (a stable LQR then looked unstable, radius 1.80 on ``accel_link``).
    """
    signals = [("root_moment" if s == "moment_1" else s) for s in design.signals]
    rows = []
    for name in names:
        if name in signals:
            rows.append(design.C_sensors[signals.index(name)])
        elif name in _TIP_ROWS:
            rows.append(design.C_tip[_TIP_ROWS[name]])
        else:
            row = np.zeros(design.n_x)
            row[design.state_names.index(name)] = 1.0
            rows.append(row)
    return np.array(rows).reshape(len(names), design.n_x)


def hardware_plant(A, B, hardware, command: str = "torque") -> tuple:
    """A continuous linear SFOAM with the rig's drive and viscous friction at the hub.

    The hub torque is ``g u - b theta_dot``: ``g`` the drive's torque per unit command and
    ``b`` its back-EMF damping plus the viscous friction on a DC motor commanded in volts
    (:meth:`~hubbeam_ctrl.sim.hardware.Hardware.hub_damping`), ``g = 1`` and ``b`` the viscous
    friction for a torque command. Coulomb friction and the limits are not linear and are left out.

    Parameters
    ----------
    A : ndarray (n, n)
        ``x = [theta, q2, theta_dot, q2_dot]`` [1/s].
    B : ndarray (n, 1)
        Per N m at the hub.
    hardware : Hardware or None
        The rig's (None: the beam alone).
    command : {"torque", "voltage"}
        The controller's output.

    Returns
    -------
    tuple
        ``(A, B, delay)``: the input in the command's unit, the computation delay [-].
    """
    if hardware is None:
        return A, B, 0.0
    voltage = command == "voltage" and hardware.command == "voltage"
    gain = hardware.torque_per_volt() if voltage else 1.0
    damping = hardware.hub_damping() if voltage else hardware.friction.viscous
    h = A.shape[0] // 2
    A = np.array(A, dtype=float)
    A[:, h] -= damping * np.asarray(B, dtype=float)[:, 0]
    return A, np.asarray(B, dtype=float) * gain, float(hardware.delay)


def rig_plant(d: DesignModel, inputs, hardware=None, command: str = "torque", params=None) -> tuple:
    """The sampled plant of a loop as it runs on a rig (:func:`sampled_rig_plant` of the design
    model's matrices, sensors and delay).

    Parameters
    ----------
    d : DesignModel
        The linear model (its continuous ``A``, ``B``, ``sensors``, ``delay`` without hardware).
    inputs : sequence of str
        The controller's input names.
    hardware : Hardware, optional
    command : {"torque", "voltage"}
    params : Params, optional
        The parameters of ``d``'s matrices (default ``d.params``).

    Returns
    -------
    tuple of ndarray
        ``(Ad, Bd, Cm)`` with ``Cm`` the rows of the inputs on ``[x, u_prev, f]``.
    """
    names = [("root_moment" if n == "moment_1" else n) for n in inputs]
    return sampled_rig_plant(d.A, d.B, d.dt, inputs, lambda n: _measurement_matrix(d, names), hardware=hardware,
                             command=command, delay=d.delay, layout=d.sensors, params=params or d.params,
                             spin=d.spin)[:3]


def sampled_rig_plant(A, B, dt: float, inputs, measurement, *, hardware=None, command: str = "torque",
                      delay: float = 0.0, layout=None, params=None, spin: float = 0.0, rows=None) -> tuple:
    """The sampled plant of a loop as it runs on a rig: drive, viscous friction, the sensors the
    controller reads (an accelerometer's feedthrough), the computation delay and the anti-alias
    filter. The one assembly the margins (:func:`rig_plant`) and the certificate
    (:func:`hubbeam_ctrl.study.certificate.loop_matrix`) share.

    The state is ``[x, u_prev, f]`` (:func:`hubbeam_ctrl.linear.delay.delay_augmented`; with no
    delay ``u_prev`` only feeds the accelerometer; ``f`` the anti-alias filter's outputs of the
    filtered signals, :func:`controllers.sensing.with_anti_alias`).

    Parameters
    ----------
    A : ndarray (n, n)
        Continuous plant ``x = [theta, q2, theta_dot, q2_dot]`` [1/s].
    B : ndarray (n, 1)
        Per N m at the hub.
    dt : float
        Sample time [s].
    inputs : sequence of str
        The controller's input names (the rig's sensor signals when they are ``layout.signals``).
    measurement : callable
        ``measurement(n)``: the rows of the inputs on the plant state of size ``n``, for inputs that
        are not the rig's sensor signals.
    hardware : Hardware, optional
        The rig's drive, friction and delay (None: the beam alone, delayed by ``delay``).
    command : {"torque", "voltage"}
        The controller's output.
    delay : float
        Computation delay [samples] without hardware.
    layout : SensorLayout, optional
        The rig's sensors.
    params : Params, optional
        The parameters of ``A`` (for the sensors' rows).
    spin : float
        Spin rate of ``A`` [rad/s].
    rows : tuple, optional
        ``(C, D)``: the inputs' rows on the plant state with the drive's states and their
        feedthrough of the command, given instead of computed (a plant in other coordinates than
        SFOAM's, e.g. :func:`hubbeam_ctrl.study.frozen.frozen_loop`'s FOAM).

    Returns
    -------
    tuple
        ``(Ad, Bd, Cm, A)``: ``Cm`` the rows of the inputs on ``[x, u_prev, f]``; ``A`` the
        continuous plant with the drive's damping [1/s].
    """
    from hubbeam_ctrl.linear.delay import delay_augmented
    A, Bu, hw_delay = hardware_plant(A, B, hardware, command)
    if hardware is not None:
        delay = hw_delay
    rig_signals = layout is not None and list(inputs) == list(layout.signals)
    if rows is not None:
        Cm, Dm = rows
    elif rig_signals:
        Cm, Dm = layout.rows(A, Bu, params, spin)
    else:
        Cm = measurement(A.shape[0])
        Dm = np.zeros((Cm.shape[0], 1))
    Ad, Bd = delay_augmented(A, Bu, dt, delay)
    Cm = np.hstack([Cm, Dm])
    if rig_signals:                       # the rig's anti-alias filter
        Ad, Bd, Cm = with_anti_alias(Ad, Bd, Cm, layout, dt)
    return Ad, Bd, Cm, A
