"""Open-loop input-shaped slews: a rigid-body torque profile convolved with a ZV, ZVD or EI shaper.

The *base* profile drives the rigid body (inertia ``J_total``) along a rest-to-rest slew:

* ``"bangbang"``: ``+a`` then ``-a`` for ``T_b/2`` each, ``a = 4 J Theta / T_b^2`` (the
  time-optimal rigid slew);
* ``"smooth"``: the acceleration shape of :func:`controllers.slew_reference`
  (``tanh(k sin(2 pi t/T_b))``, ``k`` = flatness), peak ``J Theta / (c T_b^2)``;
* ``"feedforward"``: the reference's own rigid-body feedforward torque (any reference,
  e.g. the spin-up).

The shaper (:func:`controllers.shaping.design_shaper`, designed on the SFOAM modes at the
design spin) then spreads it over ``T_b + T_s`` with ``T_s`` the shaper's length. Every
shaper here has positive impulses summing to one, so the shaped torque never exceeds the
base profile's peak, and the rigid-body angle and final rate are those of the base
profile. The torque held over each sample is the exact average of the shaped profile over
that sample, so the sampled command keeps the profile's rate at every sample instant.

``duration`` is the whole shaped manoeuvre ``T_b + T_s``; when the base profile would need
more than ``tau_max`` in it, a :class:`ParameterError` names the shortest feasible duration.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.settings import setting

from .base import Controller, ControllerSettings, DesignModel, Reference
from .reference import slew_reference, slew_shape_constant
from .shaping import SHAPERS, Shaper, _mode_numbers, design_shaper

__all__ = ["ShapedSettings", "ShapedOpenLoop", "ZVOpenLoop", "ZVDOpenLoop", "EIOpenLoop",
           "ShapedProfile", "shaped_profile", "PROFILES"]

#: Base profiles of :class:`ShapedOpenLoop`.
PROFILES = ("bangbang", "smooth", "feedforward")


def _ends_at_rest(reference: Reference) -> bool:
    """Whether the reference's final rate is zero (to round-off of its top rate)."""
    return abs(reference.theta_dot[-1]) <= 1e-9 * max(1.0, float(np.abs(reference.theta_dot).max()))


@dataclass(frozen=True)
class ShapedSettings(ControllerSettings):
    """Settings of the open-loop shaped controllers (:class:`ShapedOpenLoop`)."""

    profile: str = setting("bangbang", choices=PROFILES,
                           doc="Base profile: bangbang or smooth (rest-to-rest slews), or feedforward "
                               "(the reference's rigid-body feedforward, shaped).")
    duration: float | None = setting(None, unit="s", lo=0.0, lo_open=True, kind=float,
                                     doc="Whole shaped manoeuvre, base profile plus shaper; None: the "
                                         "shortest one within tau_max (ignored by feedforward, which "
                                         "keeps the reference's timing).")
    angle: float | None = setting(None, unit="rad", kind=float,
                                  doc="Slew angle; None: the reference's final angle (its final rate "
                                      "must be 0).")
    tau_max: float = setting(200.0, unit="N m", lo=0.0, lo_open=True,
                             doc="Torque budget: the base profile's peak must stay within it.")
    modes: tuple = setting((1,), kind=object,
                           doc="Mode numbers of the design model to shape (1 = first bending mode); "
                               "several modes are shaped by convolving their shapers.")
    tolerance: float = setting(0.05, lo=0.0, lo_open=True, hi=0.5, hi_open=True,
                               doc="EI: allowed residual vibration at the design frequency.")
    flatness: float = setting(3.0, lo=0.0,
                              doc="smooth only: shape parameter k of controllers.slew_reference.")

    def __post_init__(self):
        super().__post_init__()
        object.__setattr__(self, "modes", _mode_numbers(self.modes, 10 ** 6))

    @classmethod
    def for_scenario(cls, scenario, **options) -> "ShapedSettings":
        """The scenario's torque budget; a smooth slew in the task's duration ``t_f`` if its
        reference ends at rest (a ``t_f`` the budget cannot do is refused when the controller is
        built, naming the shortest feasible one), else its feedforward shaped.

        Parameters
        ----------
        scenario : object
            Read: ``tau_max``, ``reference``, ``t_f`` [s].
        **options
            Ignored unless they name a field.

        Returns
        -------
        ShapedSettings
        """
        if _ends_at_rest(scenario.reference):
            chosen = {"profile": "smooth", "duration": float(scenario.t_f)}
        else:
            chosen = {"profile": "feedforward"}
        return super().for_scenario(scenario, **{**chosen, **options})


