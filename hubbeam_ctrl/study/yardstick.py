"""The physical limit as the yardstick of a verdict: settling time against the fastest possible task.

"% of the open loop's residual" says how much better a controller is than the paper's Eq. 44
torque, not how good it is: with damping the open loop decays too, and on a payload where
Eq. 44 happens to leave little vibration the ratio reads 300 %. This module states every run
in absolute terms (issue 22):

* ``limit_s``: the shortest time the task can take with the torque the drive has. By default
  the rigid body's bound (closed form: ``2 sqrt(|Theta| J / tau_max)`` for a rest-to-rest
  slew, ``J |w_f| / tau_max`` for a spin-up), which no flexible beam beats; with
  ``limit="optimal"`` the time-optimal slew of the nonlinear beam that ends with its residual
  vibration below 0.1 % of L (:func:`hubbeam_ctrl.limit.time_optimal_slew`, on the rig when
  there is one: back-EMF, current limit and friction included). ``limit_kind`` says which.
* ``settling_over_limit``: the run's settling time (hub in its angle band and tip in its
  deflection band, for good) over ``limit_s``: 1 is the physical limit itself.
* ``residual_pct_of_L``: the residual tip vibration as a percentage of the beam's length.
"""

from __future__ import annotations

import dataclasses
import math

from hubbeam_ctrl.core.errors import ParameterError

__all__ = ["LINEAR_PLAN_TIP_SHARE", "linear_plan_note", "linear_plan_tip_share",
           "LIMIT_KINDS", "RESIDUAL_PERIODS", "rigid_limit", "task_limit", "yardstick_metrics", "task_t_end",
           "task_dt", "SAMPLES_PER_PERIOD", "DEFAULT_RIG_SLEW_RAD", "DEFAULT_RIG_PACE", "rig_default_slew",
           "task_on_rig", "rig_angle_note"]

#: The angle of a rig's default slew [rad]: a quarter turn.
DEFAULT_RIG_SLEW_RAD = math.pi / 2
#: A rig's default slew takes this many times an upper bound of its time-optimal slew.
DEFAULT_RIG_PACE = 1.5

#: The yardsticks a comparison can use.
LIMIT_KINDS = ("rigid", "optimal")
#: ``limit_kind`` of the rigid bound on a rig's DC drive.
DRIVE_BOUND = "rigid bound on the drive"


def rigid_limit(scenario) -> float:
    """The rigid body's shortest time for the task [s] (a bound no flexible beam beats).

    Parameters
    ----------
    scenario : Scenario
        Its ``name`` (``slew`` or ``spinup``), ``target`` (angle [rad] or final rate [rad/s]),
        ``tau_max`` and ``params.total_inertia``.

    Returns
    -------
    float
        ``2 sqrt(|Theta| J / tau_max)`` for a slew, ``J |w_f| / tau_max`` for a spin-up.
    """
    J, tau = scenario.params.total_inertia, scenario.tau_max
    if scenario.name == "spinup":
        return J * abs(scenario.target) / tau
    return 2.0 * math.sqrt(abs(scenario.target) * J / tau)


def task_limit(scenario, kind: str = "rigid", rig=None) -> dict:
    """The yardstick of a task: ``{"limit_s", "limit_kind"}``.

    Parameters
    ----------
    scenario : Scenario
    kind : {"rigid", "optimal"}
        ``"optimal"``: the time-optimal slew of the nonlinear beam (a slew only; seconds to a
        minute of IPOPT, see :mod:`hubbeam_ctrl.limit`).
    rig : Rig, optional
        The rig whose drive bounds the slew: with a DC motor the rigid bound of a slew is the
        bang-bang within its voltage limit through back-EMF, current limit and friction
        (:func:`hubbeam_ctrl.limit.rigid_bound`; at least the bound with ``tau_max``),
        ``limit_kind`` :data:`DRIVE_BOUND`; and the time-optimal slew.

    Returns
    -------
    dict
    """
    if kind not in LIMIT_KINDS:
        raise ParameterError(f"limit must be one of {', '.join(LIMIT_KINDS)}, got {kind!r}")
    if kind == "rigid" or scenario.name != "slew":
        if rig is not None and scenario.name == "slew" and not rig.drive.is_ideal:
            from hubbeam_ctrl.limit import rigid_bound  # back-EMF, current limit, friction (issue 36)
            bound = rigid_bound(scenario.params, scenario.target, rig)
            return {"limit_s": max(bound, rigid_limit(scenario)), "limit_kind": DRIVE_BOUND}
        return {"limit_s": rigid_limit(scenario), "limit_kind": "rigid bound"}
    from hubbeam_ctrl.limit import time_optimal_slew
    source = rig if rig is not None else scenario.params
    r = time_optimal_slew(source, scenario.target)
    return {"limit_s": r.duration_s, "limit_kind": "time-optimal" + ("" if r.converged else " (not converged)")}


