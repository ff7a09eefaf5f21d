"""Closed-loop scenarios: the task (reference, torque budget, times) and its design point.

Scenarios are registered once in :data:`SCENARIOS` with :func:`register_scenario`; the
comparison and the CLI (``--scenario`` choices and help) read the registry. Built in:
``slew`` (rest-to-rest by the Eq. 44 rigid angle) and ``spinup`` (the corrected Eq. 43
profile, then hold); their builders' docstrings say more.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from controllers import slew_reference, spinup_reference
from hubbeam_ctrl.core.budget import T_END_MAX
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.validation import check_in_range
from hubbeam_ctrl.plant.params import Params, check_spin

__all__ = ["RANGES", "SCENARIOS", "PLANTS", "Scenario", "make_scenario", "register_scenario"]

#: Scenario name -> builder, in registration order (see :func:`register_scenario`).
SCENARIOS: dict = {}
#: The nonlinear plants a scenario runs on (the models with dynamic stiffening and axial modes).
PLANTS = ("foam", "cfoam")


def register_scenario(name: str):
    """Register a scenario builder under ``name`` (a decorator).

    The builder is called by :func:`make_scenario` with the validated keyword arguments
    ``params``, ``tau_max``, ``t_f``, ``dt``, ``t_ref_end`` (last reference sample [s]),
    ``w_f`` and ``flatness`` (it takes those it needs and ``**_`` for the rest) and returns
    a dict with ``design_spin`` [rad/s], ``target``, ``target_key`` (its name with unit in
    summaries), ``baseline`` (the open-loop profile compared against: ``"eq44"`` or
    ``"feedforward"``), ``reference`` and ``description``.

    Parameters
    ----------
    name : str
        Scenario name.

    Returns
    -------
    callable
        The decorator (returns the builder unchanged).
    """
    def register(builder):
        SCENARIOS[name] = builder
        return builder
    return register


#: Ranges of :func:`make_scenario`'s numbers: name as in messages -> (lo, hi, unit). Also
#: ``t_end > tf + 5``, ``dt <= tf / 10``, ``abs(wf) <= params.max_spin`` and, for the slew,
#: ``tau_max tf / (pi J_total) <= params.max_spin``.
RANGES = {"tau_max": (1e-6, 1e9, "N m"), "tf": (1e-3, 1e6, "s"), "t_end": (1e-3, T_END_MAX, "s"),
          "dt": (1e-6, 10.0, "s")}


@dataclass(frozen=True, eq=False)
class Scenario:
    """A closed-loop task: reference, torque budget, times and design point.

    Attributes
    ----------
    name : str
        Registered scenario name (:data:`SCENARIOS`).
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
    target_key : str
        Name (with unit suffix) of ``target`` in :meth:`to_dict`.
    baseline : {"eq44", "feedforward"}
        The open-loop profile the scenario compares against
        (:class:`controllers.OpenLoopSettings`).
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
    target_key: str = "target"
    baseline: str = "feedforward"

    def to_dict(self) -> dict:
        """Plain-data summary (JSON-ready)."""
        return {"scenario": self.name, "plant": self.plant, "tau_max_nm": self.tau_max,
                "tf_s": self.t_f, "t_end_s": self.t_end, "dt_s": self.dt,
                "design_spin_rad_s": self.design_spin,
                self.target_key: self.target,
                "reference": self.reference.description, "params": self.params.to_dict(),
                "description": self.description}


