"""Open-loop maneuvers on the exact-beam plant (``hubbeam simulate --plant ancf``).

:func:`simulate_exact` runs a hub torque (free hub, the torque applied at every integration step,
no zero-order hold) or a prescribed hub motion (spin-up) on
:class:`~hubbeam_ctrl.exact.ExactBeamPlant`, Exudyn's geometrically exact ANCF beam, and returns
the toolbox's :class:`~hubbeam_ctrl.sim.results.Result` (``kind="fixed_step"``,
``model="ancf"``): the exact ``v_tip``, ``u_tip`` and root moment, and the state projected on
FOAM's assumed modes. The elements come from :func:`~hubbeam_ctrl.exact.element_rule`, the step
from the assumed-mode plant's :func:`~hubbeam_ctrl.sim.stepper.substep_rule` (FOAM's modes at
rest, hub free or prescribed as the maneuver says). Passing ``range_limit`` L is recorded (the
assumed-mode models' validated range; the exact beam has none), only ``divergence_limit`` L
stops the run.
"""

from __future__ import annotations

import math
import time

import numpy as np

from hubbeam_ctrl.core.budget import T_END_MAX, WallClock, check_budget
from hubbeam_ctrl.core.errors import HubbeamError, ParameterError
from hubbeam_ctrl.core.progress import progress_bar
from hubbeam_ctrl.core.validation import check_in_range
from hubbeam_ctrl.exact import ExactBeamPlant, element_rule, require_exudyn
from hubbeam_ctrl.plant.modal import modal_analysis
from hubbeam_ctrl.plant.models import build_model
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.sim.results import Result
from hubbeam_ctrl.sim.simulate import _check_maneuver_spin, _maneuver_and_hub
from hubbeam_ctrl.sim.stepper import substep_rule

__all__ = ["simulate_exact"]

#: Low estimate of the wall time of one integration step of 16 ANCF elements [s] (measured 0.25 ms
#: with 16 elements, 0.5 ms with 32, shared 2-core machine); scaled by the element count.
SECONDS_PER_STEP = 5e-5


