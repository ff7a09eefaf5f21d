"""Defaults that scale: weights, noise levels, settling bands and reference shaping from the
beam and the task, not from the paper's numbers.

A task (slew by ``Theta`` in ``t_f``, or spin-up to ``w_f`` in ``t_f``) on a beam (length
``L``, design model with first flexible mode ``w_1``) with a torque budget ``tau_max`` has
natural scales (:class:`TaskScales`): an angle (the slew angle; ``|w_f| t_f / 2`` for a
spin-up, the angle it turns while spinning up) [rad], a time ``t_f`` [s], a length ``L``
[m], a vibration frequency ``w_1`` [rad/s], a torque ``tau_max`` [N m], and the peaks of the
reference's rate and of the root bending moment its acceleration causes quasi-statically.
:class:`Tolerances` holds the dimensionless numbers that turn them into settings:

* LQR/LQG/MPC weights by Bryson's rule (:func:`bryson_weights`), ``w = 1 / allowed^2``:
  hub angle ``angle_error * angle``, hub rate ``angle_error * angle / (rate_time * t_f)``,
  tip deflection ``tip_deflection * L``, every modal coordinate half of that (a mode's tip
  deflection is twice its coordinate), their rates those times ``vibration_rate * w_1``,
  torque ``tau_max``;
* sensor noise (:func:`sensor_noise`) relative to the ranges of the signals in the task
  (the angle, the peak reference rate, the peak quasi-static root moment), at the paper's
  ratios (1e-4 rad, 1e-3 rad/s, 0.02 N m on its slew);
* the Kalman filter's process noise relative to ``tau_max`` (:func:`kalman_noise`);
* settling bands relative to the angle and ``L``, the residual-vibration window starting
  ``residual_delay * t_f`` after the maneuver (:func:`settling_bands`);
* reference shaping (:func:`reference_shaping`): the slew reference's acceleration
  smoothed over ``smoothing`` first-mode periods (a moving average over one period leaves
  no excitation at ``w_1``), as far as ``feedforward_share`` of ``tau_max`` allows;
* the PD bandwidth ``pd_bandwidth / t_f``.

On the paper's default slew (t_f = 10 s) the residual window starts 5 s after the
maneuver and the settling bands are 1 mm and ``1e-3 Theta``, as before. A geometrically
similar beam (lengths times ``k``, masses times ``k^3``, stiffnesses and torques
dimensionally consistent, times times ``k``) gets the same dimensionless settings, so the
same dimensionless closed-loop results.

Examples
--------
>>> from controllers import DesignModel, slew_reference
>>> from hubbeam_ctrl import Params
>>> p = Params(L=1, rho=2700, A=9e-5, E=69e9, I=6.75e-11, J_h=0.02, r=0.05, m_t=0.05, tau_max=1.5)
>>> d = DesignModel.build(p, n_modes=3)
>>> ref = slew_reference(1.5708, 1.2, p.total_inertia, 1.5, 0.01, 3.0)
>>> s = task_scales(d, ref, 1.5708, 1.2, 1.5)
>>> round(s.first_mode / (2 * math.pi), 2)              # first flexible mode [Hz]
4.63
>>> w = bryson_weights(s)
>>> bool(w.torque == 1 / 1.5 ** 2 and w.tip == 1 / (Tolerances().tip_deflection * 1.0) ** 2)
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.settings import Settings, setting
from hubbeam_ctrl.core.validation import check_positive

from .base import DesignModel, Reference, Weights
from .reference import slew_shape_constant

__all__ = ["Tolerances", "HEAVY_HUB", "LIGHT_HUB", "HUB_SHARES", "SPINUP_TOLERANCES", "default_tolerances",
           "TaskScales", "task_scales", "first_mode", "bryson_weights", "sensor_noise", "kalman_noise",
           "settling_bands", "reference_shaping", "scaled_defaults"]


@dataclass(frozen=True)
class Tolerances(Settings):
    """Dimensionless tolerances that make a task's defaults (see :mod:`controllers.scaling`)."""

    angle_error: float = setting(1e-2, lo=0.0, lo_open=True,
                                 doc="Allowed hub-angle error of Bryson's rule, relative to the task's angle.")
    rate_time: float = setting(1.0, lo=0.0, lo_open=True,
                               doc="Allowed hub-rate error = allowed angle error / (rate_time t_f).")
    tip_deflection: float = setting(1e-3, lo=0.0, lo_open=True,
                                    doc="Allowed tip deflection of Bryson's rule, relative to L.")
    modal_deflection: float | None = setting(None, lo=0.0, lo_open=True, kind=float,
                                             doc="Allowed modal coordinate, relative to L; None: half the "
                                                 "allowed tip deflection (a mode's tip deflection is twice "
                                                 "its coordinate).")
    vibration_rate: float = setting(1.0, lo=0.0, lo_open=True,
                                    doc="Allowed tip and modal rates = allowed deflections times "
                                        "vibration_rate w_1 (first flexible mode).")
    settle_angle: float = setting(1e-3, lo=0.0, lo_open=True,
                                  doc="Settling band of the hub-angle error, relative to the task's angle.")
    settle_tip: float = setting(1.25e-4, lo=0.0, lo_open=True,
                                doc="Settling band of the tip deflection, relative to L (1 mm on 8 m).")
    residual_delay: float = setting(0.5, lo=0.0,
                                    doc="Start of the residual-vibration window after t_f, relative to t_f.")
    angle_noise: float = setting(7.8e-6, lo=0.0,
                                 doc="Hub-angle sensor noise relative to the task's angle (1e-4 rad on the "
                                     "paper's slew).")
    rate_noise: float = setting(3.9e-4, lo=0.0,
                                doc="Hub-rate sensor noise relative to the task's peak reference rate.")
    moment_noise: float = setting(7.5e-4, lo=0.0,
                                  doc="Root-moment sensor noise relative to the task's peak quasi-static "
                                      "root moment.")
    torque_noise: float = setting(0.005, lo=0.0, lo_open=True,
                                  doc="Kalman filter's process noise (hub torque per sample), relative "
                                      "to tau_max (the paper's 1 N m of 200; 0.025 on light hubs until the "
                                      "filter's prescribed decay, issue 22).")
    modal_noise: float = setting(1.25e-6, lo=0.0,
                                 doc="Kalman filter's process noise on each modal coordinate, relative to "
                                     "L (on the rates: times vibration_rate w_1; the paper's 1e-5 m of 8 m; "
                                     "1e-4 on light hubs until the filter's prescribed decay).")
    flatness: float = setting(3.0, lo=0.0, doc="Shape of the slew reference (controllers.slew_reference).")
    smoothing: float = setting(0.5, lo=0.0,
                               doc="Smoothing of the slew reference's acceleration, in first-mode periods "
                                   "(capped by feedforward_share and 0.45 t_f).")
    feedforward_share: float = setting(0.75, lo=0.0, hi=1.0, lo_open=True,
                                       doc="Largest share of tau_max the smoothing may give the reference's "
                                           "feedforward (the rest is left to the feedback).")
    pd_bandwidth: float = setting(10.0, lo=0.0, lo_open=True,
                                  doc="PD rigid-body bandwidth times t_f (1 rad/s on the paper's 10 s slew).")


