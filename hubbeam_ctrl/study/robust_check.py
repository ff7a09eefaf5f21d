"""The robust certificate checked: the controller and the open loop run on the nonlinear plant
at chosen points of the uncertainty set (the worst plant the certificate found, the corners).

The controller is the one the comparison ran (designed on the nominal rig, as it runs); the
plant is the evaluation plant of the comparison (same model, modes and sample time) with the
physical parameters and hardware of the rig at that point
(:meth:`~hubbeam_ctrl.plant.uncertainty.Uncertainty.apply`). Each point gets its own open-loop
run, so the residual is a share of *that* plant's open loop, as the targets ask.
"""

from __future__ import annotations

import contextlib
import io
import math

from controllers import CONTROLLERS, make_controller
from controllers.design_model import DesignModel
from hubbeam_ctrl.plant.rig import Rig
from hubbeam_ctrl.plant.uncertainty import Uncertainty
from hubbeam_ctrl.sim.closedloop import simulate_closed_loop
from hubbeam_ctrl.sim.evaluation import evaluation_plant
from hubbeam_ctrl.study.judge import judge
from hubbeam_ctrl.study.rig_loop import on_rig, rig_closed_loop, rig_design, task_noise
from hubbeam_ctrl.study.yardstick import task_limit

__all__ = ["run_at", "CHECK_KEYS", "check_points", "residual_score", "ResidualScore", "TARGET_RESIDUAL_PCT"]

#: The residual target of a design over the set [% of each plant's open loop] (issue 39).
TARGET_RESIDUAL_PCT = 2.0
#: Metrics a check keeps for each point.
CHECK_KEYS = ("verdict", "settling_time_s", "residual_tip_max_m", "residual_pct_of_openloop", "peak_torque_nm",
              "peak_command", "command_unit", "within_drive_limits", "loop_spectral_radius", "completed",
              "final_angle_error_rad")


def run_at(comparison, controller, rig: Rig, values: dict, uncertainty: Uncertainty,
           openloop: dict | None = None) -> dict:
    """A controller and the open loop on the plant at ``values``.

    Parameters
    ----------
    comparison : Comparison
        The comparison whose task and evaluation plant the runs take
        (:func:`~hubbeam_ctrl.study.compare.compare`).
    controller : str or Controller
        A controller the comparison ran (its name), or one built for the same task and rig
        (e.g. :func:`~hubbeam_ctrl.study.robust_design.design_for_set`'s).
    rig : Rig
        The nominal rig of the comparison (``Rig(beam=params)`` for the beam alone).
    values : dict
        Uncertain parameter -> value: the plant's point of the set.
    uncertainty : Uncertainty
        The set (applies ``values`` to ``rig``).
    openloop : dict, optional
        A cache of the open loop's metrics by point (filled here): the open loop does not
        depend on the controller, so a search over candidates runs it once per point.

    Returns
    -------
    dict
        The :data:`CHECK_KEYS` of the controller's run, ``openloop_residual_tip_max_m`` and the
        point's ``values``.
    """
    sc, ev = comparison.scenario, comparison.plant
    ctrl = comparison.controllers[controller] if isinstance(controller, str) else controller
    name = ctrl.name
    point = uncertainty.apply(rig, values)
    plant = evaluation_plant(sc.plant, sc.params, sc.dt, int(ctrl.n_modes), sc.design_spin,
                             plant_params=point.plant_params, plant_modes=ev.modes)
    sim, hardware = rig_closed_loop(point, sc.closed_loop_settings())
    ref = sc.reference
    own = ctrl
    while hasattr(own, "inner"):
        own = own.inner
    own_ref = getattr(own, "reference", None) or ref      # a candidate may plan its own reference
    spec = CONTROLLERS["openloop"]
    design = DesignModel.build(sc.params, sc.design_spin, sc.dt, int(ctrl.n_modes))
    on_a_rig = comparison.rig is not None
    if on_a_rig:
        design = rig_design(design, rig)
    ol = make_controller("openloop", design, spec.settings.for_scenario(sc), ref)
    if on_a_rig:
        ol = on_rig(ol, point, task_noise(sc, point), hardware)
    else:
        hardware = None
    limit = task_limit(sc, "rigid", point if on_a_rig else None)
    out = {"values": dict(values)}
    runs = {}
    key = tuple(sorted(values.items()))
    if openloop is not None and key in openloop:
        runs["openloop"] = openloop[key]
    for label, c, r in (("openloop", ol, ref), (name, ctrl, own_ref)):
        if label in runs:
            continue
        # CasADi writes a failed implicit step's inputs to Python's stderr: the run's message says it
        with contextlib.redirect_stderr(io.StringIO()):
            res = simulate_closed_loop(plant, c, sc.t_end, settings=sim, reference=(r.theta_at, r.theta_dot_at),
                                       hardware=hardware)
        runs[label], _ = judge(res, c, sc, plant.params, label, limit=limit)
    if openloop is not None:
        openloop[key] = runs["openloop"]
    base = runs["openloop"]["residual_tip_max_m"]
    m = runs[name]
    m["residual_pct_of_openloop"] = (100.0 * m["residual_tip_max_m"] / base
                                     if base and math.isfinite(base) else float("nan"))
    out.update({k: m.get(k) for k in CHECK_KEYS})
    out["openloop_residual_tip_max_m"] = base
    return out


