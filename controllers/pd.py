"""Collocated PD control of the hub toward a reference (the classic design)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.core.settings import setting

from .base import Controller, DesignModel, Reference, TrackingSettings, check_positive, saturate

__all__ = ["PDSettings", "PD", "pd_gains"]


def pd_gains(bandwidth: float, damping: float, inertia: float) -> tuple:
    """PD gains that give the rigid hub a second-order closed loop.

    ``J s^2 + kd s + kp = J (s^2 + 2 zeta w s + w^2)``, i.e. ``kp = J w^2``,
    ``kd = 2 zeta w J``.

    Parameters
    ----------
    bandwidth : float
        Closed-loop natural frequency w [rad/s], > 0.
    damping : float
        Damping ratio zeta [-], > 0.
    inertia : float
        Rigid-body inertia J [kg m^2], > 0.

    Returns
    -------
    kp : float
        Angle gain [N m/rad].
    kd : float
        Rate gain [N m s/rad].

    Examples
    --------
    >>> pd_gains(1.0, 0.7, 300.0)
    (300.0, 420.0)
    """
    w = check_positive("bandwidth", bandwidth, "rad/s")
    z = check_positive("damping", damping, "-")
    J = check_positive("inertia", inertia, "kg m^2")
    return J * w * w, 2 * z * w * J


@dataclass(frozen=True)
class PDSettings(TrackingSettings):
    """Settings of :class:`PD`. Gains default to :func:`pd_gains` of bandwidth and damping."""

    bandwidth: float = setting(1.0, unit="rad/s", lo=0.0, lo_open=True,
                               doc="Rigid-body closed-loop natural frequency (used when kp/kd are None).")
    damping: float = setting(0.9, lo=0.0, lo_open=True,
                             doc="Rigid-body closed-loop damping ratio (used when kp/kd are None).")
    kp: float | None = setting(None, unit="N m/rad", lo=0.0, kind=float,
                               doc="Angle gain; overrides the bandwidth design.")
    kd: float | None = setting(None, unit="N m s/rad", lo=0.0, kind=float,
                               doc="Rate gain; overrides the bandwidth design.")
    roll_off_hz: float | None = setting(None, unit="Hz", lo=0.0, lo_open=True, hi=1e6, kind=float,
                                        doc="Corner of a first-order low-pass on the feedback torque (sampled "
                                            "exactly, pole exp(-2 pi f dt)): a static PD under a zero-order hold "
                                            "pumps the modes above Nyquist; the roll-off takes its gain off them "
                                            "(None: no filter).")


class PD(Controller):
    """``tau = sat(tau_ff + kp (theta_ref - theta) + kd (theta_dot_ref - theta_dot))``.

    Reads the hub sensors (angle and rate, with their noise): a collocated design that
    knows nothing of the beam.

    Parameters
    ----------
    design : DesignModel
        Gives ``dt`` and the rigid inertia for the default gains.
    settings : PDSettings, optional
    reference : Reference, optional
    """

    measurement = "sensors"

    @property
    def signals(self):
        """The hub angle and rate (None on the beam alone: the closed loop's default sensors)."""
        return None if self.design.sensors is None else ("theta", "theta_dot")

    def __init__(self, design: DesignModel, settings: PDSettings | None = None,
                 reference: Reference | None = None):
        settings = settings or PDSettings()
        super().__init__(design, settings, reference)
        kp, kd = pd_gains(settings.bandwidth, settings.damping, design.inertia)
        self.kp = float(settings.kp) if settings.kp is not None else kp
        self.kd = float(settings.kd) if settings.kd is not None else kd
        self._ff = 1.0 if settings.feedforward else 0.0
        f = settings.roll_off_hz
        self._a = 0.0 if f is None else float(np.exp(-2.0 * np.pi * f * self.dt))
        self._x = 0.0

    def reset(self) -> None:
        """Clear the roll-off filter."""
        self._x = 0.0

    def feedback_matrices(self) -> tuple:
        """Output feedback ``u = -kp e_theta - kd e_theta_dot``: static, or through the roll-off's
        one state ``x_k = a x_{k-1} + (1 - a) u_k`` (``u = x_k``)."""
        D = np.array([[-self.kp, -self.kd]])
        if self.settings.roll_off_hz is None:
            return np.zeros((0, 0)), np.zeros((0, 2)), np.zeros((1, 0)), D, [], ["theta", "theta_dot"]
        a = self._a
        return (np.array([[a]]), (1 - a) * D, np.array([[a]]), (1 - a) * D, ["roll_off"], ["theta", "theta_dot"])

    def __call__(self, t: float, y) -> float:
        ref = self.reference
        k = int(round(t / self.dt))
        if k < len(ref.theta):
            th, thd, tff = ref.theta[k], ref.theta_dot[k], ref.torque[k]
        else:
            (th,), (thd,), (tff,) = ref.window(k, 1)
        if self.settings.roll_off_hz is None:       # the static PD (this order of operations, bit for bit)
            return saturate(float(self._ff * tff + self.kp * (th - y[0]) + self.kd * (thd - y[1])), self.tau_max)
        fb = self.kp * (th - y[0]) + self.kd * (thd - y[1])
        self._x = self._a * self._x + (1.0 - self._a) * fb
        return saturate(float(self._ff * tff + self._x), self.tau_max)
