"""Figures of merit of a closed-loop run (one flat dictionary per run).

Names are snake case with their unit as suffix (``_m``, ``_rad``, ``_s``, ``_nm``,
``_ms``...), the same in ``metrics.csv``, ``metrics.json`` and the printed tables. The one
nested entry is ``plant_params`` (the evaluation plant's :class:`Params` as a dictionary,
in ``metrics.json`` only).
"""

from __future__ import annotations

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.validation import check_positive

__all__ = ["closed_loop_metrics", "METRIC_UNITS", "settling_time", "VERDICTS", "verdict",
           "residual_growth", "saturated_fraction", "GROWTH_LIMIT", "SATURATION_LIMIT"]

#: The verdicts of a closed-loop run, in the order they are tested (see :func:`verdict`).
VERDICTS = ("diverged", "unstable", "settled", "not settled")
#: A run whose residual-window envelope grows by more than this factor is unstable [-].
GROWTH_LIMIT = 2.0
#: A run whose torque sits at its limit for more than this fraction of the residual window
#: is in a saturation limit cycle, i.e. unstable [-].
SATURATION_LIMIT = 0.25

#: Metric name -> (unit, description), in table order.
METRIC_UNITS = {
    "peak_tip_m": ("m", "peak |v_tip| over the whole run"),
    "residual_tip_rms_m": ("m", "RMS of v_tip from t_f + delay to the end"),
    "residual_tip_max_m": ("m", "max |v_tip| from t_f + delay to the end"),
    "angle_error_tf_rad": ("rad", "hub angle minus reference at t_f"),
    "final_angle_error_rad": ("rad", "hub angle minus reference at the end"),
    "settling_time_s": ("s", "time after which |angle error| and |v_tip| stay inside their bands "
                             "(None: not within the run)"),
    "peak_torque_nm": ("N m", "peak |tau|"),
    "torque_squared_integral_n2m2s": ("N^2 m^2 s", "integral of tau^2 (held torque)"),
    "torque_saturated_fraction": ("-", "fraction of the residual window with |tau| at tau_max"),
    "residual_growth": ("-", "max |v_tip| in the last quarter of the residual window over the first quarter"),
    "step_time_median_ms": ("ms", "median wall time of one controller call"),
    "step_time_p99_ms": ("ms", "99th percentile of the controller call time"),
}


#: Entries of the result's settings that describe the plant and its integration step.
_PLANT_KEYS = ("plant_model", "plant_modes", "plant_axial_modes", "design_modes", "plant_modes_reason",
               "substeps", "step_s", "step_mode", "step_mode_hz", "step_mode_frequency_error", "step_reason")


def settling_time(t, angle_error, v_tip, angle_band: float, tip_band: float):
    """First time after which both ``|angle_error| <= angle_band`` and ``|v_tip| <= tip_band``.

    Parameters
    ----------
    t : ndarray
        Times [s].
    angle_error : ndarray
        Hub-angle error [rad].
    v_tip : ndarray
        Tip deflection [m].
    angle_band : float
        [rad], > 0.
    tip_band : float
        [m], > 0.

    Returns
    -------
    float or None
        [s]; None if the response is outside the bands at the last sample.
    """
    inside = (np.abs(angle_error) <= angle_band) & (np.abs(v_tip) <= tip_band)
    if not inside.size or not inside[-1]:
        return None
    outside = np.nonzero(~inside)[0]
    return float(t[0]) if not outside.size else float(t[outside[-1] + 1])


