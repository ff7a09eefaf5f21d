"""The rigid body's shortest rest-to-rest slew: the yardstick of the time-optimal slew.

With a constant torque limit ``tau_max`` it is the bang-bang ``2 sqrt(|Theta| J / tau_max)``
(:func:`rigid_bang_bang_time`). On a DC drive the torque the drive gives falls with the speed
(the voltage limit through back-EMF) and friction takes its share, so the rigid body accelerates
with ``a(w) = min(tau_stall - k_emf w, tau_current) - c w - tau_c`` and brakes with
``b(w) = min(tau_stall + k_emf w, tau_current) + c w + tau_c`` (the drive's bounds of
:func:`_drive_terms`); the shortest slew still accelerates fully
up to one switching speed ``W`` and brakes fully from it (:func:`drive_bang_bang_time`):

``J int_0^W w (1/a(w) + 1/b(w)) dw = |Theta|``,  ``T = J int_0^W (1/a(w) + 1/b(w)) dw``.
"""

from __future__ import annotations

import math

from scipy import integrate, optimize

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.plant.rig import Rig

__all__ = ["rigid_bang_bang_time", "drive_bang_bang_time", "rigid_bound"]


def rigid_bang_bang_time(params: Params, slew_angle: float) -> float:
    """Shortest rest-to-rest slew of the rigid body, ``2 sqrt(|Theta| J_total / tau_max)`` [s].

    Parameters
    ----------
    params : Params
        Beam and hub (``total_inertia``, ``tau_max``).
    slew_angle : float
        Theta [rad].
    """
    return 2.0 * math.sqrt(abs(slew_angle) * params.total_inertia / params.tau_max)


def drive_bang_bang_time(inertia: float, slew_angle: float, drive: tuple) -> float:
    """Shortest rest-to-rest slew of a rigid body on a DC drive with friction [s].

    Parameters
    ----------
    inertia : float
        The rigid body's inertia about the hub, ``J_total`` [kg m^2], > 0.
    slew_angle : float
        Theta [rad], not 0.
    drive : tuple
        ``(tau_stall, k_emf, tau_current, c, tau_c, ...)`` at the hub: stall torque at the
        voltage limit [N m], back-EMF torque per hub rate [N m s], current-limit torque [N m],
        viscous friction [N m s], Coulomb friction [N m] (below the stall torque); further
        entries are ignored.

    Returns
    -------
    float
        ``T`` [s]; ``rigid_bang_bang_time`` when ``k_emf``, ``c`` and ``tau_c`` are 0 and the
        current limit is above the stall torque. A slew long enough to reach the top speed
        (where the drive's torque only balances back-EMF and friction) cruises there.

    Examples
    --------
    >>> round(drive_bang_bang_time(2.0, 1.0, (4.0, 0.0, 10.0, 0.0, 0.0)), 6)    # 2 sqrt(1 x 2 / 4)
    1.414214
    """
    stall, k, current, viscous, coulomb = (float(x) for x in drive[:5])
    theta, J = abs(float(slew_angle)), float(inertia)
    accel = lambda w: min(stall - k * w, current) - viscous * w - coulomb     # noqa: E731
    brake = lambda w: min(stall + k * w, current) + viscous * w + coulomb     # noqa: E731
    kinks = [(stall - current) / k] if k > 0 and stall > current else []

    def phases(W):
        points = [x for x in kinks if 0 < x < W] or None
        t = sum(integrate.quad(lambda w, f=f: J / f(w), 0.0, W, points=points, limit=200)[0] for f in (accel, brake))
        angle = sum(integrate.quad(lambda w, f=f: J * w / f(w), 0.0, W, points=points, limit=200)[0]
                    for f in (accel, brake))
        return t, angle

    if k + viscous > 0:                      # the top speed: the drive's torque balances back-EMF and friction
        hi = (stall - coulomb) / (k + viscous)          # the top speed without the current limit
        top = hi if accel(hi) >= -1e-12 * stall else optimize.brentq(accel, 0.0, hi)
        W_hi = top * (1.0 - 1e-9)
    else:
        W_hi = 2.0 * theta / (2.0 * math.sqrt(theta * J / max(accel(0.0), 1e-300)))
        while phases(W_hi)[1] < theta:
            W_hi *= 2.0
    t, angle = phases(W_hi)
    if angle <= theta:                       # accelerate to the top speed, cruise, brake
        return t + (theta - angle) / W_hi
    W = optimize.brentq(lambda w: phases(w)[1] - theta, 0.0, W_hi, xtol=1e-12 * W_hi, rtol=1e-12)
    return phases(W)[0]


def rigid_bound(params: Params, slew_angle: float, drive=None) -> float:
    """The yardstick of a time-optimal slew [s]: the rigid body's shortest rest-to-rest slew.

    Without a DC drive the bang-bang with ``tau_max`` (:func:`rigid_bang_bang_time`); on one
    (``drive`` from :func:`_drive_terms`, or a :class:`~hubbeam_ctrl.plant.rig.Rig`) the
    bang-bang within the voltage limit through back-EMF, the current limit and friction
    (:func:`~hubbeam_ctrl.limit.bound.drive_bang_bang_time`), which is longer.

    Parameters
    ----------
    params, slew_angle
        As :func:`rigid_bang_bang_time`.
    drive : tuple or Rig, optional
        The drive's torque bounds at the hub.
    """
    if isinstance(drive, Rig):
        drive = _drive_terms(drive)
    if drive is None:
        return rigid_bang_bang_time(params, slew_angle)
    return drive_bang_bang_time(params.total_inertia, slew_angle, drive)


def _drive_terms(rig) -> tuple | None:
    """The DC drive's torque bounds at the hub, affine in the hub rate, and the friction to overcome.

    ``|tau_drive + k_emf theta_dot| <= tau_stall`` (the voltage limit through back-EMF) and
    ``|tau_drive| <= tau_current`` (the current limit), with ``tau_stall = eta N k_t V_max / R``,
    ``k_emf = eta N^2 k_t k_e / R`` and ``tau_current = eta N k_t I_max`` (``eta`` the gear's
    driving efficiency, also while braking: conservative); ``tau_drive`` is the net hub torque
    plus viscous and Coulomb friction (the sign smoothed over ``v_c``). None without a DC motor.
    """
    if rig is None or rig.drive.is_ideal:
        return None
    d, f = rig.drive, rig.friction
    gain = d.eta_forward * d.N * d.k_torque        # eta_motor k_t: the motor's own efficiency applied
    stall = gain * min(d.V_max / d.R, d.I_max)
    if f.static >= stall:
        raise ParameterError(f"friction.breakaway ({f.static:g} N m) must be below the drive's stall torque "
                             f"{stall:.4g} N m (eta_forward N k_t min(V_max / R, I_max)): the drive cannot start "
                             "the slew in any time")
    return (gain * d.V_max / d.R, gain * d.N * d.k_e / d.R, gain * d.I_max, f.viscous, f.coulomb, 0.05)
