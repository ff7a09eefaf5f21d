"""Defaults that scale: weights, noise levels, settling bands and reference shaping from the
beam and the task, not from the paper's numbers.

A task (slew by ``Theta`` in ``t_f``, or spin-up to ``w_f`` in ``t_f``) on a beam (length
``L``, design model with first flexible mode ``w_1``) with a motor (``tau_max``) has natural
scales (:class:`TaskScales`): an angle ``Theta`` [rad] (for a spin-up, ``|w_f| t_f / 2``, the
angle it turns while spinning up), a time ``t_f`` [s], a length ``L`` [m], a vibration
frequency ``w_1`` [rad/s], a torque ``tau_max`` [N m], and the peaks of the reference's
rate and of the root bending moment its acceleration causes. :class:`Tolerances` holds the
dimensionless numbers that turn these scales into settings:

* LQR/LQG/MPC weights by Bryson's rule (:func:`bryson_weights`), ``w = 1 / x_allowed^2``:
  hub angle ``angle_error * Theta``, hub rate ``angle_error * Theta / (rate_time * t_f)``,
  tip deflection ``tip_deflection * L`` and every modal coordinate half of it (a mode's tip
  deflection is twice its coordinate), their rates those times ``w_1``, torque ``tau_max``;
* sensor noise (:func:`sensor_noise`): the hub-angle encoder's own specification
  ``angle_noise_rad`` (an angle is the same on any beam), the rate and root-moment sensors'
  relative to the ranges of their signals in the task;
* the Kalman filter's process noise relative to ``tau_max``;
* settling bands relative to ``Theta`` and ``L``; the residual window starting
  ``residual_delay * t_f`` after the maneuver;
* reference shaping (:func:`reference_shaping`): the flatness that keeps the reference's
  feedforward within ``feedforward_share`` of ``tau_max`` when it can.

A geometrically similar beam (lengths times ``k``, masses times ``k^3``, stiffnesses and
torques consistently, times times ``k``) has the same dimensionless settings, so the same
dimensionless closed-loop results.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.validation import check_positive

from .base import DesignModel, Reference, Weights

__all__ = ["Tolerances", "TaskScales", "task_scales", "bryson_weights", "sensor_noise",
           "kalman_noise", "settling_bands", "first_mode"]


@dataclass(frozen=True)
class Tolerances:
    """Dimensionless tolerances that make the defaults of a task (see the module docstring)."""

    angle_error: float = 1e-3
    """Allowed hub-angle error of Bryson's rule, relative to the task's angle [-], > 0."""
    rate_time: float = 0.4
    """Time over which the allowed angle error may build up, relative to t_f [-], > 0
    (allowed hub-rate error = allowed angle error / (rate_time t_f))."""
    tip_deflection: float = 2e-3
    """Allowed tip deflection of Bryson's rule, relative to L [-], > 0."""
    vibration_rate: float = 0.4
    """Allowed tip and modal rates relative to the allowed deflections times the first
    mode's frequency w_1 [-], > 0."""
    settle_angle: float = 1e-3
    """Settling band of the hub-angle error, relative to the task's angle [-], > 0."""
    settle_tip: float = 1.25e-4
    """Settling band of the tip deflection, relative to L [-], > 0 (1 mm on the paper's 8 m)."""
    residual_delay: float = 0.5
    """Start of the residual-vibration window after t_f, relative to t_f [-], >= 0."""
    angle_noise_rad: float = 1e-4
    """Hub-angle encoder noise, standard deviation [rad] (its own specification: about a
    16-bit encoder; an angle does not scale with the beam)."""
    rate_noise: float = 4e-4
    """Hub-rate sensor noise relative to the task's peak reference rate [-], >= 0."""
    moment_noise: float = 1e-3
    """Root-moment sensor noise relative to the peak quasi-static root moment of the task [-], >= 0."""
    torque_noise: float = 0.025
    """Kalman filter's process noise (torque disturbance per sample) relative to tau_max [-], > 0."""
    feedforward_share: float = 0.75
    """Largest share of tau_max the reference's feedforward may take when the task allows
    it (the rest is left to the feedback) [-], in (0, 1]."""

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name in ("residual_delay", "rate_noise", "moment_noise"):
                if not (isinstance(value, (int, float)) and not isinstance(value, bool)
                        and math.isfinite(value) and value >= 0):
                    raise ParameterError(f"{f.name} must be a finite number >= 0 [-], got {value!r}")
            else:
                check_positive(f.name, value, "-")
        if self.feedforward_share > 1:
            raise ParameterError(f"feedforward_share must be in (0, 1] [-], got {self.feedforward_share!r}")


