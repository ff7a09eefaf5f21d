"""Designs for a payload range: the nominal design verified over the range and retuned by measurement.

A tip payload between ``m_min`` and ``m_max`` changes the beam's frequencies and the rigid
inertia; a controller designed at one mass can lose its damping, or (LQG, whose filter
predicts the root moment from the model) its stability, at another. :func:`design_for_range`
builds candidate designs and keeps the one whose worst case over the range is best, measured
on the sampled linear SFOAM models at a grid of payloads (:func:`payload_grid`) running the
task's reference through the controller itself (:func:`linear_task_residual`):

* the design payload: the nominal one, the middle of the range and its ends;
* the allowed tip and modal deflections of the weights times :data:`DEFLECTION_FACTORS`
  (1 only: tighter ones measured worse on the paper's beam, whose torque the slew uses up);
* for LQG also the filter's process noise, times 1 and 10 (:data:`NOISE_FACTORS`: a filter
  that trusts the sensors more than the model follows a plant that differs from it);
* MPC takes the design chosen for LQR (the same weights and model; its constraints do not
  change the linear behaviour inside the torque limit).

The score of a candidate is its worst residual over the grid relative to the open-loop
Eq. 44 residual of the same linear model (:func:`linear_openloop_residual`), and infinite if
a closed loop is unstable (spectral radius >= 1); for a spin-up (a design spin other than
0) it is the worst spectral radius. The choice is made on linear models only;
the study layer then judges it on the nonlinear plant at ``m_min``, nominal and ``m_max``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.validation import check_nonnegative

from .analysis import closed_loop_poles
from .base import DesignModel, Reference
from .lqr import LQRSettings

__all__ = ["check_payload_range", "payload_grid", "linear_task_residual", "linear_openloop_residual",
           "RangeDesign", "design_for_range", "NOISE_FACTORS", "DEFLECTION_FACTORS"]

#: Multipliers of the LQG filter's process noise (torque and modal) tried over a payload range.
NOISE_FACTORS = (1.0, 10.0)
#: Factors on the allowed tip and modal deflections (and rates) of the weights tried over a
#: payload range (smaller: more damping of the vibration).
DEFLECTION_FACTORS = (1.0,)


def check_payload_range(payload_range, nominal: float | None = None, name: str = "payload_range") -> tuple:
    """Validate ``(m_min, m_max)`` [kg]: finite, ``0 <= m_min <= m_max``, holding ``nominal``.

    Parameters
    ----------
    payload_range : sequence of two floats
    nominal : float, optional
        The nominal tip mass [kg] that must lie in the range.
    name : str
        The argument's name for the error message.

    Returns
    -------
    tuple of float

    Raises
    ------
    ParameterError
        One line naming ``name`` and the allowed range.
    """
    try:
        lo, hi = payload_range
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be two numbers (m_min, m_max) [kg], got {payload_range!r}") from None
    lo = check_nonnegative(f"{name} m_min", lo, "kg")
    hi = check_nonnegative(f"{name} m_max", hi, "kg")
    if lo > hi:
        raise ParameterError(f"{name} must have 0 <= m_min <= m_max [kg], got ({lo:g}, {hi:g})")
    if nominal is not None and not lo <= nominal <= hi:
        raise ParameterError(f"{name} ({lo:g}, {hi:g}) kg must hold the nominal tip mass m_t = {nominal:g} kg")
    return lo, hi


def payload_grid(payload_range, nominal: float) -> tuple:
    """Payloads [kg] a design is verified at: the ends of the range and the nominal payload.

    Parameters
    ----------
    payload_range : tuple of float
        ``(m_min, m_max)`` [kg].
    nominal : float
        Nominal tip mass [kg].
    """
    lo, hi = payload_range
    return tuple(sorted({lo, nominal, hi}))


def _linear_run(design: DesignModel, plant: DesignModel, ctrl, n_steps: int) -> np.ndarray:
    """Tip deflection of the linear ``plant`` under ``ctrl`` over ``n_steps`` samples [m]."""
    x = np.zeros(plant.n_x)
    A, b = plant.Ad, plant.Bd[:, 0]
    c_tip = plant.C_tip[0]
    C = plant.C_sensors if ctrl.measurement == "sensors" else None
    ctrl.reset()
    v = np.empty(n_steps)
    for k in range(n_steps):
        v[k] = c_tip @ x
        y = x if C is None else C @ x
        x = A @ x + b * ctrl(k * design.dt, y)
        if not np.all(np.isfinite(x)) or abs(v[k]) > 10 * plant.params.L:
            v[k:] = np.inf
            break
    return v


def linear_task_residual(design: DesignModel, plant: DesignModel, ctrl, t_f: float, t_end: float,
                         delay: float) -> float:
    """Residual vibration of the task on a linear plant: max abs(v_tip) after ``t_f + delay`` [m].

    Parameters
    ----------
    design : DesignModel
        The controller's design model (gives ``dt``).
    plant : DesignModel
        The linear plant (same modes as the design, another payload).
    ctrl : Controller
        Built on ``design`` with the task's reference.
    t_f, t_end, delay : float
        Maneuver time, run length and residual-window delay [s].

    Returns
    -------
    float
        ``inf`` if the run blows up.
    """
    n = int(round(t_end / design.dt)) + 1
    v = _linear_run(design, plant, ctrl, n)
    return float(np.max(np.abs(v[int(round((t_f + delay) / design.dt)):])))


def linear_openloop_residual(plant: DesignModel, torque, t_f: float, t_end: float, delay: float) -> float:
    """Residual vibration of an open-loop torque on a linear plant [m] (the baseline of the scores).

    Parameters
    ----------
    plant : DesignModel
        Sampled linear plant.
    torque : callable
        ``torque(t) -> tau`` [N m] on an array of sample times [s] (e.g. the Eq. 44 pulse).
    t_f, t_end, delay : float
        Maneuver time, run length and residual-window delay [s].

    Returns
    -------
    float
    """
    n = int(round(t_end / plant.dt)) + 1
    tau = np.asarray(torque(plant.dt * np.arange(n)), dtype=float) * np.ones(n)
    x = np.zeros(plant.n_x)
    v = np.empty(n)
    for k in range(n):
        v[k] = plant.C_tip[0] @ x
        x = plant.Ad @ x + plant.Bd[:, 0] * tau[k]
    return float(np.max(np.abs(v[int(round((t_f + delay) / plant.dt)):])))


@dataclass(frozen=True)
class RangeDesign:
    """The design chosen for a payload range.

    Attributes
    ----------
    design : DesignModel
        The design model (at ``design_mass``).
    settings : ControllerSettings
        The controller's settings (LQG: with the chosen process noise).
    design_mass : float
        Payload the model was built with [kg].
    choice : str
        The chosen candidate (payload, deflection and noise factors).
    score : float
        Worst linear residual over the grid relative to the open loop's [-].
    scores : dict
        Candidate label -> score, every candidate tried.
    grid : tuple
        Payloads verified [kg].
    """

    design: DesignModel
    settings: object
    design_mass: float
    choice: str
    score: float
    scores: dict
    grid: tuple


def _stiffer(weights, factor: float):
    """``weights`` with the allowed tip and modal deflections and rates times ``factor``."""
    if factor == 1.0:
        return weights
    rate = weights.modal if weights.modal_rate is None else weights.modal_rate
    return dataclasses.replace(weights, tip=weights.tip / factor ** 2, tip_rate=weights.tip_rate / factor ** 2,
                               modal=weights.modal / factor ** 2, modal_rate=rate / factor ** 2)


def _candidates(name: str, settings, payload_range, nominal: float):
    """``(label, payload, settings)`` of every candidate design."""
    lo, hi = payload_range
    masses = sorted({nominal, 0.5 * (lo + hi), hi, lo})
    noises = NOISE_FACTORS if name == "lqg" else (1.0,)
    for m in masses:
        for g in DEFLECTION_FACTORS:
            for f in noises:
                changes = {"weights": _stiffer(settings.weights, g)}
                if f != 1.0:
                    changes.update(torque_noise_nm=settings.torque_noise_nm * f,
                                   modal_noise=settings.modal_noise * f)
                    if settings.modal_rate_noise is not None:
                        changes["modal_rate_noise"] = settings.modal_rate_noise * f
                label = f"m={m:g} kg" + (f", deflections x{g:g}" if g != 1.0 else "") + \
                    (f", noise x{f:g}" if f != 1.0 else "")
                yield label, m, dataclasses.replace(settings, **changes)


def design_for_range(name: str, make, base: DesignModel, settings, reference: Reference, payload_range, *,
                     t_f: float, t_end: float, delay: float, baseline, score=None) -> RangeDesign:
    """Choose the design of a controller for a payload range by measurement (see the module docstring).

    Parameters
    ----------
    name : {"lqr", "lqg", "mpc"}
        Controller (MPC is measured through the LQR of its weights).
    make : callable
        ``make(name, design, settings, reference) -> Controller`` (e.g. :func:`controllers.make_controller`).
    base : DesignModel
        The nominal design model (its ``params.m_t`` is the nominal payload).
    settings : ControllerSettings
        The controller's settings at the nominal design.
    reference : Reference
        The task's reference.
    payload_range : tuple of float
        ``(m_min, m_max)`` [kg], holding the nominal payload.
    t_f, t_end, delay : float
        Maneuver time, run length and residual-window delay of the task [s].
    baseline : callable
        Open-loop torque ``baseline(t)`` [N m] whose residual the scores are relative to
        (e.g. the Eq. 44 pulse); for a spin-up (design spin not 0) the scores are the
        closed-loop spectral radii instead (the linear model holds deviations from the
        design spin, not the spin-up itself).
    score : callable, optional
        ``score(ctrl, payload) -> float`` measuring a candidate controller on the plant with
        that payload (e.g. a nonlinear run, relative to the open loop's residual on the same
        plant); default: the linear measure above. Candidates whose linear loop is unstable
        at a payload of the grid are dropped before it is called.

    Returns
    -------
    RangeDesign
    """
    nominal = base.params.m_t
    payload_range = check_payload_range(payload_range, nominal)
    grid = payload_grid(payload_range, nominal)
    models = {m: base if m == nominal else DesignModel.build(base.params.replace(m_t=m), base.spin, base.dt,
                                                              base.n_modes) for m in grid}
    spinup = base.spin != 0.0
    if not spinup and score is None:
        open_loop = {m: linear_openloop_residual(models[m], baseline, t_f, t_end, delay) for m in grid}
    probe = "lqr" if name == "mpc" else name
    if name == "mpc":     # the LQR of the MPC's weights and limits
        settings_probe = LQRSettings(weights=settings.weights, tau_max=settings.tau_max,
                                     feedforward=settings.feedforward,
                                     elastic_reference=settings.elastic_reference)
    else:
        settings_probe = settings
    best, scores = None, {}
    for label, m, st in _candidates(probe, settings_probe, payload_range, nominal):
        design = models.get(m) or DesignModel.build(base.params.replace(m_t=m), base.spin, base.dt, base.n_modes)
        ctrl = make(probe, design, st, reference)
        worst = 0.0
        for mp in grid:
            radius = _spectral_radius(ctrl, models[mp])
            if radius >= 1.0:
                worst = math.inf
                break
            if score is not None:
                worst = max(worst, float(score(ctrl, mp)))
            elif spinup:
                worst = max(worst, radius)
            else:
                r = linear_task_residual(design, models[mp], ctrl, t_f, t_end, delay)
                worst = max(worst, r / open_loop[mp] if open_loop[mp] > 0 else r)
        scores[label] = worst
        if best is None or worst < best[0]:
            best = (worst, label, m, design, st)
    worst, label, m, design, st = best
    chosen = settings.replace(weights=st.weights) if name == "mpc" else st
    return RangeDesign(design=design, settings=chosen, design_mass=m, choice=label, score=worst,
                       scores=scores, grid=grid)


def _spectral_radius(ctrl, plant: DesignModel) -> float:
    """Largest closed-loop pole magnitude of ``ctrl`` on the linear ``plant`` [-]."""
    return float(np.max(np.abs(closed_loop_poles(ctrl, plant))))