def yardstick_metrics(metrics: dict, scenario, limit: dict) -> dict:
    """The absolute figures of one run: settling time over the limit, residual in % of L.

    Parameters
    ----------
    metrics : dict
        The run's metrics (``settling_time_s``, ``residual_tip_max_m``).
    scenario : Scenario
    limit : dict
        From :func:`task_limit`.

    Returns
    -------
    dict
        ``limit_s``, ``limit_kind``, ``settling_over_limit`` (None when the run did not settle),
        ``residual_pct_of_L``.
    """
    settle = metrics.get("settling_time_s")
    residual = metrics.get("residual_tip_max_m")
    L = scenario.params.L
    return {**limit,
            "settling_over_limit": None if settle is None else settle / limit["limit_s"],
            "residual_pct_of_L": (100.0 * residual / L if residual is not None and math.isfinite(residual)
                                  else float("nan"))}


#: First-mode periods the run goes on after the residual window opens (:func:`task_t_end`).
RESIDUAL_PERIODS = 6


def task_t_end(scenario) -> float:
    """Simulated time of a task [s], from the task and the beam (issue 22: not the paper's 30 s).

    The residual window opens at ``t_f + residual_delay`` and lasts :data:`RESIDUAL_PERIODS`
    periods of the design model's first flexible mode (enough half-period blocks for the
    envelope-growth evidence of the verdict), and the run lasts at least ``3 t_f``: 30 s for the
    paper's 10 s slew and spin-up, as before; 3.6 s for the 1 m lab arm's 1.2 s slew; 2.19 s for
    the 0.6 s slew of ``servo_link``.

    Parameters
    ----------
    scenario : Scenario
        Its ``t_f``, ``bands["residual_delay"]`` [s], ``dt`` and design model.

    Returns
    -------
    float
        [s], a whole number of samples (``3 t_f`` itself when that is the longer).
    """
    from controllers import DesignModel
    from controllers.scaling import first_mode
    w1 = first_mode(DesignModel.build(scenario.params, scenario.design_spin, scenario.dt, 1))
    window = scenario.t_f + scenario.bands["residual_delay"] + RESIDUAL_PERIODS * 2 * math.pi / w1
    if window <= 3.0 * scenario.t_f:
        return 3.0 * scenario.t_f
    return math.ceil(window / scenario.dt - 1e-9) * scenario.dt


#: Fewest samples per period of the first flexible mode the default sample time gives (:func:`task_dt`).
SAMPLES_PER_PERIOD = 20
#: The longest default sample time [s] (the paper's 10 ms).
DT_MAX = 0.01


