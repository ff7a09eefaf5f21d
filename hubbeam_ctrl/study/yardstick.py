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

import math

from hubbeam_ctrl.core.errors import ParameterError

__all__ = ["LIMIT_KINDS", "rigid_limit", "task_limit", "yardstick_metrics"]

#: The yardsticks a comparison can use.
LIMIT_KINDS = ("rigid", "optimal")


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
        The rig whose drive bounds the time-optimal slew.

    Returns
    -------
    dict
    """
    if kind not in LIMIT_KINDS:
        raise ParameterError(f"limit must be one of {', '.join(LIMIT_KINDS)}, got {kind!r}")
    if kind == "rigid" or scenario.name != "slew":
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
