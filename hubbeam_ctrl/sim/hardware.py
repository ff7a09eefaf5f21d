"""The hub hardware in the plant: the drive and friction between the command and the hub torque.

:class:`Hardware` maps the controller's command ``u`` (a torque [N m] for the ideal torque
drive, a voltage [V] for the DC motor) and the hub rate ``thd`` [rad/s] to the torque on
the hub, ``tau_hub = tau_drive(u, thd) - tau_friction(thd)``. The same relations are
written once (:func:`hub_torque`) for NumPy arrays and for CasADi symbols, so the plant
step (:class:`~hubbeam_ctrl.sim.stepper.PlantStepper` with ``hardware=``) applies them
inside its compiled implicit step at the end of every substep, and the tests and reports
evaluate them on samples.

DC motor with gearbox
    ``V = clip(u, +-V_max)``; ``i = clip((V - k_e N thd) / R, +-I_max)`` (the amplifier's
    current limit lowers the terminal voltage to ``R i + k_e N thd``); with an armature
    inductance ``L > 0`` the current is a state of the plant step instead,
    ``L di/dt = V - R i - k_e N thd`` by backward Euler over each substep
    (:func:`inductive_current`; the amplifier clips it to ``+-I_max``); motor torque
    ``k_t i``, mechanical power at the motor shaft ``P_m = k_t i N thd``. The gear passes
    ``eta_forward`` of the power while the motor drives the load (``P_m >= 0``, at rest
    too) and ``1 / eta_backward`` while the load drives the gear (``P_m < 0``: braking,
    the power flows back), so the hub torque is ``eta_forward N k_t i`` or
    ``N k_t i / eta_backward``. The switch is made continuous (an implicit step has no root
    on a jump): the hub torque is ``N k_t i e`` with ``e = eta_forward + (1 / eta_backward -
    eta_forward) tanh(max(x, 0))^2`` and ``x = -thd sign(i) / v_eps`` (``x > 0``: back-driven),
    so motoring and the torque at rest are exactly ``eta_forward``'s and back-driving faster
    than about ``2 v_eps`` exactly ``1 / eta_backward``'s; in between the gear's loss
    ``P_gear = P_m - P_out`` may dip below zero by at most ``(1 - eta_forward) N k_t |i|
    3 v_eps``. The power balance ``V_term i = R i^2 + P_gear + P_out`` (with ``P_out =
    tau_drive thd``) holds exactly when ``k_e = k_t`` (:func:`drive_power`).

Friction (the smooth, sliding part)
    ``b thd + (F_c + (F_s - F_c) exp(-(thd / v_s)^2)) tanh(thd / v_eps)``: Coulomb's sign
    function regularised by ``tanh`` over ``v_eps`` (and a Stribeck peak ``F_s`` when
    ``breakaway`` is set). The regularisation alone lets a hub under a torque below
    breakaway creep at ``v_eps atanh(tau / F_c)``; the stepper therefore sticks the hub
    (Karnopp): a hub that slows into ``stick_velocity`` or reverses within a sample is
    held at rest while the torque needed to hold it stays within ``F_s``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.rig import Drive, Friction, Rig, Sensors, Timing

__all__ = ["Hardware", "HW_LAYOUT", "hub_torque", "drive_torque", "friction_torque", "drive_power", "motor_torque",
           "inductive_current"]

#: The hardware's numbers as the plant step reads them (its input ``hw``), in this order;
#: ``stick`` (1: the hub is held at rest) is set by the stepper at every sample. ``k_t`` is the
#: motor's shaft torque per ampere with its efficiency applied, ``eta_motor k_t``
#: (:attr:`~hubbeam_ctrl.plant.rig.Drive.k_torque`).
HW_LAYOUT = ("dc_motor", "R", "k_t", "k_e", "N", "eta_forward", "eta_backward", "V_max", "I_max",
             "viscous", "coulomb", "breakaway", "stribeck_velocity", "v_eps", "L", "stick")


def _ops(*xs):
    """``(where, clip, tanh, exp)`` for NumPy values or CasADi symbols, or :mod:`math` when every
    value is a plain Python float (one sample, no array overhead)."""
    if any(isinstance(x, (ca.SX, ca.MX, ca.DM)) for x in xs):
        return (ca.if_else, lambda v, lo, hi: ca.fmin(ca.fmax(v, lo), hi), ca.tanh, ca.exp)
    if all(type(x) is float for x in xs):
        return (lambda c, a, b: a if c else b, lambda v, lo, hi: min(max(v, lo), hi), math.tanh, math.exp)
    return (np.where, np.clip, np.tanh, np.exp)


def _efficiency(i, thd, h, clip, tanh):
    """Gear factor ``e`` of the hub torque ``N k_t i e`` (continuous switch, module docstring)."""
    x = clip(-thd * (2 * (i >= 0) - 1) / h["v_eps"], 0.0, 50.0)       # > 0: the load drives the gear
    return h["eta_forward"] + (1.0 / h["eta_backward"] - h["eta_forward"]) * tanh(x) ** 2


def _unpack(hw) -> dict:
    return {name: hw[k] for k, name in enumerate(HW_LAYOUT)}


def drive_torque(u, thd, hw):
    """Torque of the drive on the hub [N m] (see the module docstring).

    Parameters
    ----------
    u : float, ndarray or casadi symbol
        Command: torque [N m] (torque drive) or voltage [V] (DC motor).
    thd : float, ndarray or casadi symbol
        Hub rate [rad/s].
    hw : sequence
        The numbers of :data:`HW_LAYOUT` (:meth:`Hardware.values`).

    Returns
    -------
    float, ndarray or casadi symbol
    """
    h = _unpack(hw)
    where, clip, _, _ = _ops(u, thd, hw[0])
    V = clip(u, -h["V_max"], h["V_max"])
    i = clip((V - h["k_e"] * h["N"] * thd) / h["R"], -h["I_max"], h["I_max"])
    motor = h["N"] * h["k_t"] * i * _efficiency(i, thd, h, clip, _ops(u, thd, hw[0])[2])
    return where(h["dc_motor"] > 0.5, motor, u)


def motor_torque(i, thd, hw):
    """Hub torque of the geared DC motor at armature current ``i`` [N m]: ``N k_t i e`` (gear factor
    ``e`` of the module docstring).

    Parameters
    ----------
    i : float, ndarray or casadi symbol
        Armature current [A].
    thd : float, ndarray or casadi symbol
        Hub rate [rad/s].
    hw : sequence
        The numbers of :data:`HW_LAYOUT`.

    Returns
    -------
    float, ndarray or casadi symbol
    """
    h = _unpack(hw)
    _, clip, tanh, _ = _ops(i, thd, hw[0])
    return h["N"] * h["k_t"] * i * _efficiency(i, thd, h, clip, tanh)


def inductive_current(u, thd, i0, step, hw):
    """Armature current at the end of an integration step with inductance [A].

    ``L di/dt = V - R i - k_e N thd`` by the backward Euler rule over ``step`` (L-stable: the
    electrical time constant ``L / R`` may be far below the step), ``V = clip(u, +-V_max)``, the
    result clipped to ``+-I_max`` by the amplifier: ``i1 = clip((L / step i0 + V - k_e N thd) /
    (L / step + R), +-I_max)``. With ``L = 0`` it is the current of the module docstring.

    Parameters
    ----------
    u : float, ndarray or casadi symbol
        Voltage command [V].
    thd : float, ndarray or casadi symbol
        Hub rate at the end of the step [rad/s].
    i0 : float, ndarray or casadi symbol
        Current at the start of the step [A].
    step : float
        Integration step [s], > 0.
    hw : sequence
        The numbers of :data:`HW_LAYOUT`.

    Returns
    -------
    float, ndarray or casadi symbol
    """
    h = _unpack(hw)
    _, clip, _, _ = _ops(u, thd, i0, hw[0])
    V = clip(u, -h["V_max"], h["V_max"])
    g = h["L"] / step
    return clip((g * i0 + V - h["k_e"] * h["N"] * thd) / (g + h["R"]), -h["I_max"], h["I_max"])


def friction_torque(thd, hw):
    """Sliding friction torque at the hub [N m], opposing ``thd`` (see the module docstring).

    Parameters
    ----------
    thd : float, ndarray or casadi symbol
        Hub rate [rad/s].
    hw : sequence
        The numbers of :data:`HW_LAYOUT`.

    Returns
    -------
    float, ndarray or casadi symbol
    """
    h = _unpack(hw)
    _, _, tanh, exp = _ops(thd, hw[0])
    peak = (h["breakaway"] - h["coulomb"]) * exp(-(thd / h["stribeck_velocity"]) ** 2)
    return h["viscous"] * thd + (h["coulomb"] + peak) * tanh(thd / h["v_eps"])


def hub_torque(u, thd, hw):
    """Net torque of the hardware on the sliding hub: drive minus friction [N m].

    Parameters
    ----------
    u : float, ndarray or casadi symbol
        Command [N m or V].
    thd : float, ndarray or casadi symbol
        Hub rate [rad/s].
    hw : sequence
        The numbers of :data:`HW_LAYOUT`.

    Returns
    -------
    float, ndarray or casadi symbol
    """
    return drive_torque(u, thd, hw) - friction_torque(thd, hw)


def drive_power(u, thd, hw, current=None, di_dt=None) -> dict:
    """The DC drive's power flows at command ``u`` [V] and hub rate ``thd`` [rad/s].

    Parameters
    ----------
    u : float or ndarray
        Voltage command [V].
    thd : float or ndarray
        Hub rate [rad/s].
    hw : sequence
        The numbers of :data:`HW_LAYOUT`.
    current : float or ndarray, optional
        Armature current [A] when the inductance makes it a state (default: the current of the
        resistive circuit, ``clip((V - k_e N thd) / R, +-I_max)``).
    di_dt : float or ndarray, optional
        Its rate [A/s] (with ``current``; default 0).

    Returns
    -------
    dict of ndarray
        ``V`` terminal voltage ``R i + L di/dt + k_e N thd`` [V] (the command clipped to
        ``V_max``, lowered in current limit), ``i`` current [A], ``P_in = V i`` electrical power
        in, ``P_copper = R i^2``, ``P_inductor = L i di/dt`` (the rate of the magnetic energy),
        ``P_shaft = k_t i N thd`` at the motor shaft, ``P_gear = P_shaft - P_out`` gear losses,
        ``P_out = tau_drive thd`` at the hub [W], and ``tau`` the hub torque [N m]. So
        ``P_in = P_copper + P_inductor + P_gear + P_out`` whenever ``k_e = k_t``.
    """
    h = _unpack(np.asarray(hw, dtype=float))
    u, thd = np.asarray(u, dtype=float), np.asarray(thd, dtype=float)
    if current is None:
        V = np.clip(u, -h["V_max"], h["V_max"])
        i = np.clip((V - h["k_e"] * h["N"] * thd) / h["R"], -h["I_max"], h["I_max"])
        di_dt = np.zeros_like(i)
        tau = drive_torque(u, thd, hw)
    else:
        i = np.asarray(current, dtype=float)
        di_dt = np.zeros_like(i) if di_dt is None else np.asarray(di_dt, dtype=float)
        tau = motor_torque(i, thd, np.asarray(hw, dtype=float))
    P_inductor = h["L"] * i * di_dt
    V_term = h["R"] * i + h["L"] * di_dt + h["k_e"] * h["N"] * thd
    P_out = tau * thd
    P_shaft = h["k_t"] * i * h["N"] * thd
    return {"V": V_term, "i": i, "P_in": V_term * i, "P_copper": h["R"] * i * i, "P_inductor": P_inductor,
            "P_shaft": P_shaft, "P_gear": P_shaft - P_out, "P_out": P_out, "tau": tau}


@dataclass(frozen=True)
class Hardware:
    """The hardware of a rig as the closed loop applies it: drive, friction, sensors and timing.

    The drive and friction act in the plant step (:class:`~hubbeam_ctrl.sim.stepper.PlantStepper`);
    the sensors make the measurement (:class:`~hubbeam_ctrl.sim.measurement.MeasurementChain`)
    and the timing delays the command (:func:`~hubbeam_ctrl.sim.closedloop.simulate_closed_loop`).

    Parameters
    ----------
    drive : Drive
    friction : Friction
    sensors : Sensors, optional
        None: the closed loop's own sensor settings (today's).
    timing : Timing, optional
        None: no computation delay.

    Examples
    --------
    >>> from hubbeam_ctrl.plant.rig import load_rig
    >>> hw = Hardware.from_rig(load_rig("servo_link"))
    >>> round(float(hw.hub_torque(10.0, 0.0)), 4)      # stall torque at 10 V
    1.8609
    >>> Hardware.from_rig(Rig()).is_ideal
    True
    """

    drive: Drive
    friction: Friction
    sensors: Sensors | None = None
    timing: Timing | None = None

    def __post_init__(self):
        if not isinstance(self.drive, Drive) or not isinstance(self.friction, Friction):
            raise ParameterError("hardware needs a Drive and a Friction (plant.rig)")
        if self.sensors is not None and not isinstance(self.sensors, Sensors):
            raise ParameterError(f"hardware sensors must be a Sensors (plant.rig), got {type(self.sensors).__name__}")
        if self.timing is not None and not isinstance(self.timing, Timing):
            raise ParameterError(f"hardware timing must be a Timing (plant.rig), got {type(self.timing).__name__}")

    @classmethod
    def from_rig(cls, rig: Rig) -> "Hardware":
        """The hardware of a :class:`Rig`.

        Parameters
        ----------
        rig : Rig
        """
        if not isinstance(rig, Rig):
            raise ParameterError(f"rig must be a Rig, got {type(rig).__name__}")
        return cls(rig.drive, rig.friction, rig.sensors, rig.timing)

    @property
    def mechanics_ideal(self) -> bool:
        """True for the ideal torque source without friction: the plant step is then today's, bit for bit."""
        return self.drive.is_ideal and self.friction.is_ideal

    @property
    def inductive(self) -> bool:
        """True for a DC motor with armature inductance ``L > 0``: the current is a state of the plant step."""
        return not self.drive.is_ideal and self.drive.L > 0.0

    @property
    def delay(self) -> float:
        """Computation delay as a fraction of the sample [-] (0 without timing)."""
        return 0.0 if self.timing is None else self.timing.delay

    @property
    def is_ideal(self) -> bool:
        """True for the ideal torque source without friction, ideal sensors (or none given) and no
        delay: the closed loop is then today's, bit for bit."""
        return (self.mechanics_ideal and (self.sensors is None or self.sensors.is_ideal)
                and self.delay == 0.0 and self.drive.slew_rate is None)

    @property
    def command(self) -> str:
        """What the controller commands: ``"torque"`` [N m] or ``"voltage"`` [V]."""
        return "torque" if self.drive.is_ideal else "voltage"

    @property
    def command_limit(self) -> float:
        """Largest command: ``V_max`` [V] for the DC motor, ``inf`` for the torque drive."""
        return math.inf if self.drive.is_ideal else self.drive.V_max

    def values(self, stick: bool = False) -> np.ndarray:
        """The numbers of :data:`HW_LAYOUT`.

        Parameters
        ----------
        stick : bool
            The hub is held at rest.

        Returns
        -------
        ndarray (len(HW_LAYOUT),)
        """
        d, f = self.drive, self.friction
        return np.array([0.0 if d.is_ideal else 1.0, d.R, d.k_torque, d.k_e, d.N, d.eta_forward, d.eta_backward,
                         d.V_max, d.I_max, f.viscous, f.coulomb, f.static, f.stribeck_velocity, f.v_eps,
                         0.0 if d.is_ideal else d.L, 1.0 if stick else 0.0])

    def hub_torque(self, u, thd):
        """Drive minus sliding friction [N m] at command ``u`` [N m or V] and hub rate ``thd`` [rad/s].

        Parameters
        ----------
        u : float or ndarray
        thd : float or ndarray
        """
        return hub_torque(np.asarray(u, dtype=float), np.asarray(thd, dtype=float), self.values())

    def hub_torque_scalar(self, u: float, thd: float) -> float:
        """:meth:`hub_torque` for one command and one hub rate, in plain floats: the same functions
        on their :mod:`math` path (about 4 times faster than the array path; the exact-beam plant
        calls it at every Newton iteration of every step).

        Parameters
        ----------
        u : float
            Command [N m or V].
        thd : float
            Hub rate [rad/s].

        Returns
        -------
        float
            Drive minus sliding friction [N m].
        """
        return hub_torque(float(u), float(thd), self._float_values)

    @property
    def _float_values(self) -> tuple:
        """:meth:`values` as plain floats (the :mod:`math` path of the hardware's functions)."""
        cached = self.__dict__.get("_floats")
        if cached is None:
            cached = tuple(float(v) for v in self.values())
            object.__setattr__(self, "_floats", cached)
        return cached

    def torque_per_volt(self) -> float:
        """Hub torque per unit command at rest, below the current limit [N m/V] (1 for the torque drive).

        The drive linearised while motoring: ``eta_forward N k_t / R``.
        """
        d = self.drive
        return 1.0 if d.is_ideal else d.eta_forward * d.N * d.k_torque / d.R

    def back_emf_constant(self) -> float:
        """Voltage per hub rate of the back-EMF, ``k_e N`` [V s/rad] (0 for the torque drive)."""
        d = self.drive
        return 0.0 if d.is_ideal else d.k_e * d.N

    def hub_damping(self) -> float:
        """Linear damping of the hub from the drive and friction [N m s/rad]: the back-EMF's
        ``torque_per_volt * k_e N`` plus the viscous friction (Coulomb friction is not linear and
        is left out)."""
        return self.torque_per_volt() * self.back_emf_constant() + self.friction.viscous

    def clipped_torque(self, tau: float, thd: float) -> float | None:
        """The hub torque [N m] the drive gives at hub rate ``thd`` [rad/s] when the voltage that
        ``tau`` [N m] needs (:meth:`voltage_for_torque`, same efficiency) is past ``+-V_max``: the
        torque of ``+-V_max`` through the same static model; None when it is within (or a torque drive).

        Parameters
        ----------
        tau : float
        thd : float
        """
        d = self.drive
        if d.is_ideal:
            return None
        sign = 1.0 if tau >= 0 else -1.0
        x = min(max(-thd * sign / self.friction.v_eps, 0.0), 50.0)
        e = d.eta_forward + (1.0 / d.eta_backward - d.eta_forward) * math.tanh(x) ** 2
        v = d.R * tau / (d.N * d.k_torque * e) + d.k_e * d.N * thd
        if -d.V_max <= v <= d.V_max:
            return None
        return (math.copysign(d.V_max, v) - d.k_e * d.N * thd) * d.N * d.k_torque * e / d.R

    def voltage_for_torque(self, tau, thd):
        """The voltage [V] that gives the hub torque ``tau`` [N m] at hub rate ``thd`` [rad/s].

        The static inverse of the drive, clipped to ``+-V_max``: how a controller designed in torque commands
        the DC motor. For the torque drive, ``tau`` itself.

        Parameters
        ----------
        tau : float or ndarray
        thd : float or ndarray
        """
        d = self.drive
        if d.is_ideal:
            return tau
        if isinstance(tau, float) and isinstance(thd, float):      # one sample: no array overhead
            sign = 1.0 if tau >= 0 else -1.0
            x = min(max(-thd * sign / self.friction.v_eps, 0.0), 50.0)
            e = d.eta_forward + (1.0 / d.eta_backward - d.eta_forward) * math.tanh(x) ** 2
            return min(max(d.R * tau / (d.N * d.k_torque * e) + d.k_e * d.N * thd, -d.V_max), d.V_max)
        return np.clip(self.voltage_needed(tau, thd), -d.V_max, d.V_max)

    def voltage_needed(self, tau, thd) -> np.ndarray:
        """The voltage [V] the DC motor needs for the hub torque ``tau`` [N m] at the hub rate ``thd``
        [rad/s], not clipped (above ``V_max`` the drive cannot give it); for the torque drive, ``tau``.

        Parameters
        ----------
        tau, thd : array_like
            Hub torque [N m] and rate [rad/s].

        Returns
        -------
        ndarray
        """
        tau, thd = np.asarray(tau, dtype=float), np.asarray(thd, dtype=float)
        d = self.drive
        if d.is_ideal:
            return tau
        h = _unpack(self.values())
        i = tau / (d.N * d.k_torque * _efficiency(tau, thd, h, np.clip, np.tanh))     # sign(i) = sign(tau)
        return d.R * i + d.k_e * d.N * thd
