"""Input shapers on the nonlinear plant: residual vibration against frequency error.

:func:`controllers.shaping.shaper_sensitivity` gives each shaper's residual vibration for
a linear mode whose frequency is off by a relative error. :func:`plant_sensitivity`
checks it on the nonlinear plant: the plant's frequency is moved (Young's modulus scaled
by ``(1 + e)^2``, which scales every bending frequency at rest by exactly ``1 + e``, or a
tip mass found by modal analysis), and the residual tip vibration of the shaped open-loop
slew is divided by that of the same base profile unshaped.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from controllers import DesignModel, ShapedOpenLoop, ShapedSettings, Shaper, design_shaper
from controllers.shaped import shaped_profile
from controllers.shaping import SHAPERS, design_modes
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.validation import check_positive
from hubbeam_ctrl.plant.modal import modal_analysis
from hubbeam_ctrl.plant.models import build_model
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.sim.closedloop import ClosedLoopSettings, simulate_closed_loop

__all__ = ["plant_sensitivity", "residual_after", "plant_variant", "VARIANTS", "task_shaped_settings"]

#: How :func:`plant_variant` moves the plant's first frequency.
VARIANTS = ("stiffness", "tip_mass")


def _first_frequency(plant: str, params: Params) -> float:
    return float(modal_analysis(plant, 0.0, "free", params).bending_hz[0])


def plant_variant(params: Params, error: float, how: str = "stiffness", plant: str = "foam") -> Params:
    """Plant parameters whose first bending frequency at rest (free hub) is ``(1 + error)`` times ``params``'.

    Parameters
    ----------
    params : Params
    error : float
        Relative frequency error [-], > -1.
    how : {"stiffness", "tip_mass"}
        ``"stiffness"``: Young's modulus ``E (1 + error)^2`` (every bending frequency moves
        by exactly ``1 + error``); ``"tip_mass"``: the tip mass that gives the first
        frequency, found by modal analysis (only the first mode moves by exactly that).
    plant : str
        Model of the modal analysis.

    Returns
    -------
    Params
    """
    if not (isinstance(error, (int, float, np.floating)) and np.isfinite(error) and error > -1):
        raise ParameterError(f"error must be a finite relative frequency error > -1 [-], got {error!r}")
    if how == "stiffness":
        return params.replace(E=params.E * (1 + error) ** 2)
    if how != "tip_mass":
        raise ParameterError(f"how must be one of {', '.join(VARIANTS)}, got {how!r}")
    target = (1 + error) * _first_frequency(plant, params)
    f = lambda m: _first_frequency(plant, params.replace(m_t=m)) - target
    hi = max(1.0, 4 * params.m_t)
    while f(hi) > 0 and hi < 1e3 * params.beam_mass:
        hi *= 4
    if f(0.0) < 0 or f(hi) > 0:
        raise ParameterError(f"error = {error:g}: no tip mass in [0, {hi:.3g}] kg moves the first "
                             f"frequency by that much; use how='stiffness'")
    import scipy.optimize  # here: SciPy's optimize package costs 0.2 s of every command's start
    return params.replace(m_t=scipy.optimize.brentq(f, 0.0, hi, xtol=1e-12))


def task_shaped_settings(kind: str, settings, design: DesignModel, scenario):
    """A shaped slew's settings for a task, with the task's duration ``t_f`` honoured (issue 22).

    The settings from :meth:`ShapedSettings.for_scenario` ask for the slew in ``t_f``. A ``t_f``
    that the torque budget cannot do raises, naming ``t_f`` and the shortest feasible duration;
    except on the Eq. 44 task (the angle the Eq. 44 torque turns at the full budget in ``t_f``),
    which no shaped profile can turn in ``t_f`` by construction: there the slew takes its
    shortest feasible duration and the returned note says so.

    Parameters
    ----------
    kind : str
        Controller name (``"zv"``, ``"zvd"``, ``"ei"``; any other is returned unchanged).
    settings : ControllerSettings
        The controller's settings (a :class:`ShapedSettings` for a shaped kind).
    design : DesignModel
        The design model (modes, rigid-body inertia).
    scenario : Scenario
        The task (read: ``t_f`` [s], ``tau_max`` [N m], ``reference``, ``baseline``,
        ``baseline_tau_m`` [N m]).

    Returns
    -------
    settings : ControllerSettings
    note : str or None
        One line for the report when the slew is longer than ``t_f``.

    Raises
    ------
    ParameterError
        ``t_f = ... s is too short for KIND: ...; shortest feasible duration ... s``.
    """
    if not isinstance(settings, ShapedSettings) or settings.duration is None or kind not in SHAPERS:
        return settings, None
    try:
        shaped_profile(design, kind, settings, scenario.reference)
        return settings, None
    except ParameterError as exc:
        text = str(exc)
        if not text.startswith("duration = "):
            raise
        eq44 = (scenario.baseline == "eq44" and scenario.baseline_tau_m is not None
                and scenario.baseline_tau_m >= scenario.tau_max * (1 - 1e-9))
        if not eq44:
            raise ParameterError(f"t_f = {scenario.t_f:g} s is too short for {kind}: "
                                 f"{text.split(' is too short: ', 1)[-1]}") from None
    longest = dataclasses.replace(settings, duration=None)
    took = shaped_profile(design, kind, longest, scenario.reference).duration
    return longest, (f"{kind}: its shaped slew takes {took:.4g} s, longer than t_f = {scenario.t_f:g} s (no "
                     f"shaped profile turns the Eq. 44 angle within tau_max = {scenario.tau_max:g} N m in t_f)")


def residual_after(result, start: float) -> float:
    """Max ``|v_tip|`` [m] from ``start`` [s] to the end of a closed-loop run (inf if it stopped).

    Parameters
    ----------
    result : Result
        A closed-loop run.
    start : float
        Start of the window [s].
    """
    if result.stopped:
        return float("inf")
    return float(np.max(np.abs(result.v_tip[result.t >= start - 1e-9])))


def plant_sensitivity(design: DesignModel, errors=(-0.2, 0.0, 0.2), kinds=SHAPERS, *,
                      plant: str = "foam", params: Params | None = None, tau_max: float | None = None,
                      base_duration: float = 8.0, modes=None, tolerance: float = 0.05,
                      residual_window: float = 10.0, how: str = "stiffness") -> dict:
    """Residual vibration of shaped open-loop slews on the nonlinear plant, by frequency error.

    The base profile is a bang-bang slew that uses exactly ``tau_max`` in ``base_duration``
    (its angle follows); each shaper lengthens it by its own duration. For every error
    ``e`` the plant is :func:`plant_variant` ``(params, e, how)``.

    Parameters
    ----------
    design : DesignModel
        Gives the shapers (its modes at its design spin, which should be 0 here).
    errors : sequence of float
        Relative frequency errors [-], each > -1.
    kinds : sequence of {"zv", "zvd", "ei"}
    plant : str
        Nonlinear plant model (``"foam"`` or ``"cfoam"``).
    params : Params, optional
        Plant parameters at ``e = 0`` (default ``design.params``).
    tau_max : float, optional
        Torque of the bang-bang base profile [N m], > 0 (default: a quarter of the drive's
        ``params.tau_max``, 50 N m on Table 1's beam, which keeps FOAM close to linear).
    base_duration : float
        Length of the base profile [s], > 0.
    modes : sequence of int, optional
        Mode numbers shaped (default: all of the design model's).
    tolerance : float
        EI's allowed residual [-].
    residual_window : float
        The residual is taken over this long after the longest shaped profile ends [s].
    how : {"stiffness", "tip_mass"}
        How the plant's frequency is moved (see :func:`plant_variant`).

    Returns
    -------
    dict
        ``"errors"`` [-]; ``"unshaped_m"``: residual of the unshaped base profile [m] per
        error; and per kind ``"<kind>"``: measured residual ratio [-] and
        ``"<kind>_linear"``: the shaper's residual vibration at ``(1 + e) omega_1`` [-].
    """
    err = np.asarray(errors, dtype=float).ravel()
    if err.size == 0 or not np.all(np.isfinite(err)) or np.any(err <= -1):
        raise ParameterError("errors must be finite relative frequency errors > -1 [-]")
    params = params if params is not None else design.params
    tau_max = check_positive("tau_max", params.tau_max / 4 if tau_max is None else tau_max, "N m")
    T = check_positive("base_duration", base_duration, "s")
    modes = tuple(range(1, design.n_modes + 1)) if modes is None else modes
    shapers = {k: design_shaper(design, k, modes, tolerance) for k in kinds}
    shapers["unshaped"] = Shaper(np.zeros(1), np.ones(1), "unshaped")
    angle = tau_max * T ** 2 / (4 * design.inertia)
    start = T + max(s.duration for s in shapers.values())
    sim = ClosedLoopSettings(dt=design.dt)
    w, z = design_modes(design)
    w1, z1 = float(w[0]), float(z[0])
    out = {"errors": err, "unshaped_m": np.zeros(err.size)}
    for k in kinds:
        out[k] = np.zeros(err.size)
        out[f"{k}_linear"] = shapers[k].residual(w1 * (1 + err), z1)
    for i, e in enumerate(err):
        model = build_model(plant, plant_variant(params, float(e), how, plant))
        res = {}
        for k, sh in shapers.items():
            st = ShapedSettings(profile="bangbang", angle=angle, tau_max=tau_max, duration=T + sh.duration)
            r = simulate_closed_loop(model, ShapedOpenLoop(design, st, shaper=sh), start + residual_window,
                                     settings=sim)
            res[k] = residual_after(r, start)
        out["unshaped_m"][i] = res["unshaped"]
        for k in kinds:
            out[k][i] = res[k] / res["unshaped"]
    return out