@dataclass(frozen=True, eq=False)
class ShapedProfile:
    """A shaped rigid-body torque profile.

    Attributes
    ----------
    shaper : Shaper
    inertia : float
        Rigid-body inertia [kg m^2].
    base_rate : callable
        Rigid-body rate ``omega_b(t)`` [rad/s] of the base profile, for any ``t`` (0 before
        it starts, its final rate after it ends).
    base_duration : float
        Length of the base profile [s].
    base_peak : float
        Peak ``|torque|`` of the base profile [N m] (a bound on the shaped one's).
    description : str
    """

    shaper: Shaper
    inertia: float
    base_rate: object
    base_duration: float
    base_peak: float
    description: str = ""

    @property
    def duration(self) -> float:
        """Base profile plus shaper [s]."""
        return self.base_duration + self.shaper.duration

    def rate(self, t) -> np.ndarray:
        """Rigid-body rate of the shaped profile at ``t`` [rad/s].

        Parameters
        ----------
        t : float or array_like
            Time(s) [s].
        """
        return self.shaper.apply(self.base_rate, t)

    def held_torques(self, dt: float, t_end: float) -> np.ndarray:
        """Torque to hold over ``[k dt, (k+1) dt)`` for ``k = 0..round(t_end/dt)`` [N m].

        The exact average of the shaped torque over each sample: ``J (rate(t_{k+1}) -
        rate(t_k)) / dt``.

        Parameters
        ----------
        dt : float
            Sample time [s].
        t_end : float
            Last sample [s].
        """
        t = dt * np.arange(int(round(t_end / dt)) + 2)
        return self.inertia * np.diff(self.rate(t)) / dt


def _bangbang(angle, T, J):
    a = 4.0 * angle / T ** 2
    return (lambda t: a * np.clip(0.5 * T - np.abs(np.asarray(t) - 0.5 * T), 0.0, None)), J * abs(a)


def _smooth(angle, T, J, flatness, tau_max):
    ref = slew_reference(angle, T, J, tau_max * (1 + 1e-9), T / 20000, T, flatness=flatness)
    t, w = ref.t, ref.theta_dot
    return (lambda s: np.interp(s, t, w, left=0.0, right=0.0)), float(np.max(np.abs(ref.torque)))


def _rest_to_rest(settings: ShapedSettings, shaper: Shaper, J: float, angle: float):
    """Base duration and profile of a rest-to-rest slew; raises when tau_max is too small."""
    c = 0.25 if settings.profile == "bangbang" else slew_shape_constant(settings.flatness)
    t_min = math.sqrt(J * abs(angle) / (c * settings.tau_max))     # peak = J angle / (c T^2)
    shortest = t_min + shaper.duration
    duration = shortest if settings.duration is None else settings.duration
    if duration < shortest * (1 - 1e-12):
        raise ParameterError(
            f"duration = {duration:g} s is too short: the {settings.profile} slew of {angle:.4g} rad "
            f"shaped by {shaper.name} ({shaper.duration:.4g} s) needs more than tau_max = "
            f"{settings.tau_max:g} N m; shortest feasible duration {math.ceil(shortest * 1e4) / 1e4:.4f} s")
    T = duration - shaper.duration
    if angle == 0.0:
        return T, (lambda t: np.zeros_like(np.asarray(t, dtype=float))), 0.0
    if settings.profile == "bangbang":
        return (T, *_bangbang(angle, T, J))
    return (T, *_smooth(angle, T, J, settings.flatness, settings.tau_max))


def _feedforward(settings: ShapedSettings, reference: Reference, J: float):
    peak = float(np.max(np.abs(reference.torque)))
    if peak > settings.tau_max:
        raise ParameterError(f"the reference's feedforward needs {peak:.4g} N m, more than tau_max = "
                             f"{settings.tau_max:g} N m")
    t, w = reference.t, reference.theta_dot
    return float(t[-1]), (lambda s: np.interp(s, t, w, left=w[0], right=w[-1])), peak


def _reference_angle(reference: Reference) -> float:
    if not _ends_at_rest(reference):
        raise ParameterError("angle: the reference does not end at rest (final rate "
                             f"{reference.theta_dot[-1]:.4g} rad/s); give angle= or profile='feedforward'")
    return float(reference.theta[-1] - reference.theta[0])