#: Design tolerances of a slew with a heavy hub (``J_h / J_total >= 0.8``): the paper's tuned
#: weights and filter noise (the residual-mode LQG's 1 N m and 1e-5) expressed relative to its
#: slew (Table 1's beam, the Eq. 44 angle in 10 s), to four digits; no reference smoothing.
HEAVY_HUB = {"angle_error": 7.808e-4, "rate_time": 0.3162, "tip_deflection": 2.282e-3,
             "modal_deflection": 1.25e-3, "vibration_rate": 0.3463, "modal_noise": 1.25e-6,
             "torque_noise": 0.005, "smoothing": 0.0}
#: Design tolerances of a slew with a light hub (``J_h / J_total <= 0.1``, e.g. a lab arm): the
#: hub moves with the first mode, so the hub-rate weight damps the beam and the hub angle is
#: held loosely; the reference is smoothed over half a first-mode period (measured on light-hub
#: aluminium and steel links and a long boom, see docs/controllers.md). The filter's process
#: noise is the heavy hub's: with the filter's prescribed decay (``KalmanNoise.error_decay``) the
#: model error no longer needs a large process noise to die out, and the light hubs' former 0.025
#: and 1e-4 passed the rate gyro's noise on to the tip (issue 22, docs/limit.md).
LIGHT_HUB = {"angle_error": 1e-2, "rate_time": 1.0, "tip_deflection": 1e-3, "modal_deflection": 5e-4,
             "vibration_rate": 1.0, "modal_noise": 1.25e-6, "torque_noise": 0.005, "smoothing": 0.5}