def check_points(uncertainty: Uncertainty, worst: dict | None = None) -> list:
    """``(kind, values)`` of the points a check runs at: the worst plant (if given), every corner
    of the varying ranges and the centre.

    Parameters
    ----------
    uncertainty : Uncertainty
    worst : dict, optional
        The worst plant the certificate found.

    Returns
    -------
    list of tuple
    """
    import itertools
    vary = uncertainty.varying
    out = [("worst", dict(worst))] if worst is not None else []
    out += [("corner", uncertainty.values_at(c)) for c in itertools.product((0.0, 1.0), repeat=len(vary))]
    if vary:
        out.append(("centre", uncertainty.values_at([0.5] * len(vary))))
    return out


class ResidualScore:
    """``score(ctrl, bound=inf)``: how far the worst run over the set's corners and centre is
    from the targets, 1 on the boundary: the largest of its residual over that plant's open
    loop's relative to ``target_pct`` and its final angle error relative to the task's settling
    band (inf for a run that is unstable or fails). ``residual_score`` is this class.

    The score is a largest value over points, so a candidate stops being run as soon as one
    point reaches ``bound`` (the best score so far: it cannot win); the point that gave the
    last largest value runs first. A stopped candidate's score is then a lower bound, at
    least ``bound``.

    Parameters
    ----------
    comparison : Comparison
        Its task and evaluation plant.
    rig : Rig
        The nominal rig, without its uncertainty.
    uncertainty : Uncertainty
        The set whose corners and centre the runs take.
    target_pct : float
        The residual target [% of the open loop's].
    """

    #: :func:`~hubbeam_ctrl.study.robust_design.design_for_set` passes the best score so far.
    takes_bound = True

    def __init__(self, comparison, rig: Rig, uncertainty: Uncertainty, target_pct: float = TARGET_RESIDUAL_PCT):
        self.comparison, self.rig, self.uncertainty, self.target_pct = comparison, rig, uncertainty, target_pct
        self.points = [values for _, values in check_points(uncertainty)]
        self.band = float(comparison.scenario.bands["settle_angle"])
        self.openloop = {}
        self.runs = 0

    def __call__(self, ctrl, bound: float = math.inf) -> float:
        """The score [-] of ``ctrl``: inf for a run that is unstable or fails; at least ``bound``
        when the runs stopped there."""
        worst, worst_at = 0.0, 0
        for i, values in enumerate(self.points):
            m = run_at(self.comparison, ctrl, self.rig, values, self.uncertainty, self.openloop)
            self.runs += 1
            pct, err = m["residual_pct_of_openloop"], m["final_angle_error_rad"]
            if m["verdict"] in ("unstable", "failed") or pct is None or not math.isfinite(pct) \
                    or err is None or not math.isfinite(err):
                value = math.inf
            else:
                value = max(float(pct) / self.target_pct, abs(float(err)) / self.band)
            if value > worst:
                worst, worst_at = value, i
            if worst >= bound:
                break
        if worst_at:                   # the hardest point first next time
            self.points.insert(0, self.points.pop(worst_at))
        return worst


#: ``residual_score(comparison, rig, uncertainty, target_pct=TARGET_RESIDUAL_PCT)``: the score
#: :func:`~hubbeam_ctrl.study.robust_design.design_for_set` takes (:class:`ResidualScore`).
residual_score = ResidualScore