def residual_growth(v_tip) -> float:
    """Envelope growth of a vibration: ``max |v|`` of its last quarter over its first quarter.

    Parameters
    ----------
    v_tip : ndarray
        Tip deflection over the residual window [m].

    Returns
    -------
    float
        [-]; about 1 for a steady oscillation, < 1 for a decaying one, NaN for fewer than
        eight samples.

    Examples
    --------
    >>> t = np.linspace(0, 10, 1001)
    >>> round(residual_growth(np.exp(0.1 * t) * np.sin(20 * t)), 1)     # about e^(0.1 * 7.5 s)
    2.1
    """
    v = np.abs(np.asarray(v_tip, dtype=float))
    if v.size < 8:
        return float("nan")
    q = v.size // 4
    first = np.max(v[:q])
    return float(np.max(v[-q:]) / first) if first > 0 else float("inf") if np.max(v[-q:]) > 0 else 1.0


def saturated_fraction(tau, tau_max: float) -> float:
    """Fraction of torque samples at the limit, ``|tau| >= (1 - 1e-6) tau_max`` [-] (NaN if empty).

    Parameters
    ----------
    tau : array_like
        Torque samples [N m].
    tau_max : float
        Limit [N m].
    """
    tau = np.asarray(tau, dtype=float)
    if not tau.size:
        return float("nan")
    return float(np.mean(np.abs(tau) >= (1 - 1e-6) * tau_max))


def verdict(stopped: bool, growth: float, residual_end_m: float, saturated: float,
            settled: bool, tip_band: float) -> str:
    """The verdict of a closed-loop run (:data:`VERDICTS`), tested in this order.

    * ``"diverged"``: the run stopped early (it passed the divergence limit, by default L,
      or the integrator or the controller failed);
    * ``"unstable"``: in the residual window the vibration grows (its last quarter's peak
      exceeds :data:`GROWTH_LIMIT` times its first quarter's and the tip band), or the torque
      sits at its limit for more than :data:`SATURATION_LIMIT` of the window (a saturation
      limit cycle);
    * ``"settled"``: hub-angle error and tip deflection are inside their settling bands at
      the end;
    * ``"not settled"``: anything else (e.g. the undamped open loop, which rings on).

    Parameters
    ----------
    stopped : bool
    growth : float
        :func:`residual_growth` of the residual window [-].
    residual_end_m : float
        Peak ``|v_tip|`` in the last quarter of the residual window [m].
    saturated : float
        :func:`saturated_fraction` of the residual window [-] (NaN: no torque limit).
    settled : bool
        Inside the settling bands at the end.
    tip_band : float
        Settling band of the tip deflection [m].

    Returns
    -------
    str
    """
    if stopped:
        return "diverged"
    if (growth > GROWTH_LIMIT and residual_end_m > tip_band) or saturated > SATURATION_LIMIT:
        return "unstable"
    return "settled" if settled else "not settled"


