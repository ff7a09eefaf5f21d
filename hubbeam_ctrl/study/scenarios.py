"""Closed-loop scenarios: the task (reference, torque budget, times) and its design point.

Scenarios
---------
``slew``
    Rest-to-rest rotation by ``slew_angle`` (or a :class:`~hubbeam_ctrl.study.tasks.Slew`
    task) in ``t_f``; without an angle, by the rigid-body angle of the paper's Eq. 44
    profile with amplitude ``tau_max``, ``Theta = tau_max t_f^2 / (2 pi J_total)``. The
    baseline is the open-loop Eq. 44 torque scaled to the same angle and time,
    ``tau_m = 2 pi J_total Theta / t_f^2`` (refused if above ``tau_max``); the feedback
    controllers follow a smooth reference (:func:`controllers.slew_reference`) designed on
    SFOAM linearised at rest.
``spinup``
    Spin-up to ``w_f`` (default 3 rad/s, above TLAM's critical speed; or a
    :class:`~hubbeam_ctrl.study.tasks.SpinUp` task) along the corrected
    Eq. 43 profile in ``t_f``, then hold; design model linearised at ``w_f``. The baseline
    is the rigid-body feedforward torque alone.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from controllers import slew_reference, spinup_reference
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.study.tasks import Slew, SpinUp

__all__ = ["SCENARIOS", "PLANTS", "Scenario", "make_scenario"]

SCENARIOS = ("slew", "spinup")
PLANTS = ("foam", "cfoam")


def _number(name, value, unit, positive=True):
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)) \
            or not math.isfinite(value) or (positive and not value > 0):
        raise ParameterError(f"{name} must be a finite number{' > 0' if positive else ''} "
                             f"[{unit}], got {value!r}")
    return float(value)


@dataclass(frozen=True, eq=False)
class Scenario:
    """A closed-loop task: reference, torque budget, times and design point.

    Attributes
    ----------
    name : {"slew", "spinup"}
    plant : {"foam", "cfoam"}
    params : Params
    tau_max : float
        Torque budget [N m] (= Eq. 44's tau_m in the slew).
    t_f : float
        Maneuver time [s].
    t_end : float
        Simulated time [s].
    dt : float
        Controller sample time [s].
    design_spin : float
        Spin rate of the SFOAM linearisation [rad/s].
    target : float
        Slew angle Theta [rad] or final rate w_f [rad/s].
    reference : controllers.Reference
        Hub reference and feedforward torque of the feedback controllers.
    description : str
    task : Slew or SpinUp
        The task in physical terms.
    baseline_tau_m : float or None
        Slew: amplitude of the open-loop Eq. 44 baseline [N m], ``2 pi J_total Theta / t_f^2``
        (``tau_max`` itself for the Eq. 44 angle); None for the spin-up.
    """

    name: str
    plant: str
    params: Params
    tau_max: float
    t_f: float
    t_end: float
    dt: float
    design_spin: float
    target: float
    reference: object
    description: str
    task: object = None
    baseline_tau_m: float | None = None

    def to_dict(self) -> dict:
        """Plain-data summary (JSON-ready)."""
        return {"scenario": self.name, "plant": self.plant, "tau_max_nm": self.tau_max,
                "tf_s": self.t_f, "t_end_s": self.t_end, "dt_s": self.dt,
                "design_spin_rad_s": self.design_spin,
                ("slew_angle_rad" if self.name == "slew" else "final_rate_rad_s"): self.target,
                "reference": self.reference.description, "params": self.params.to_dict(),
                "baseline_tau_m_nm": self.baseline_tau_m, "description": self.description}


def make_scenario(scenario="slew", *, plant: str = "cfoam", params: Params | None = None,
                  tau_max: float | None = None, t_f: float = 10.0, t_end: float = 30.0,
                  dt: float = 0.01, w_f: float = 3.0, slew_angle: float | None = None,
                  flatness: float = 3.0, preview_s: float = 2.0) -> Scenario:
    """Build a :class:`Scenario` (validating every setting).

    Parameters
    ----------
    scenario : {"slew", "spinup"} or Slew or SpinUp
        The scenario's name, or a task in physical terms (:mod:`hubbeam_ctrl.study.tasks`);
        a task gives the angle or rate and the duration (``t_f``, ``w_f`` and
        ``slew_angle`` are then not used).
    plant : {"foam", "cfoam"}
    params : Params, optional
        Default: Table 1 (m_t = 0.1 kg at the tip).
    tau_max : float, optional
        Torque budget [N m], 0 < tau_max <= ``params.tau_max`` (default: the motor's
        ``params.tau_max``). Without ``slew_angle`` the slew turns by the rigid angle of
        Eq. 44 with amplitude ``tau_max``.
    t_f : float
        Maneuver time [s], > 0.
    t_end : float
        Simulated time [s]; must exceed ``t_f + 5`` (the residual window).
    dt : float
        Controller sample time [s], > 0.
    w_f : float
        Spin-up final rate [rad/s] (spinup only).
    slew_angle : float, optional
        Slew angle [rad], finite and not 0 (slew only); default: the Eq. 44 angle
        ``tau_max t_f^2 / (2 pi J_total)``.
    flatness : float
        Shape of the slew reference (see :func:`controllers.slew_reference`).
    preview_s : float
        Reference tabulated this long beyond ``t_end`` (MPC preview) [s].

    Returns
    -------
    Scenario

    Raises
    ------
    ParameterError
        Among others when the task needs more torque than ``tau_max``: the message names
        the shortest feasible ``tf`` (or ``duration`` for a task object).
    """
    if plant not in PLANTS:
        raise ParameterError(f"plant must be one of {', '.join(PLANTS)}, got {plant!r}")
    params = params if params is not None else Params()
    if not isinstance(params, Params):
        raise ParameterError(f"params must be a Params, got {type(params).__name__}")
    tau_max = _budget(tau_max, params)
    t_end = _number("t_end", t_end, "s")
    dt = _number("dt", dt, "s")
    J = params.total_inertia
    task, tf_name = _task(scenario, tau_max, t_f, w_f, slew_angle, J)
    t_f = task.duration
    if t_end <= t_f + 5.0:
        raise ParameterError(f"t_end must exceed tf + 5 s = {t_f + 5:g} s (the residual-vibration "
                             f"window starts there), got {t_end:g} s")
    if dt > t_f / 10:
        raise ParameterError(f"dt must be at most tf/10 = {t_f / 10:g} s, got {dt:g} s")
    task.check_feasible(J, tau_max, tf_name)
    horizon_end = t_end + preview_s
    if task.name == "slew":
        theta = task.angle
        ref = slew_reference(theta, t_f, J, tau_max, dt, horizon_end, flatness=flatness)
        eq44 = slew_angle is None and isinstance(scenario, str)
        baseline = tau_max if eq44 else task.baseline_torque(J)
        text = (f"rest-to-rest slew by Theta = tau_m tf^2/(2 pi J_total) = {theta:.4f} rad "
                f"(tau_m = {tau_max:g} N m, tf = {t_f:g} s, J_total = {J:.4g} kg m^2)") if eq44 \
            else task.describe(J)
        return Scenario("slew", plant, params, tau_max, t_f, t_end, dt, 0.0, theta, ref, text,
                        task=task, baseline_tau_m=baseline)
    ref = spinup_reference(task.rate, t_f, J, dt, horizon_end, tau_max=tau_max)
    return Scenario("spinup", plant, params, tau_max, t_f, t_end, dt, task.rate, task.rate, ref,
                    f"{task.describe(J)}; design model linearised at {task.rate:g} rad/s", task=task)


def _budget(tau_max, params: Params) -> float:
    """The scenario's torque budget: ``tau_max`` or the motor's, never above the motor's [N m]."""
    if tau_max is None:
        return params.tau_max
    tau_max = _number("tau_max", tau_max, "N m")
    if tau_max > params.tau_max:
        raise ParameterError(f"tau_max must be in (0, {params.tau_max:g}] N m (the motor's "
                             f"Params.tau_max), got {tau_max:g}")
    return tau_max


def _task(scenario, tau_max: float, t_f, w_f, slew_angle, inertia: float):
    """``(task, name of its duration)`` from a task object or a scenario name and its options."""
    if isinstance(scenario, (Slew, SpinUp)):
        return scenario, "duration"
    if scenario not in SCENARIOS:
        raise ParameterError(f"scenario must be one of {', '.join(SCENARIOS)} or a Slew or SpinUp "
                             f"task, got {scenario!r}")
    t_f = _number("tf", t_f, "s")
    if scenario == "spinup":
        if slew_angle is not None:
            raise ParameterError("slew_angle applies to the slew scenario only")
        return SpinUp(_number("wf", w_f, "rad/s", positive=False), t_f), "tf"
    if slew_angle is None:
        return Slew.eq44(tau_max, t_f, inertia), "tf"
    angle = _number("slew_angle", slew_angle, "rad", positive=False)
    if angle == 0.0:
        raise ParameterError("slew_angle must be a finite number != 0 [rad], got 0")
    return Slew(angle, t_f), "tf"
