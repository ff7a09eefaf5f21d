"""Tasks in physical terms: what the hub must do, independent of how a controller does it.

A task names the motion and the time allowed for it; the scenario
(:func:`hubbeam_ctrl.study.scenarios.make_scenario`) turns it into a reference, a design
point and an open-loop baseline for a given beam and motor (``Params.tau_max``).

``Slew(angle, duration)``
    Rest-to-rest rotation of the hub by ``angle`` [rad] in ``duration`` [s]. Its open-loop
    baseline is the paper's Eq. 44 torque scaled to that angle and time,
    ``tau_m = 2 pi J_total Theta / t_f^2`` (one sine period: the rigid body starts and ends
    at rest after turning by ``Theta``).
``SpinUp(rate, duration)``
    Spin-up from rest to ``rate`` [rad/s] along the corrected Eq. 43 profile in
    ``duration`` [s], then hold; its rigid-body torque peaks at ``2 J_total w_f / t_f``.

Both say whether the motor can do them (:meth:`Slew.check_feasible`): a task that needs more
torque than the motor has is refused with one line naming the shortest feasible duration.

These task objects are not the plant-side maneuvers of :mod:`hubbeam_ctrl.plant.maneuvers`
(a prescribed hub motion or an applied torque for the open-loop simulator).

Examples
--------
>>> from hubbeam_ctrl import Params
>>> p = Params(L=1, rho=2700, A=9e-5, E=69e9, I=6.75e-11, J_h=0.02, r=0.05, m_t=0.05, tau_max=1.5)
>>> task = Slew(angle=math.pi / 2, duration=1.2)
>>> round(task.baseline_torque(p.total_inertia), 4)      # Eq. 44 amplitude [N m]
1.1575
>>> round(task.shortest_duration(p.total_inertia, p.tau_max), 4)
1.0541
>>> Slew(math.pi / 2, 0.9).check_feasible(p.total_inertia, p.tau_max)  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
hubbeam_ctrl.core.errors.ParameterError: duration must be >= 1.0541 s (the shortest ...), got 0.9 s
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.validation import check_finite, check_positive
from hubbeam_ctrl.study.bands import parse_band

__all__ = ["Slew", "SpinUp", "TASKS", "MIN_TARGET", "check_target"]

#: Smallest size of a task's target, ``|angle|`` [rad] of a slew or ``|rate|`` [rad/s] of a
#: spin-up: the task's scales (Bryson weights ~ 1 / angle^2, sensor noise, the yardstick's
#: shortest time) degenerate below it (a Riccati equation without a solution at 1e-9 rad,
#: an overflow at 1e-300, a division by zero at 0).
MIN_TARGET = 1e-6
#: The longest task duration (maneuver time) a study takes [s].
MAX_DURATION = 1e6


def check_target(name: str, value, unit: str, what: str) -> float:
    """Return ``float(value)``; raise unless it is a finite number with ``|value| >= MIN_TARGET``.

    Parameters
    ----------
    name : str
        The argument's name as the caller spelled it (starts the message).
    value : float
        The slew angle [rad] or the spin-up's final rate [rad/s].
    unit : str
        Its unit (for the message).
    what : str
        What 0 would mean, for the message (``"a slew by 0 is no task"``).

    Examples
    --------
    >>> check_target("rate", 1e-9, "rad/s", "a spin-up to rest is no task")
    Traceback (most recent call last):
    ...
    hubbeam_ctrl.core.errors.ParameterError: rate must be a finite number with |rate| >= 1e-06 [rad/s], got 1e-09
    """
    value = check_finite(name, value, unit)
    if value == 0.0:
        raise ParameterError(f"{name} must be a finite number != 0 [{unit}] ({what}), got 0")
    if abs(value) < MIN_TARGET:
        raise ParameterError(f"{name} must be a finite number with |{name}| >= {MIN_TARGET:g} [{unit}], "
                             f"got {value:g}")
    return value


def _check_bands(task) -> None:
    """Parse the task's own settling bands (:func:`~hubbeam_ctrl.study.bands.parse_band`)."""
    for key, kind in (("settle_angle", "angle"), ("settle_tip", "tip")):
        if getattr(task, key) is not None:
            object.__setattr__(task, key, parse_band(key, getattr(task, key), kind))


