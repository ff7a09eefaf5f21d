"""Designs for a payload range: multi-model choices measured over the range.

A tip payload between ``m_min`` and ``m_max`` changes the beam's frequencies, the rigid
inertia and the quasi-static deflection a hub acceleration causes; a controller designed at
one mass can lose its damping, or (LQG, whose filter predicts the root moment from the model)
its stability, at another. :func:`design_for_range` builds candidate designs and keeps the one
whose worst case over the range is best, measured at a grid of payloads
(:func:`payload_grid`: the ends and the nominal payload) either on the sampled linear SFOAM
models (:func:`linear_task_residual`) or by a caller's measure (the study layer runs the
nonlinear evaluation plant). The candidates:

* the design payload: the nominal one, the middle of the range and its ends; the best
  candidate's payload is then refined by bisection (:data:`REFINE_STEPS`) towards the payload
  at which the two ends of the range do equally well;
* the deflection weighting (:data:`WEIGHTINGS`): ``"full"``, the weights as given, or
  ``"rates"``, the tip and modal deflections unweighted and their rates kept. The deflection
  a reference acceleration causes depends on the payload, so a design at one mass tracks the
  wrong deflection at another and trades hub-angle error for it during the maneuver; weighting
  only the rates damps the vibration without fighting a quasi-static deflection (measured on
  Table 1's beam, 0-0.5 kg: worst case 3.7 % -> 1.9 % of the open loop for LQR);
* LQG's Kalman filter is a multi-model filter: its process noise carries the spread of the
  models over the range along the task (:func:`model_error_covariance`), so it trusts its
  model only as far as the payload range allows (without it the filter designed at one end
  of Table 1's range is unstable at the other);
* MPC's candidates are LQR's (the same weights and model): their linear loops are checked
  through the LQR of the weights, and a caller's measure runs the MPC itself.

The score of a candidate is its worst residual over the grid relative to the open-loop
Eq. 44 residual of the same plant, and infinite if a linear closed loop at a grid payload is
unstable (spectral radius >= 1); for a spin-up (a design spin other than 0) the linear
measure is the worst spectral radius.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.progress import progress_bar
from hubbeam_ctrl.core.validation import check_in_range, check_nonnegative

from .analysis import closed_loop_poles
from .base import DesignModel, Reference
from .lqr import LQRSettings

__all__ = ["check_payload_range", "payload_grid", "linear_task_residual", "linear_openloop_residual",
           "RangeDesign", "design_for_range", "model_error_covariance", "multi_model_filter", "estimator_like",
           "rates_only",
           "WEIGHTINGS"]

#: Deflection weightings tried over a payload range: the weights as given, or their rates only
#: (:func:`rates_only`).
WEIGHTINGS = ("full", "rates")
#: Shares of the model-error covariance (:func:`model_error_covariance`) tried for LQG's
#: multi-model filter. The full covariance (share 1) treats a systematic model error as white
#: noise and raises the filter's bandwidth until aliased higher modes destabilise the loop on
#: Table 1's beam; shares of 1-10 % keep the low-frequency robustness (measured, see
#: docs/controllers.md).
FILTER_SHARES = (0.003, 0.01, 0.03)
#: Modes whose model error the multi-model filter carries (besides the rigid body): the payload
#: moves the first mode most; the others keep the filter's own noise level.
FILTER_MODES = 1
#: Bisection steps that refine the best candidate's design payload (each one more candidate).
REFINE_STEPS = 4


#: Largest tip mass of :class:`~hubbeam_ctrl.plant.params.Params` (its ``m_t`` range) [kg].
_M_T_MAX = 1e6


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
    for label, value in (("m_min", lo), ("m_max", hi)):
        check_in_range(f"{name} {label}", value, "kg", 0.0, _M_T_MAX, "the range of Params.m_t")
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
    """Tip deflection of the linear ``plant`` under ``ctrl`` over ``n_steps`` samples [m].

    A state-reading controller whose gain acts on more modes than ``plant`` has (residual
    control) runs on the same plant with those modes, and reads the coordinates of its modes."""
    m = int(getattr(ctrl, "state_modes", plant.n_modes))
    if ctrl.measurement != "sensors" and plant.n_modes < m:
        plant = DesignModel.build(plant.params, plant.spin, plant.dt, m)
    n = plant.n_x // 2
    read = np.r_[0:1 + m, n:n + 1 + m] if ctrl.measurement != "sensors" else None
    x = np.zeros(plant.n_x)
    A, b = plant.Ad, plant.Bd[:, 0]
    c_tip = plant.C_tip[0]
    C = plant.C_sensors if ctrl.measurement == "sensors" else None
    ctrl.reset()
    v = np.empty(n_steps)
    for k in range(n_steps):
        v[k] = c_tip @ x
        y = x[read] if C is None else C @ x
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


def rates_only(weights):
    """``weights`` without the tip and modal deflection terms; their rates keep their weights.

    Parameters
    ----------
    weights : Weights
        The weights of a design (scalar form; a full ``state_matrix`` is returned unchanged).

    Returns
    -------
    Weights
    """
    if weights.state_matrix is not None:
        return weights
    rate = weights.modal if weights.modal_rate is None else weights.modal_rate
    return dataclasses.replace(weights, tip=0.0, modal=0.0, modal_rate=rate)


def model_error_covariance(model: DesignModel, models, reference: Reference, n_modes: int | None = None) -> np.ndarray:
    """Process-noise covariance of the model error over a set of plants along a task [state units^2].

    ``mean_i (A_i - A) S_x (A_i - A)' + s_u (B_i - B)(B_i - B)'``, with ``S_x`` the second
    moment of the task's reference states on ``model`` (:meth:`DesignModel.reference_states`)
    and ``s_u`` the mean square of its feedforward torque: the one-step prediction error the
    filter's model makes, on average, when the plant is one of ``models``.

    Parameters
    ----------
    model : DesignModel
        The filter's model.
    models : sequence of DesignModel
        The plants of the range, each with ``model``'s states and sample time.
    reference : Reference
        The task.
    n_modes : int, optional
        Keep the error of the rigid body and the first ``n_modes`` modes only (the filter's
        residual modes keep their own noise level); default: every mode.

    Returns
    -------
    ndarray (n_x, n_x)
        Symmetric positive semidefinite.
    """
    X = model.reference_states(reference, True)
    tau = np.asarray(reference.window(0, len(reference.theta))[2], dtype=float)
    S_x, s_u = X.T @ X / len(X), float(np.mean(tau ** 2))
    Q = np.zeros((model.n_x, model.n_x))
    for m in models:
        if m.n_x != model.n_x or m.dt != model.dt:
            raise ParameterError(f"models must have the filter model's {model.n_x} states and dt = {model.dt:g} s")
        dA, dB = m.Ad - model.Ad, m.Bd[:, 0] - model.Bd[:, 0]
        Q += dA @ S_x @ dA.T + s_u * np.outer(dB, dB)
    Q /= max(1, len(models))
    if n_modes is not None:           # only the rigid body and the first n_modes modes
        n = model.n_x // 2
        keep = np.zeros(model.n_x, dtype=bool)
        keep[:1 + n_modes] = keep[n:n + 1 + n_modes] = True
        Q[~keep, :] = 0.0
        Q[:, ~keep] = 0.0
    return 0.5 * (Q + Q.T)


def multi_model_filter(design: DesignModel, settings, payloads, reference: Reference, share: float = 0.01,
                       n_modes: int = FILTER_MODES):
    """LQG settings whose Kalman filter carries the model error over ``payloads``.

    Parameters
    ----------
    design : DesignModel
        The LQG's design model.
    settings : LQGSettings
        Its settings (``model_error`` is replaced).
    payloads : sequence of float
        Tip masses of the range [kg] (the design's own adds nothing).
    reference : Reference
        The task.
    share : float
        Multiplier of the model-error covariance [-] (see :data:`FILTER_SHARES`).
    n_modes : int
        Modes besides the rigid body whose model error is carried.

    Returns
    -------
    LQGSettings
    """
    from .lqg import filter_model
    fm = filter_model(design, settings)
    plants = [estimator_like(fm, m) for m in payloads if m != design.params.m_t]
    error = share * model_error_covariance(fm, plants, reference, n_modes) if plants else None
    return settings.replace(model_error=error)


def estimator_like(model: DesignModel, payload: float) -> DesignModel:
    """``model`` (same spin, sample time and modes) with another tip payload [kg].

    Parameters
    ----------
    model : DesignModel
    payload : float
        Tip mass [kg].
    """
    return DesignModel.build(model.params.replace(m_t=payload), model.spin, model.dt, model.n_modes)


def _candidates(settings, payload_range, nominal: float, shares=(None,)):
    """``(label, payload, settings, filter share)`` of every candidate design."""
    lo, hi = payload_range
    masses = sorted({nominal, 0.5 * (lo + hi), hi, lo})
    for m in masses:
        for weighting in WEIGHTINGS:
            st = settings
            if weighting == "rates":
                st = st.replace(weights=rates_only(st.weights))
            for share in shares:
                label = f"m={m:g} kg" + (", rates" if weighting == "rates" else "") + \
                    (f", filter share {share:g}" if share is not None else "")
                yield label, m, st, share


def design_for_range(name: str, make, base: DesignModel, settings, reference: Reference, payload_range, *,
                     t_f: float, t_end: float, delay: float, baseline, score=None,
                     progress: bool = False) -> RangeDesign:
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
    progress : bool
        A progress bar over the candidates on stderr (only on a terminal,
        :func:`hubbeam_ctrl.core.progress.progress_bar`).

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
    lo, hi = payload_range

    def evaluate(m, st, share):
        """Worst score over the grid and the score per payload of one candidate."""
        design = models.get(m) or DesignModel.build(base.params.replace(m_t=m), base.spin, base.dt, base.n_modes)
        if share is not None:
            st = multi_model_filter(design, st, grid, reference, share)
        ctrl = make(probe, design, st, reference)
        # the nonlinear measure runs the controller itself (MPC with the candidate's weights)
        measured = make(name, design, settings.replace(weights=st.weights), reference) \
            if name == "mpc" and score is not None else ctrl
        per = {}
        for mp in grid:
            radius = _spectral_radius(ctrl, models[mp])
            if radius >= 1.0:
                per[mp] = math.inf
                break
            if score is not None:
                per[mp] = float(score(measured, mp))
            elif spinup:
                per[mp] = radius
            else:
                r = linear_task_residual(design, models[mp], ctrl, t_f, t_end, delay)
                per[mp] = r / open_loop[mp] if open_loop[mp] > 0 else r
        return max(per.values()), per, design, st

    best, scores = None, {}
    shares = FILTER_SHARES if probe == "lqg" else (None,)
    masses = sorted({m for _, m, _, _ in _candidates(settings_probe, payload_range, nominal)})
    candidates = list(_candidates(settings_probe, payload_range, nominal, shares))
    bar = progress_bar(len(candidates) + (REFINE_STEPS if hi > lo else 0), f"{name} payload range", enabled=progress)
    with bar:
        best, scores = _search(evaluate, candidates, masses, lo, hi, bar)
    worst, label, m, design, st_used = best[:5]
    chosen = settings.replace(weights=st_used.weights) if name == "mpc" else st_used
    return RangeDesign(design=design, settings=chosen, design_mass=m, choice=label, score=worst,
                       scores=scores, grid=grid)


def _search(evaluate, candidates, masses, lo, hi, bar) -> tuple:
    """The best candidate, refined by bisection (see :func:`design_for_range`), and every score."""
    best, scores = None, {}
    for label, m, st, share in candidates:
        worst, per, design, st_used = evaluate(m, st, share)
        bar.update(1)
        scores[label] = worst
        if best is None or worst < best[0]:
            best = (worst, label, m, design, st_used, per, st, share)
    # refine the design payload of the best candidate: bisection towards the payload at which
    # the two ends of the range do equally well (the worst case is the larger of the two)
    worst, label, m, design, st_used, per, st, share = best
    if math.isfinite(worst) and hi > lo:
        suffix = label[label.index(" kg") + 3:]
        i = masses.index(m)
        heavier_hurts = per.get(hi, math.inf) >= per.get(lo, math.inf)
        a, b = (m, masses[min(i + 1, len(masses) - 1)]) if heavier_hurts else (masses[max(i - 1, 0)], m)
        for _ in range(REFINE_STEPS):
            mid = 0.5 * (a + b)
            w, p, d, su = evaluate(mid, st, share)
            bar.update(1)
            scores[f"m={mid:.4g} kg{suffix}"] = w
            if w < best[0]:
                best = (w, f"m={mid:.4g} kg{suffix}", mid, d, su, p, st, share)
            if p.get(hi, math.inf) >= p.get(lo, math.inf):
                a = mid
            else:
                b = mid
    bar.update(max(0, bar.total - bar.n))       # no refinement (an infeasible range): the bar ends full
    return best, scores


def _spectral_radius(ctrl, plant: DesignModel) -> float:
    """Largest closed-loop pole magnitude of ``ctrl`` on the linear ``plant`` [-]."""
    return float(np.max(np.abs(closed_loop_poles(ctrl, plant))))