def task_dt(params, spin: float = 0.0) -> float:
    """Default controller sample time for a beam [s] (issue 22: not the paper's 10 ms on a stiff beam).

    At least :data:`SAMPLES_PER_PERIOD` samples per period of the design model's first flexible
    mode, at most 10 ms, rounded down to 1, 2 or 5 times a power of ten: 10 ms for the paper's
    beam (0.46 Hz) and the 1 m lab arm (4.7 Hz), 0.5 ms for a 52 Hz link. A rig's own
    ``timing.dt`` takes precedence.

    Parameters
    ----------
    params : Params
    spin : float
        Design spin rate [rad/s].

    Returns
    -------
    float
    """
    from controllers import DesignModel
    from controllers.scaling import first_mode
    w1 = first_mode(DesignModel.build(params, spin, DT_MAX, 1))
    dt = 2 * math.pi / w1 / SAMPLES_PER_PERIOD
    if dt >= DT_MAX:
        return DT_MAX
    decade = 10.0 ** math.floor(math.log10(dt))
    return max(m * decade for m in (1.0, 2.0, 5.0) if m * decade <= dt * (1 + 1e-12))


def rig_default_slew(rig, slew_angle: float | None = None):
    """The slew a rig is asked for when the caller names no duration: ``(Slew, note)``.

    The duration is :data:`DEFAULT_RIG_PACE` times an upper bound of the time-optimal slew
    that costs no optimisation: the rigid body's shortest slew on the rig's drive
    (:func:`hubbeam_ctrl.limit.bound.rigid_bound`, back-EMF, current limit and friction
    included) plus one period of the first flexible mode (free hub). That is how long the rigid
    bang-bang takes through a ZVD shaper on the first mode, which leaves that mode at rest and
    keeps the torque within its limit. On the presets the bound is 1.00-1.23 x the time-optimal
    slew ``hubbeam optimal --rig`` computes (``tests/test_rig_default_task.py``).

    Parameters
    ----------
    rig : Rig
    slew_angle : float, optional
        The slew's angle [rad], ``|slew_angle| >= 1e-6`` and its slew within the longest t_f (1e6 s);
        default :data:`DEFAULT_RIG_SLEW_RAD`.

    Returns
    -------
    task : Slew
    note : str
        One line for the report: where the task came from.

    Raises
    ------
    ParameterError
        An angle out of that range, named ``slew_angle``.
    """
    from controllers import DesignModel
    from controllers.scaling import first_mode
    from hubbeam_ctrl.limit.bound import rigid_bound
    from hubbeam_ctrl.study.tasks import MAX_DURATION, Slew, check_target

    angle = DEFAULT_RIG_SLEW_RAD if slew_angle is None else check_target("slew_angle", slew_angle, "rad",
                                                                           "a slew by 0 is no task")
    params = rig.plant_params
    bound = rigid_bound(params, abs(angle), rig)
    modes = min(params.n_transverse, 3)
    design = DesignModel.build(params.replace(n_transverse=modes), 0.0, rig.timing.dt or task_dt(params), modes)
    period = 2.0 * math.pi / first_mode(design)
    duration = DEFAULT_RIG_PACE * (bound + period)
    if not duration <= MAX_DURATION:
        raise ParameterError(f"slew_angle = {angle:g} rad takes the rig's default slew {duration:.4g} s "
                             f"({DEFAULT_RIG_PACE:g} x (rigid bound + first-mode period)), past the longest "
                             f"tf, {MAX_DURATION:g} s")
    note = (f"task: the rig's default slew, {angle:.4g} rad in {duration:.4g} s = {DEFAULT_RIG_PACE:g} x (rigid "
            f"bound {bound:.4g} s + first-mode period {period:.4g} s, an upper bound of the time-optimal slew); "
            "give --tf (or a Slew) for another, `hubbeam optimal --rig` for the time-optimal one")
    return Slew(angle, duration), note