def make_scenario(scenario: str = "slew", *, plant: str = "cfoam", params: Params | None = None,
                  tau_max: float = 200.0, t_f: float = 10.0, t_end: float = 30.0,
                  dt: float = 0.01, w_f: float = 3.0, flatness: float = 3.0,
                  preview_s: float = 2.0) -> Scenario:
    """Build a :class:`Scenario` (validating every setting).

    Parameters
    ----------
    scenario : str
        A registered scenario (:data:`SCENARIOS`: ``slew``, ``spinup``).
    plant : {"foam", "cfoam"}
    params : Params, optional
        Default: Table 1 (m_t = 0.1 kg at the tip).
    tau_max : float
        Torque budget [N m], in [1e-6, 1e9] (the slew's Eq. 44 amplitude); the slew's peak
        rigid rate ``tau_max t_f / (pi J_total)`` must not exceed ``params.max_spin``.
    t_f : float
        Maneuver time [s], in [1e-3, 1e6].
    t_end : float
        Simulated time [s]; must exceed ``t_f + 5`` (the residual window), at most 1e9.
    dt : float
        Controller sample time [s], in [1e-6, 10] and at most ``t_f / 10``.
    w_f : float
        Spin-up final rate [rad/s] (spinup only), ``|w_f| <= params.max_spin``.
    flatness : float
        Shape of the slew reference (see :func:`controllers.slew_reference`).
    preview_s : float
        Reference tabulated this long beyond ``t_end`` (MPC preview) [s].

    Returns
    -------
    Scenario
    """
    if scenario not in SCENARIOS:
        raise ParameterError(f"scenario must be one of {', '.join(SCENARIOS)}, got {scenario!r}")
    if plant not in PLANTS:
        raise ParameterError(f"plant must be one of {', '.join(PLANTS)}, got {plant!r}")
    params = params if params is not None else Params()
    if not isinstance(params, Params):
        raise ParameterError(f"params must be a Params, got {type(params).__name__}")
    tau_max, t_f, t_end, dt = (check_in_range(name, value, RANGES[name][2], *RANGES[name][:2])
                               for name, value in (("tau_max", tau_max), ("tf", t_f),
                                                   ("t_end", t_end), ("dt", dt)))
    if t_end <= t_f + 5.0:
        raise ParameterError(f"t_end must exceed tf + 5 s = {t_f + 5:g} s (the residual-vibration "
                             f"window starts there), got {t_end:g} s")
    if dt > t_f / 10:
        raise ParameterError(f"dt must be at most tf/10 = {t_f / 10:g} s, got {dt:g} s")
    parts = SCENARIOS[scenario](params=params, tau_max=tau_max, t_f=t_f, dt=dt,
                                t_ref_end=t_end + preview_s, w_f=w_f, flatness=flatness)
    return Scenario(scenario, plant, params, tau_max, t_f, t_end, dt, **parts)


@register_scenario("slew")
def _slew(*, params, tau_max, t_f, dt, t_ref_end, flatness, **_) -> dict:
    """Rest-to-rest slew by the rigid-body angle of Eq. 44 in tf, with its budget tau_max.

    ``Theta = tau_m t_f^2 / (2 pi J_total)`` with ``tau_m = tau_max``. The baseline is the
    open-loop Eq. 44 torque itself; the feedback controllers follow a smooth reference
    (:func:`controllers.slew_reference`) designed on SFOAM linearised at rest.
    """
    J = params.total_inertia
    peak = tau_max * t_f / (math.pi * J)
    if peak > params.max_spin:
        raise ParameterError(f"tau_max = {tau_max:g} N m over tf = {t_f:g} s spins the hub up to {peak:.4g} "
                             f"rad/s (tau_max tf / (pi J_total)), above Params.max_spin = "
                             f"{params.max_spin:.4g} rad/s (1 % centrifugal strain at the root)")
    theta = tau_max * t_f ** 2 / (2 * math.pi * J)
    ref = slew_reference(theta, t_f, J, tau_max, dt, t_ref_end, flatness=flatness)
    return dict(design_spin=0.0, target=theta, target_key="slew_angle_rad", baseline="eq44", reference=ref,
                description=f"rest-to-rest slew by Theta = tau_m tf^2/(2 pi J_total) = {theta:.4f} rad "
                            f"(tau_m = {tau_max:g} N m, tf = {t_f:g} s, J_total = {J:.4g} kg m^2)")


@register_scenario("spinup")
def _spinup(*, params, tau_max, t_f, dt, t_ref_end, w_f, **_) -> dict:
    """Spin-up to wf along the corrected Eq. 43 profile in tf, then hold.

    The default ``w_f`` (3 rad/s) is above TLAM's critical speed; the design model is
    linearised at ``w_f``. The baseline is the rigid-body feedforward torque alone.
    """
    w_f = check_spin("wf", w_f, params)
    ref = spinup_reference(w_f, t_f, params.total_inertia, dt, t_ref_end, tau_max=tau_max)
    return dict(design_spin=w_f, target=w_f, target_key="final_rate_rad_s", baseline="feedforward",
                reference=ref,
                description=f"spin-up to {w_f:g} rad/s in tf = {t_f:g} s (Eq. 43), then hold; "
                            f"design model linearised at {w_f:g} rad/s")