_BANDS_DOC = """
    settle_angle : float or str, optional
        The task's own settling band of the hub-angle error: a number [rad] or a text with a
        unit or counts (``"0.05deg"``, ``"2counts"``; :func:`hubbeam_ctrl.study.bands.parse_band`).
        Default: the task's (1e-3 of the angle, at least two counts of a rig's angle sensor).
        Applied by :func:`~hubbeam_ctrl.study.compare.compare`, which knows the rig's sensors.
    settle_tip : float or str, optional
        The task's own settling band of the tip deflection: a number [m] or ``"0.5mm"``,
        ``"1e-3L"`` (a fraction of L). Default: the task's (1.25e-4 L).
    """


class _Task:
    """What a slew and a spin-up share: the checks of their fields, the target, whether the
    motor can do them, their line in reports."""

    #: (field, unit, what 0 would mean) of the task's target.
    _target: ClassVar[tuple]

    def __post_init__(self):
        key, unit, zero = self._target
        object.__setattr__(self, key, check_target(key, getattr(self, key), unit, zero))
        object.__setattr__(self, "duration", check_positive("duration", self.duration, "s"))
        _check_bands(self)

    @property
    def target(self) -> float:
        """The slew angle [rad] or the spin-up's final rate [rad/s]."""
        return getattr(self, self._target[0])

    def check_feasible(self, inertia: float, tau_max: float, name: str = "duration") -> None:
        """Raise unless the rigid-body torque of the task (:meth:`peak_torque`) stays within ``tau_max``.

        Parameters
        ----------
        inertia : float
            Rigid-body inertia J_total [kg m^2].
        tau_max : float
            Motor torque limit [N m].
        name : str
            The duration's name as the caller spelled it (``"tf"`` on the command line).

        Raises
        ------
        ParameterError
            One line naming ``name`` and the shortest feasible duration.
        """
        if self.peak_torque(inertia) > tau_max * (1 + 1e-12):
            raise ParameterError(f"{name} must be >= {self.shortest_duration(inertia, tau_max):.5g} s (the "
                                 f"shortest in which {self._how(tau_max)}), got {self.duration:g} s")