#: Hub shares of the two anchors; in between, every design tolerance is interpolated
#: geometrically (the smoothing linearly) in the hub share.
HUB_SHARES = (0.1, 0.8)
#: Tolerances of a spin-up: the paper's tuned spin-up defaults expressed relative to its task
#: (3 rad/s in 10 s on Table 1's beam), to four digits.
SPINUP_TOLERANCES = Tolerances(angle_error=6.667e-4, rate_time=0.3162, tip_deflection=2.282e-3,
                               modal_deflection=1.25e-3, vibration_rate=0.2970, settle_angle=6.667e-5,
                               angle_noise=6.667e-6, rate_noise=3.333e-4, moment_noise=8.284e-4,
                               modal_noise=1.25e-6, torque_noise=0.005, smoothing=0.0)


def default_tolerances(task: str, hub_share: float | None = None) -> Tolerances:
    """The default :class:`Tolerances` of a task on a beam.

    Parameters
    ----------
    task : {"slew", "spinup"}
    hub_share : float, optional
        ``J_h / J_total`` [-] of the beam (slew only; default: a heavy hub).

    Returns
    -------
    Tolerances
        Spin-up: :data:`SPINUP_TOLERANCES`. Slew: the design tolerances interpolated between
        :data:`LIGHT_HUB` and :data:`HEAVY_HUB` at ``hub_share`` (see :data:`HUB_SHARES`),
        the other fields :class:`Tolerances`' defaults.

    Examples
    --------
    >>> default_tolerances("slew", 0.8047).angle_error      # the paper's beam: its tuned weights
    0.0007808
    >>> default_tolerances("slew", 0.05).angle_error        # a light hub
    0.01
    """
    if task == "spinup":
        return SPINUP_TOLERANCES
    share = 1.0 if hub_share is None else float(hub_share)
    g = min(1.0, max(0.0, (share - HUB_SHARES[0]) / (HUB_SHARES[1] - HUB_SHARES[0])))
    values = {k: (LIGHT_HUB[k] + g * (HEAVY_HUB[k] - LIGHT_HUB[k]) if k == "smoothing"
                  else LIGHT_HUB[k] ** (1 - g) * HEAVY_HUB[k] ** g) for k in LIGHT_HUB}
    return Tolerances(**values)


def first_mode(design: DesignModel) -> float:
    """Lowest flexible natural frequency of the design model [rad/s] (free hub, design spin).

    Parameters
    ----------
    design : DesignModel
        Its sampled ``A``: the flexible modes are its oscillatory eigenvalues.

    Returns
    -------
    float
    """
    lam = np.linalg.eigvals(design.A)
    osc = np.abs(lam.imag) > 1e-9 * max(1.0, float(np.max(np.abs(lam))))
    if not np.any(osc):
        raise ParameterError("the design model has no flexible mode")
    return float(np.min(np.abs(lam[osc])))