def shaped_profile(design: DesignModel, kind: str, settings: ShapedSettings | None = None,
                   reference: Reference | None = None, shaper: Shaper | None = None) -> ShapedProfile:
    """Build the shaped torque profile of an open-loop slew.

    Parameters
    ----------
    design : DesignModel
        Gives the modes (at the design spin) and the rigid-body inertia.
    kind : {"zv", "zvd", "ei"}
    settings : ShapedSettings, optional
    reference : Reference, optional
        The slew angle (``angle=None``) or the feedforward to shape (``"feedforward"``).
    shaper : Shaper, optional
        Use this shaper instead of designing one.

    Returns
    -------
    ShapedProfile

    Raises
    ------
    ParameterError
        If the base profile needs more than ``tau_max`` in ``duration`` (naming the shortest
        feasible duration), or a mode number does not exist.
    """
    s = settings or ShapedSettings()
    if kind not in SHAPERS:
        raise ParameterError(f"kind must be one of {', '.join(SHAPERS)}, got {kind!r}")
    shaper = shaper if shaper is not None else design_shaper(design, kind, s.modes, s.tolerance)
    J = design.inertia
    if s.profile == "feedforward":
        if reference is None or len(reference.theta) < 2:
            raise ParameterError("profile='feedforward' needs a reference")
        T, rate, peak = _feedforward(s, reference, J)
        what = f"feedforward of '{reference.description}'"
    else:
        angle = s.angle if s.angle is not None else (_reference_angle(reference) if reference else 0.0)
        T, rate, peak = _rest_to_rest(s, shaper, J, angle)
        what = f"{s.profile} slew of {angle:.4g} rad in {T:.4g} s"
    return ShapedProfile(shaper, J, rate, T, peak,
                         f"{what}, shaped by {shaper.name} ({shaper.duration:.4g} s; peak {peak:.4g} N m)")


class ShapedOpenLoop(Controller):
    """Open-loop input-shaped torque (no feedback), sampled and held.

    Parameters
    ----------
    design : DesignModel
        Its modes at the design spin give the shaper; its ``dt`` the sample time.
    settings : ShapedSettings, optional
    reference : Reference, optional
        Gives the slew angle when ``settings.angle`` is None, and the feedforward to shape
        for ``profile="feedforward"``.
    shaper : Shaper, optional
        Use this shaper instead of designing one from ``settings`` (e.g. the one-impulse
        ``Shaper([0.0], [1.0])`` for the unshaped base profile).

    Attributes
    ----------
    profile : ShapedProfile
    torques : ndarray
        Held torque of each sample [N m].

    Examples
    --------
    >>> from controllers import DesignModel, ZVDOpenLoop, ShapedSettings
    >>> ctrl = ZVDOpenLoop(DesignModel.build(n_modes=2), ShapedSettings(angle=1.0, duration=8.0))
    >>> round(ctrl.profile.shaper.duration, 3), round(ctrl.profile.base_duration, 3)
    (2.175, 5.825)
    """

    name = "shaped"
    kind = "zvd"
    measurement = "state"

    def __init__(self, design: DesignModel, settings: ShapedSettings | None = None,
                 reference: Reference | None = None, shaper: Shaper | None = None):
        settings = settings or ShapedSettings()
        if not isinstance(settings, ShapedSettings):
            raise ParameterError(f"settings must be a ShapedSettings, got {type(settings).__name__}")
        if shaper is not None and not isinstance(shaper, Shaper):
            raise ParameterError(f"shaper must be a Shaper, got {type(shaper).__name__}")
        super().__init__(design, settings, reference)
        self.profile = shaped_profile(design, self.kind, settings, reference, shaper)
        self.torques = self.profile.held_torques(self.dt, self.profile.duration + self.dt)
        self._tail = float(reference.torque[-1]) if settings.profile == "feedforward" else 0.0

    def __call__(self, t: float, y) -> float:
        k = int(round(t / self.dt))
        return float(self.torques[k]) if k < len(self.torques) else self._tail


class ZVOpenLoop(ShapedOpenLoop):
    """:class:`ShapedOpenLoop` with ZV shapers."""

    name = kind = "zv"


class ZVDOpenLoop(ShapedOpenLoop):
    """:class:`ShapedOpenLoop` with ZVD shapers."""

    name = kind = "zvd"


class EIOpenLoop(ShapedOpenLoop):
    """:class:`ShapedOpenLoop` with EI shapers (tolerance from the settings)."""

    name = kind = "ei"