@dataclass(frozen=True)
class Slew(_Task):
    __doc__ = """Rest-to-rest slew of the hub by ``angle`` in ``duration``.

    Parameters
    ----------
    angle : float
        Rotation Theta [rad], finite and not 0 (negative: the other way).
    duration : float
        Maneuver time t_f [s], > 0.""" + _BANDS_DOC

    angle: float
    duration: float
    settle_angle: object = None
    settle_tip: object = None
    #: Scenario name of the task.
    name: ClassVar[str] = "slew"
    _target: ClassVar[tuple] = ("angle", "rad", "a slew by 0 is no task")

    @classmethod
    def eq44(cls, tau_m: float, duration: float, inertia: float) -> "Slew":
        """The slew that the paper's Eq. 44 torque ``tau_m sin(2 pi t/t_f)`` makes.

        Parameters
        ----------
        tau_m : float
            Torque amplitude [N m], > 0.
        duration : float
            t_f [s], > 0.
        inertia : float
            Rigid-body inertia J_total [kg m^2], > 0.

        Returns
        -------
        Slew
            With ``angle = tau_m t_f^2 / (2 pi J_total)``.
        """
        tau_m = check_positive("tau_max", tau_m, "N m")
        t_f = check_positive("tf", duration, "s")
        J = check_positive("inertia", inertia, "kg m^2")
        return cls(tau_m * t_f ** 2 / (2 * math.pi * J), t_f)

    def baseline_torque(self, inertia: float) -> float:
        """Amplitude of the Eq. 44 torque that makes this slew [N m] (signed like ``angle``).

        ``tau_m = 2 pi J_total Theta / t_f^2``.

        Parameters
        ----------
        inertia : float
            Rigid-body inertia J_total [kg m^2].

        Returns
        -------
        float
        """
        return 2 * math.pi * inertia * self.angle / self.duration ** 2

    def peak_torque(self, inertia: float) -> float:
        """Peak of the Eq. 44 torque, ``|tau_m|`` [N m] (:meth:`baseline_torque`).

        Parameters
        ----------
        inertia : float
            Rigid-body inertia J_total [kg m^2].
        """
        return abs(self.baseline_torque(inertia))

    def shortest_duration(self, inertia: float, tau_max: float) -> float:
        """Shortest t_f in which ``tau_max`` makes this slew by Eq. 44 [s]:
        ``sqrt(2 pi J_total |Theta| / tau_max)``.

        Parameters
        ----------
        inertia : float
            Rigid-body inertia J_total [kg m^2].
        tau_max : float
            Motor torque limit [N m].
        """
        return math.sqrt(2 * math.pi * inertia * abs(self.angle) / tau_max)

    def _how(self, tau_max: float) -> str:
        return (f"tau_max = {tau_max:g} N m turns {abs(self.angle):.4g} rad by Eq. 44, "
                f"tau_m = 2 pi J_total Theta / tf^2")

    def describe(self, inertia: float) -> str:
        """One line for reports (the Eq. 44 baseline amplitude on the inertia ``J_total`` [kg m^2]).

        Parameters
        ----------
        inertia : float
        """
        return (f"rest-to-rest slew by Theta = {self.angle:.4f} rad in tf = {self.duration:g} s "
                f"(J_total = {inertia:.4g} kg m^2; Eq. 44 baseline amplitude "
                f"{self.baseline_torque(inertia):.4g} N m)")


@dataclass(frozen=True)
class SpinUp(_Task):
    __doc__ = """Spin-up of the hub from rest to ``rate`` in ``duration`` (corrected Eq. 43), then hold.

    Parameters
    ----------
    rate : float
        Final hub rate w_f [rad/s], finite.
    duration : float
        Spin-up time t_f [s], > 0.""" + _BANDS_DOC

    rate: float
    duration: float
    settle_angle: object = None
    settle_tip: object = None
    #: Scenario name of the task.
    name: ClassVar[str] = "spinup"
    _target: ClassVar[tuple] = ("rate", "rad/s", "a spin-up to rest is no task")

    def peak_torque(self, inertia: float) -> float:
        """Peak rigid-body torque of the profile, ``2 J_total |w_f| / t_f`` [N m].

        Parameters
        ----------
        inertia : float
            Rigid-body inertia ``J_total`` [kg m^2].
        """
        return 2 * inertia * abs(self.rate) / self.duration

    def shortest_duration(self, inertia: float, tau_max: float) -> float:
        """Shortest t_f whose rigid-body torque stays within ``tau_max`` [s]: ``2 J_total |w_f| / tau_max``.

        Parameters
        ----------
        inertia : float
            Rigid-body inertia ``J_total`` [kg m^2].
        tau_max : float
            Torque limit [N m].
        """
        return 2 * inertia * abs(self.rate) / tau_max

    def _how(self, tau_max: float) -> str:
        return f"tau_max = {tau_max:g} N m spins the hub up to {self.rate:g} rad/s"

    def describe(self, inertia: float) -> str:
        """One line for reports (``inertia`` [kg m^2] is not needed: the same signature as :meth:`Slew.describe`).

        Parameters
        ----------
        inertia : float
        """
        return f"spin-up to {self.rate:g} rad/s in tf = {self.duration:g} s (Eq. 43), then hold"


#: Scenario name -> task class.
TASKS = {cls.name: cls for cls in (Slew, SpinUp)}