def task_on_rig(rig, task, scenario):
    """The task a comparison runs on ``rig``: ``(task, scenario, notes)``.

    A registered ``slew`` with no duration (``scenario.t_f`` None) on a rig with any hardware is
    the rig's default slew (:func:`rig_default_slew`, by ``scenario.slew_angle`` if given); with a
    duration and no angle it turns the rig's default angle :data:`DEFAULT_RIG_SLEW_RAD` in that
    duration (not Eq. 44's ``tau_max t_f^2 / (2 pi J)``, which on a drive's torque is tens of
    radians: 39 rad for a 2.4 m link's 4 s); anything else, and any task on an ideal rig or the
    beam alone, is returned as it is.

    Parameters
    ----------
    rig : Rig or None
    task : str or Slew or SpinUp
    scenario : ScenarioChoice

    Returns
    -------
    task : str or Slew or SpinUp
    scenario : ScenarioChoice
        Without its ``slew_angle`` when the task became the rig's slew.
    notes : list of str
        The report's line saying where the task came from (empty when unchanged).
    """
    if rig is None or rig.is_ideal or task != "slew":
        return task, scenario, []
    if scenario.t_f is not None:
        if scenario.slew_angle is not None:
            return task, scenario, []
        return task, dataclasses.replace(scenario, slew_angle=DEFAULT_RIG_SLEW_RAD), [rig_angle_note(scenario.t_f)]
    slew, note = rig_default_slew(rig, scenario.slew_angle)
    return slew, dataclasses.replace(scenario, slew_angle=None), [note]


def rig_angle_note(t_f: float) -> str:
    """The report's line when a rig's slew is given a duration and no angle (:func:`task_on_rig`).

    Parameters
    ----------
    t_f : float
        The given duration [s].

    Returns
    -------
    str
    """
    return (f"task: the rig's default angle, {DEFAULT_RIG_SLEW_RAD:.4g} rad, in the given tf = {t_f:.4g} s "
            "(give --slew-angle for another; Eq. 44's angle from tf is the beam alone's task)")


#: A slew planned on the linear design model that bends the tip past this share of L is noted: the
#: geometric stiffening the linear model leaves out grows with the square of the deflection (about
#: 1 % on the frequencies at 0.1 L), so the plan's rest at t_f is no longer the nonlinear beam's.
LINEAR_PLAN_TIP_SHARE = 0.1


def linear_plan_tip_share(reference, length: float) -> float | None:
    """The largest tip deflection of a slew planned on the linear design model, as a share of L
    (None for a reference that is not such a plan).

    Parameters
    ----------
    reference : controllers.Reference
        The tracked reference.
    length : float
        The beam's length L [m].

    Returns
    -------
    float or None
        ``max |v_tip| / L`` of the plan's modal coordinates [-].
    """
    import numpy as np

    from hubbeam_ctrl.plant.basis import transverse_shapes
    elastic = getattr(reference, "elastic", None)
    if not getattr(reference, "planned_on_design", False) or elastic is None or np.ndim(elastic) != 2:
        return None
    m = np.shape(elastic)[1] // 2
    tip = np.asarray(elastic)[:, :m] @ np.asarray(transverse_shapes(np.array([length]), m, length)).reshape(-1)
    return float(np.max(np.abs(tip))) / length


def linear_plan_note(reference, length: float) -> list:
    """The report's line when the tracked slew, planned on the linear design model, bends the tip by
    more than :data:`LINEAR_PLAN_TIP_SHARE` of L (empty otherwise, or for a reference that is not such
    a plan).

    Measured on ``servo_link`` at 1.1 T* (the smoothest plan bent it by 47 % of L; the plan now keeps
    30 %, :data:`controllers.planning.DEFLECTION_LIMIT`): the NMPC tracking the 47 % plan settled
    3.55 first-mode periods after t_f with 0.33 % of L left; tracking the minimum-vibration slew of the
    nonlinear model (``reference="optimal"``), 0.35 periods and 0.0077 % (docs/limit.md).

    Parameters
    ----------
    reference : controllers.Reference
        The tracked reference.
    length : float
        The beam's length L [m].

    Returns
    -------
    list of str
    """
    share = linear_plan_tip_share(reference, length)
    if share is None or share <= LINEAR_PLAN_TIP_SHARE:
        return []
    return [f"the slew planned on the linear design model bends the tip by {100 * share:.0f} % of L (more than "
            f"{100 * LINEAR_PLAN_TIP_SHARE:.0f} %): its rest at t_f is not the nonlinear beam's; the plan on the "
            "nonlinear model (reference='optimal', --reference optimal) tracks better near the limit"]