def first_mode(design: DesignModel) -> float:
    """Lowest flexible natural frequency of the design model [rad/s] (free hub, design spin)."""
    lam = np.linalg.eigvals(design.A)
    w = np.abs(lam[np.abs(lam.imag) > 1e-9 * max(1.0, np.max(np.abs(lam)))])
    if not w.size:
        raise ParameterError("the design model has no flexible mode")
    return float(np.min(w))


@dataclass(frozen=True)
class TaskScales:
    """The scales of a task on a beam (see the module docstring).

    Attributes
    ----------
    angle : float
        Task angle [rad]: the slew angle, or ``|w_f| t_f / 2`` for a spin-up.
    duration : float
        t_f [s].
    length : float
        Beam length L [m].
    first_mode : float
        w_1 [rad/s].
    tau_max : float
        Torque budget [N m].
    peak_rate : float
        Peak |rate| of the reference [rad/s].
    peak_moment : float
        Peak |root moment| of the reference's quasi-static deflection [N m].
    """

    angle: float
    duration: float
    length: float
    first_mode: float
    tau_max: float
    peak_rate: float
    peak_moment: float


def task_scales(design: DesignModel, reference: Reference, angle: float, duration: float,
                tau_max: float) -> TaskScales:
    """The scales of a task (its reference on the design model).

    Parameters
    ----------
    design : DesignModel
    reference : Reference
        The hub reference of the task.
    angle : float
        Task angle [rad] (slew angle; ``|w_f| t_f / 2`` for a spin-up), not 0.
    duration : float
        t_f [s], > 0.
    tau_max : float
        Torque budget [N m], > 0.

    Returns
    -------
    TaskScales
    """
    angle = abs(float(angle))
    check_positive("angle", angle, "rad")
    n = design.n_modes
    moment_per_acc = float(design.C_sensors[2, 1:n + 1] @ design.quasi_static_gain)
    return TaskScales(angle=angle, duration=check_positive("duration", duration, "s"),
                      length=design.params.L, first_mode=first_mode(design),
                      tau_max=check_positive("tau_max", tau_max, "N m"),
                      peak_rate=float(np.max(np.abs(reference.theta_dot))),
                      peak_moment=abs(moment_per_acc) * float(np.max(np.abs(reference.theta_ddot))))


def bryson_weights(scales: TaskScales, tol: Tolerances = Tolerances()) -> Weights:
    """LQR/LQG/MPC weights by Bryson's rule from the task (``w = 1 / allowed^2``).

    Parameters
    ----------
    scales : TaskScales
    tol : Tolerances

    Returns
    -------
    Weights
    """
    angle = tol.angle_error * scales.angle
    rate = angle / (tol.rate_time * scales.duration)
    tip = tol.tip_deflection * scales.length
    modal = tip / 2.0                     # |f2_i(L)| = 2: a mode's tip deflection is 2 q_i
    w1 = tol.vibration_rate * scales.first_mode
    return Weights(angle=angle ** -2, rate=rate ** -2, tip=tip ** -2, tip_rate=(tip * w1) ** -2,
                   modal=modal ** -2, modal_rate=(modal * w1) ** -2, torque=scales.tau_max ** -2)


def sensor_noise(scales: TaskScales, tol: Tolerances = Tolerances()) -> dict:
    """Sensor noise standard deviations of the task (see :class:`Tolerances`).

    Returns
    -------
    dict
        ``angle_noise_rad`` [rad], ``rate_noise_rad_s`` [rad/s], ``moment_noise_nm`` [N m].
    """
    return {"angle_noise_rad": tol.angle_noise_rad,
            "rate_noise_rad_s": tol.rate_noise * scales.peak_rate,
            "moment_noise_nm": tol.moment_noise * scales.peak_moment}


def kalman_noise(scales: TaskScales, tol: Tolerances = Tolerances()) -> dict:
    """The Kalman filter's noise model: the sensors' noise and a torque process noise.

    Returns
    -------
    dict
        :func:`sensor_noise` plus ``torque_noise_nm`` [N m] and ``modal_noise`` (0: the
        torque noise drives the modes through the model).
    """
    return {**sensor_noise(scales, tol), "torque_noise_nm": tol.torque_noise * scales.tau_max,
            "modal_noise": 0.0}


def settling_bands(scales: TaskScales, tol: Tolerances = Tolerances()) -> dict:
    """Settling bands and the residual window's delay of the task.

    Returns
    -------
    dict
        ``settle_angle`` [rad], ``settle_tip`` [m], ``residual_delay`` [s].
    """
    return {"settle_angle": tol.settle_angle * scales.angle, "settle_tip": tol.settle_tip * scales.length,
            "residual_delay": tol.residual_delay * scales.duration}