def closed_loop_metrics(result, t_f: float, *, residual_delay: float = 5.0,
                        settle_angle: float = 1e-3, settle_tip: float = 1e-3,
                        tau_max: float | None = None) -> dict:
    """Metrics of one closed-loop run.

    Parameters
    ----------
    result : Result
        Of kind ``"closed_loop"`` (see :func:`hubbeam_ctrl.sim.closedloop.simulate_closed_loop`),
        with the task's hub reference (``theta_ref``).
    t_f : float
        Maneuver time [s]: the angle error is taken there, and the residual vibration
        window starts at ``t_f + residual_delay``.
    residual_delay : float
        [s], >= 0 (default 5).
    settle_angle : float
        Settling band of the hub-angle error [rad] (default 1 mrad).
    settle_tip : float
        Settling band of the tip deflection [m] (default 1 mm).
    tau_max : float, optional
        Torque limit [N m]; adds ``within_torque_limit`` (and the saturated fraction).

    Returns
    -------
    dict
        ``verdict`` (:func:`verdict`), the :data:`METRIC_UNITS` entries plus ``controller``,
        ``plant``, the plant's description (``plant_modes``, ``design_modes``, ``substeps``,
        ``step_s``, ...), ``completed``, ``outside_validated_range``,
        ``outside_range_time_s``, ``message``, ``wall_s``, the controller's own statistics
        (e.g. ``qp_fallbacks``, ``fallback_fraction``) and ``within_torque_limit``.

    Raises
    ------
    ParameterError
        If the result is not a closed-loop run, has no reference, or was planned to end
        before ``t_f + residual_delay``.
    """
    t_f = check_positive("tf", t_f, "s")
    if not (isinstance(residual_delay, (int, float)) and residual_delay >= 0):
        raise ParameterError(f"residual_delay must be >= 0 [s], got {residual_delay!r}")
    settle_angle = check_positive("settle_angle", settle_angle, "rad")
    settle_tip = check_positive("settle_tip", settle_tip, "m")
    if result.kind != "closed_loop":
        raise ParameterError(f"result must be a closed-loop run (kind 'closed_loop'), got kind {result.kind!r}")
    if result.theta_ref is None:
        raise ParameterError("the result has no hub reference (pass reference= to simulate_closed_loop)")
    t, v_tip, tau = result.t, result.v_tip, result.tau
    err = result.theta - result.theta_ref
    start = t_f + residual_delay
    window = t >= start - 1e-9
    planned_end = float(result.settings.get("t_end", t[-1]))
    out = {"controller": result.controller, "plant": result.plant}
    if planned_end < start:
        raise ParameterError(f"t_end = {planned_end:g} s must exceed tf + {residual_delay:g} s = "
                             f"{start:g} s to measure the residual vibration")
    k_f = int(np.argmin(np.abs(t - t_f)))
    applied = tau[:-1] if len(tau) > 1 else tau
    dt = float(t[1] - t[0]) if len(t) > 1 else 0.0
    steps = result.step_time_s[np.isfinite(result.step_time_s)]
    res = v_tip[window]
    nan = float("nan")
    growth = residual_growth(res)
    saturated = saturated_fraction(tau[window], tau_max) if tau_max is not None else nan
    settle = settling_time(t, err, v_tip, settle_angle, settle_tip)
    end_peak = float(np.max(np.abs(res[-max(1, res.size // 4):]))) if res.size else nan
    out["verdict"] = verdict(result.stopped, growth, end_peak, saturated, settle is not None, settle_tip)
    out.update({
        "peak_tip_m": float(np.max(np.abs(v_tip))),
        "residual_tip_rms_m": float(np.sqrt(np.mean(res ** 2))) if res.size else nan,
        "residual_tip_max_m": float(np.max(np.abs(res))) if res.size else nan,
        "angle_error_tf_rad": float(err[k_f]) if t[-1] >= t_f - 1e-9 else nan,
        "final_angle_error_rad": float(err[-1]),
        "settling_time_s": settle,
        "peak_torque_nm": float(np.max(np.abs(tau[np.isfinite(tau)]))) if np.any(np.isfinite(tau)) else nan,
        "torque_squared_integral_n2m2s": float(np.sum(applied[np.isfinite(applied)] ** 2) * dt),
        "torque_saturated_fraction": saturated,
        "residual_growth": growth,
        "step_time_median_ms": float(np.median(steps) * 1e3) if steps.size else nan,
        "step_time_p99_ms": float(np.percentile(steps, 99) * 1e3) if steps.size else nan,
    })
    if tau_max is not None:
        out["within_torque_limit"] = bool(out["peak_torque_nm"] <= tau_max * (1 + 1e-9))
    out["completed"] = not result.stopped
    out["outside_validated_range"] = bool(getattr(result, "outside_validated_range", False))
    out["outside_range_time_s"] = getattr(result, "outside_range_time_s", None)
    for key in _PLANT_KEYS:
        if key in result.settings:
            out[key] = result.settings[key]
    out["plant_params"] = result.params.to_dict()
    out["message"] = result.message
    out["wall_s"] = float(result.wall_s)
    for key, value in result.controller_stats.items():
        if isinstance(value, (int, float, str, bool)):
            out[key] = value
    return out