def simulate_exact(maneuver, t_end: float = 30.0, *, params: Params | None = None, dt: float = 0.01,
                   substeps: int | None = None, n_elements: int | None = None, rho_inf: float = 0.9,
                   range_limit: float = 0.3, divergence_limit: float = 1.0, max_wall_s: float = 600.0,
                   max_memory_mb: float = 2048.0, progress: bool = False,
                   option_names: dict | None = None) -> Result:
    """Run an open-loop maneuver on the exact-beam plant (Exudyn ANCF; extra ``exact``).

    Parameters
    ----------
    maneuver : TorquePulse, SpinUp, ConstantSpin, UserManeuver or callable
        A hub torque ``tau(t)`` [N m] (free hub) or a prescribed hub motion (its angle
        ``maneuver(t)[0]`` [rad] is imposed by a constraint).
    t_end : float
        Final time [s], at least ``dt``.
    params : Params, optional
        The beam (default Table 1); ``n_transverse`` and ``n_axial`` are the modes of the
        projected state and set the element and step rules.
    dt : float
        Output sample period [s].
    substeps : int, optional
        Integration steps per sample (default: FOAM's :func:`~hubbeam_ctrl.sim.stepper.substep_rule`
        at rest, 0.5 % on the highest mode); fewer than
        :func:`~hubbeam_ctrl.exact.min_substeps` is refused.
    n_elements : int, optional
        ANCF elements (default :func:`~hubbeam_ctrl.exact.element_rule` of ``n_transverse``).
    rho_inf : float
        Spectral radius at infinity of generalized-alpha [-].
    range_limit : float
        The assumed-mode models' validated range as a fraction of L [-]: recorded when passed
        (``past_assumed_mode_range_time_s``), never a stop.
    divergence_limit : float
        ``|v_tip| > divergence_limit L`` stops the run [-].
    max_wall_s : float
        Wall-clock limit [s]: a run whose low estimate (:data:`SECONDS_PER_STEP` per integration
        step and 16 elements) exceeds it is refused; a run that reaches it stops and keeps what it
        computed.
    max_memory_mb : float
        Memory limit of the stored series [MB].
    progress : bool
        A progress bar on stderr (only on a terminal).
    option_names : dict, optional
        How the caller spells the options named in errors: ``substeps``, ``dt``, and ``plant``
        (the option that chose the exact beam, named when Exudyn is missing), e.g.
        ``{"substeps": "--substeps", "plant": "--plant ancf"}``.

    Returns
    -------
    Result
        ``kind="fixed_step"``, ``model="ancf"``; ``settings`` holds ``plant_elements``,
        ``substeps``, ``step_s`` and the reasons; ``stats`` ``past_assumed_mode_range_time_s``.

    Raises
    ------
    ParameterError
        Without Exudyn (one line: how to install it), on bad input or a step that does not
        resolve the highest mode.
    """
    names = {"substeps": "substeps", "dt": "dt", "n_elements": "n_elements", **(option_names or {})}
    require_exudyn(names.get("plant", "simulate_exact"))
    p = Params() if params is None else params
    if not isinstance(p, Params):
        raise ParameterError(f"params must be a Params, got {type(p).__name__}")
    maneuver, hub = _maneuver_and_hub(maneuver, None)
    _check_maneuver_spin(maneuver, p)
    dt = check_in_range(names["dt"], dt, "s", 1e-5, 1.0)
    t_end = check_in_range("t_end", t_end, "s", dt, T_END_MAX, "at least one sample: t_end >= dt")
    range_limit = check_in_range("range_limit", range_limit, "-", 1e-6, 10.0)
    divergence_limit = check_in_range("divergence_limit", divergence_limit, "-", 1e-6, 10.0)
    max_wall_s = check_in_range("max_wall_s", max_wall_s, "s", 1e-3, 1e7)
    max_memory_mb = check_in_range("max_memory_mb", max_memory_mb, "MB", 1.0, 1e9)
    if substeps is None:
        f = modal_analysis(build_model("foam", p), 0.0, hub).bending_hz
        rule = substep_rule(f, dt, rho_inf=rho_inf)
        substeps, step_reason = rule.substeps, (f"{rule.substeps} steps per sample: FOAM's substep rule "
                                                f"(mode {rule.mode} at {rule.frequency_hz:.4g} Hz within 0.5 %)")
    else:
        step_reason = f"{substeps} steps per sample as requested"
    ne = element_rule(p.n_transverse) if n_elements is None else n_elements
    kw = {"torque_function": maneuver} if hub == "free" else {"prescribed": lambda t: float(maneuver(t)[0])}
    try:
        plant = ExactBeamPlant(p, n_elements=ne, dt=dt, substeps=substeps, n_modes=p.n_transverse,
                               n_axial=p.n_axial, rho_inf=rho_inf, substeps_option=names["substeps"],
                               dt_option=names["dt"], **kw)
    except ParameterError as exc:
        text = str(exc)
        for key in ("n_elements", "substeps"):
            if text.startswith(f"{key} ") and names[key] != key:
                raise ParameterError(names[key] + text[len(key):]) from None
        raise
    N = int(round(t_end / dt))
    n_x = 2 * plant.n_q
    check_budget(f"t_end = {t_end:g} s at dt = {dt:g} s ({N + 1} samples of {plant.substeps} steps)",
                 memory_bytes=8.0 * (N + 1) * (n_x + 4) * 2, seconds=N * plant.substeps * SECONDS_PER_STEP
                 * plant.n_elements / 16, max_memory_mb=max_memory_mb, max_wall_s=max_wall_s)
    states = np.full((N + 1, n_x), np.nan)
    out = np.full((N + 1, 4), np.nan)              # v_tip, u_tip, root moment, hub torque
    states[0] = plant.initial_state()
    out[0] = 0.0, 0.0, 0.0, float(maneuver(0.0)) if hub == "free" else 0.0
    L = p.L
    past_range = None
    stopped, message, last = False, "completed", N
    clock = WallClock(max_wall_s)
    start = time.perf_counter()
    bar = progress_bar(N, "simulate ancf", enabled=progress)
    for k in range(N):
        t_next = (k + 1) * dt
        try:
            states[k + 1] = plant.step(states[k], 0.0)
        except HubbeamError as exc:
            stopped, last, message = True, k, f"{exc}; results end at t = {k * dt:.3f} s"
            break
        o = plant.outputs
        tau = float(maneuver(t_next)) if hub == "free" else plant.drive_torque()
        out[k + 1] = o["v_tip"], o["u_tip"], o["root_moment"], tau
        tip = abs(o["v_tip"])
        bar.update(1)
        if past_range is None and not tip <= range_limit * L:
            past_range = t_next
        if not tip <= divergence_limit * L:
            stopped, last = True, k + 1
            message = f"ANCF left its range: |v_tip| > {divergence_limit:g} L at t = {t_next:.3f} s"
            break
        if clock.expired():
            stopped, last = True, k + 1
            message = f"stopped after max_wall_s = {max_wall_s:g} s at t = {t_next:.3f} s"
            break
    bar.close()
    wall = time.perf_counter() - start
    keep = slice(0, last + 1)
    states, out = states[keep], out[keep]
    n = plant.n_q
    if past_range is not None and not stopped:
        message = (f"completed; |v_tip| passed {range_limit:g} L = {range_limit * L:.3g} m at t = {past_range:.3f} s, "
                   "outside the assumed-mode models' validated range; the exact beam has no such limit")
    settings = {"dt": dt, "substeps": plant.substeps, "step_s": dt / plant.substeps, "step_reason": step_reason,
                "min_substeps": plant.min_substeps, "highest_mode_hz": plant.highest_mode_hz,
                "plant_elements": plant.n_elements,
                "plant_element_reason": ("as requested" if n_elements is not None else
                                         f"{plant.n_elements} ANCF cable elements (3 per bending mode of "
                                         f"{p.n_transverse} modes, a multiple of 8, at least 16)"),
                "root_moment_from": "clamp reaction (the joint's Lagrange multiplier)", "rho_inf": rho_inf,
                "t_end": float(t_end), "range_limit": range_limit, "divergence_limit": divergence_limit,
                "maneuver": type(maneuver).__name__}
    return Result(kind="fixed_step", model="ancf", t=dt * np.arange(last + 1), q=states[:, :n], v=states[:, n:],
                  v_tip=out[:, 0], u_tip=out[:, 1], root_moment=out[:, 2], tau=out[:, 3], params=p, hub=hub,
                  settings=settings,
                  stats={"integrator": "exudyn generalized-alpha", "outside_range_time_s": None,
                         "past_assumed_mode_range_time_s": past_range, "substeps": plant.substeps,
                         "peak_error_estimate": None,
                         "ms_per_sample": 1e3 * plant.wall_s / max(last, 1) if math.isfinite(plant.wall_s) else None},
                  stopped=stopped, message=message, wall_s=wall)