@dataclass(frozen=True)
class TaskScales:
    """The scales of a task on a beam (see :mod:`controllers.scaling`).

    Attributes
    ----------
    angle : float
        Task angle [rad]: the slew angle, or ``|w_f| t_f / 2`` for a spin-up.
    duration : float
        t_f [s].
    length : float
        Beam length L [m].
    first_mode : float
        First flexible mode of the design model w_1 [rad/s].
    tau_max : float
        Torque budget [N m].
    peak_rate : float
        Peak abs(rate) of the reference [rad/s].
    peak_moment : float
        Peak abs(root moment) of the reference's quasi-static deflection [N m].
    """

    angle: float
    duration: float
    length: float
    first_mode: float
    tau_max: float
    peak_rate: float
    peak_moment: float

    def to_dict(self) -> dict:
        """Plain dictionary with units in the keys."""
        return {"angle_rad": self.angle, "duration_s": self.duration, "length_m": self.length,
                "first_mode_rad_s": self.first_mode, "tau_max_nm": self.tau_max,
                "peak_rate_rad_s": self.peak_rate, "peak_moment_nm": self.peak_moment}


def task_scales(design: DesignModel, reference: Reference, angle: float, duration: float,
                tau_max: float) -> TaskScales:
    """The scales of a task: its reference on the design model.

    Parameters
    ----------
    design : DesignModel
        The design model (gives L, w_1 and the quasi-static root moment).
    reference : Reference
        The task's hub reference.
    angle : float
        Task angle [rad], not 0 (see :class:`TaskScales`).
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


def bryson_weights(scales: TaskScales, tol: Tolerances | None = None) -> Weights:
    """LQR/LQG/MPC weights by Bryson's rule from the task (``w = 1 / allowed^2``).

    Parameters
    ----------
    scales : TaskScales
        The task's angle, duration, length, first mode and torque budget.
    tol : Tolerances, optional
        The allowed errors relative to them (default :class:`Tolerances`).

    Returns
    -------
    Weights
    """
    tol = tol or Tolerances()
    angle = tol.angle_error * scales.angle
    rate = angle / (tol.rate_time * scales.duration)
    tip = tol.tip_deflection * scales.length
    modal = tip / 2.0 if tol.modal_deflection is None else tol.modal_deflection * scales.length
    w1 = tol.vibration_rate * scales.first_mode
    return Weights(angle=angle ** -2, rate=rate ** -2, tip=tip ** -2, tip_rate=(tip * w1) ** -2,
                   modal=modal ** -2, modal_rate=(modal * w1) ** -2, torque=scales.tau_max ** -2)


def sensor_noise(scales: TaskScales, tol: Tolerances | None = None) -> dict:
    """Sensor noise standard deviations of the task (see :class:`Tolerances`).

    Parameters
    ----------
    scales, tol
        As :func:`bryson_weights` (the angle, the peak rate and moment; the noise ratios).

    Returns
    -------
    dict
        ``angle_noise_rad`` [rad], ``rate_noise_rad_s`` [rad/s], ``moment_noise_nm`` [N m]
        (the fields of :class:`hubbeam_ctrl.plant.sensors.SensorSettings`).
    """
    tol = tol or Tolerances()
    return {"angle_noise_rad": tol.angle_noise * scales.angle,
            "rate_noise_rad_s": tol.rate_noise * scales.peak_rate,
            "moment_noise_nm": tol.moment_noise * scales.peak_moment}


def kalman_noise(scales: TaskScales, tol: Tolerances | None = None) -> dict:
    """The Kalman filter's noise model: the sensors' noise and a torque process noise.

    Parameters
    ----------
    scales, tol
        As :func:`sensor_noise`, plus the torque budget, the length and the first mode.

    Returns
    -------
    dict
        :func:`sensor_noise` (zero levels raised to a millionth of the range, since the
        filter needs noise on every sensor) plus ``torque_noise_nm`` [N m], ``modal_noise``
        [m] and ``modal_rate_noise`` [m/s] (the modal noise times ``vibration_rate w_1``).
    """
    tol = tol or Tolerances()
    floor = {"angle_noise_rad": 1e-6 * scales.angle, "rate_noise_rad_s": 1e-6 * scales.peak_rate,
             "moment_noise_nm": 1e-6 * max(scales.peak_moment, 1e-300)}
    noise = {k: max(v, floor[k]) for k, v in sensor_noise(scales, tol).items()}
    modal = tol.modal_noise * scales.length
    return {**noise, "torque_noise_nm": tol.torque_noise * scales.tau_max, "modal_noise": modal,
            "modal_rate_noise": modal * tol.vibration_rate * scales.first_mode}


def settling_bands(scales: TaskScales, tol: Tolerances | None = None) -> dict:
    """Settling bands and the residual window's delay of the task.

    Parameters
    ----------
    scales : TaskScales
        Its angle, length and duration.
    tol : Tolerances, optional
        Its settling bands and residual delay (default :class:`Tolerances`).

    Returns
    -------
    dict
        ``settle_angle`` [rad], ``settle_tip`` [m], ``residual_delay`` [s] (keywords of
        :func:`hubbeam_ctrl.study.metrics.closed_loop_metrics`).
    """
    tol = tol or Tolerances()
    return {"settle_angle": tol.settle_angle * scales.angle, "settle_tip": tol.settle_tip * scales.length,
            "residual_delay": tol.residual_delay * scales.duration}


def reference_shaping(angle: float, duration: float, inertia: float, tau_max: float, first_mode_rad_s: float,
                      tol: Tolerances | None = None) -> dict:
    """Flatness and smoothing of the slew reference for the beam and the task.

    The smoothing is ``tol.smoothing`` first-mode periods, at most ``0.45 t_f`` and at most
    what keeps the reference's peak feedforward ``J a_max`` within ``feedforward_share``
    of ``tau_max`` (0 if even the unsmoothed reference needs more).

    Parameters
    ----------
    angle : float
        Slew angle [rad].
    duration : float
        t_f [s].
    inertia : float
        Rigid-body inertia J_total [kg m^2].
    tau_max : float
        Torque budget [N m].
    first_mode_rad_s : float
        w_1 [rad/s].
    tol : Tolerances, optional

    Returns
    -------
    dict
        ``flatness`` [-] and ``smoothing`` [s] (keywords of :func:`controllers.slew_reference`).
    """
    tol = tol or Tolerances()
    c = slew_shape_constant(tol.flatness)
    # peak feedforward J |angle| / (c (T - s)^2) <= share tau_max
    longest = duration - math.sqrt(inertia * abs(angle) / (c * tol.feedforward_share * tau_max))
    period = 2 * math.pi / first_mode_rad_s
    smoothing = max(0.0, min(tol.smoothing * period, 0.45 * duration, longest))
    return {"flatness": tol.flatness, "smoothing": smoothing}


def scaled_defaults(scales: TaskScales, tol: Tolerances | None = None) -> dict:
    """Controller settings of the task, by field name (for ``ControllerSettings.for_scenario``).

    Parameters
    ----------
    scales, tol
        Passed to :func:`bryson_weights` and :func:`kalman_noise`.

    Returns
    -------
    dict
        ``weights`` (:func:`bryson_weights`), the :class:`~controllers.filter_model.KalmanNoise`
        fields (:func:`kalman_noise`) and the PD ``bandwidth`` [rad/s].
    """
    tol = tol or Tolerances()
    return {"weights": bryson_weights(scales, tol), **kalman_noise(scales, tol),
            "bandwidth": tol.pd_bandwidth / scales.duration}
