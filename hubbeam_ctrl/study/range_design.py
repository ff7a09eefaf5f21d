"""Designs for a payload range: the nominal design verified and retuned over the range.

:func:`range_designs` gives LQR, LQG and MPC the design chosen for a payload range
(:func:`controllers.robust.design_for_range`), measured on the nonlinear evaluation plant.
Both :func:`hubbeam_ctrl.study.compare.compare` (``payload_range=``) and
:func:`hubbeam_ctrl.study.payload.payload_comparison` use it; it imports neither, so the two
do not import each other.
"""

from __future__ import annotations

import math

import numpy as np

from controllers import CONTROLLERS, make_controller
from controllers.msmpc import scenario_range_design
from controllers.robust import check_payload_range, design_for_range

__all__ = ["ROBUST_CONTROLLERS", "SCENARIO_CONTROLLERS", "WEIGHTED_CONTROLLERS", "range_designs",
           "set_scenario_designs"]

#: Controllers designed for a payload range (the others run their nominal design).
ROBUST_CONTROLLERS = ("lqr", "lqg", "mpc")
#: Controllers whose design for a payload range is a scenario per payload of the grid
#: (:func:`controllers.msmpc.scenario_range_design`), not a search.
SCENARIO_CONTROLLERS = ("msmpc",)
#: Controllers whose design for a payload range takes the grid's payloads into its weights
#: (:mod:`controllers.hinf`: the robustness weight from the plants' spread), no search.
WEIGHTED_CONTROLLERS = ("hinf",)


#: The range designs' gain and filter: the gain on the design modes, the LQG's filter on
#: the modes below the Nyquist frequency plus one with full process noise on them (the
#: filter the multi-model design was measured with, 0.8-1.1 % of the open loop over 0-0.5 kg).
_RANGE_FILTER = {"residual_control": False, "residual_noise": 1.0}


def _nyquist_modes(design) -> int:
    """Every bending mode below the Nyquist frequency and the first above it (at least the design's)."""
    from hubbeam_ctrl.plant.modal import converged_bending_hz
    f = converged_bending_hz(design.params, design.spin)
    return int(min(20, max(design.n_modes, int((f < 0.5 / design.dt).sum()) + 1)))


def _nonlinear_score(sc, sim, design_modes: int, plant_modes: int | None):
    """``score(ctrl, payload)``: residual on the evaluation plant with that payload over the open loop's."""
    from controllers import OpenLoopSettings
    from hubbeam_ctrl.sim.closedloop import simulate_closed_loop
    from hubbeam_ctrl.sim.evaluation import evaluation_plant
    from hubbeam_ctrl.study.metrics import GROWTH_LIMIT, SATURATION_LIMIT, closed_loop_metrics
    ref, open_loop = sc.reference, {}

    def residual(ctrl, mass):
        model = evaluation_plant(sc.plant, sc.params, sc.dt, design_modes, sc.design_spin,
                                 plant_params=sc.params.replace(m_t=mass), plant_modes=plant_modes)
        res = simulate_closed_loop(model, ctrl, sc.t_end, settings=sim, reference=(ref.theta_at, ref.theta_dot_at))
        m = closed_loop_metrics(res, sc.t_f, tau_max=sc.tau_max, **sc.bands)
        # ranks candidates by their residual: out are runs that stopped, whose tip grows or whose
        # torque saturates; a slowly growing ripple is the final verdict's (with its certificate)
        gross = m["residual_growth"] > GROWTH_LIMIT and m["residual_tip_max_m"] > sc.bands["settle_tip"]
        saturated = m["torque_saturated_fraction"] > SATURATION_LIMIT
        return m["residual_tip_max_m"] if m["completed"] and not gross and not saturated else math.inf

    def score(ctrl, mass):
        if mass not in open_loop:
            ol = make_controller("openloop", ctrl.design, OpenLoopSettings.for_scenario(sc), ref)
            open_loop[mass] = residual(ol, mass)
        return residual(ctrl, mass) / open_loop[mass]
    return score


def range_designs(names, scenario, design, payload_range, settings: dict | None = None, *,
                  horizon: int = 50, solver: str = "daqp", sim=None, plant_modes: int | None = None,
                  progress: bool = False) -> dict:
    """The designs of LQR, LQG and MPC (those in ``names``) for a payload range.

    Candidates (:func:`controllers.robust.design_for_range`) are measured on the nonlinear
    plant of the scenario at ``m_min``, the nominal payload and ``m_max`` (after the linear
    loops at those payloads have been checked for stability).

    Parameters
    ----------
    names : sequence of str
        Controllers of the comparison.
    scenario : Scenario
        The task on the nominal beam (``scenario.params.m_t`` is the nominal payload).
    design : DesignModel
        The nominal design model.
    payload_range : tuple of float
        ``(m_min, m_max)`` [kg].
    settings : dict, optional
        Controller name -> settings replacing the scenario's defaults.
    horizon, solver
        MPC options (as :func:`~hubbeam_ctrl.study.compare.compare`).
    sim : ClosedLoopSettings, optional
        Settings of the measuring runs (default: the scenario's sensors).
    plant_modes : int, optional
        Transverse modes of the evaluation plants (default: their rule,
        :func:`hubbeam_ctrl.sim.evaluation.evaluation_plant`).
    progress : bool
        A progress bar per controller over its candidates (stderr, only on a terminal).

    Returns
    -------
    dict
        Controller name -> :class:`controllers.robust.RangeDesign`.
    """
    payload_range = check_payload_range(payload_range, scenario.params.m_t)
    settings = settings or {}
    sc = scenario
    if sc.baseline_tau_m is not None:
        w = 2 * math.pi / sc.t_f
        baseline = lambda t: np.where(t <= sc.t_f, sc.baseline_tau_m * np.sin(w * t), 0.0)
    else:
        baseline = lambda t: sc.reference.at(t)[2]
    if sim is None:
        sim = sc.closed_loop_settings()
    score = _nonlinear_score(sc, sim, design.n_modes, plant_modes)
    out = {}
    for name in names:
        if name not in ROBUST_CONTROLLERS + SCENARIO_CONTROLLERS + WEIGHTED_CONTROLLERS:
            continue
        st = settings.get(name) or CONTROLLERS[name].settings.for_scenario(sc, horizon=horizon, solver=solver)
        if name in WEIGHTED_CONTROLLERS:     # the grid's plants set the weights
            from controllers.robust import RangeDesign, payload_grid
            grid = payload_grid(payload_range, sc.params.m_t)
            st = st.replace(payloads=grid)
            out[name] = RangeDesign(design=design, settings=st, design_mass=design.params.m_t,
                                    choice="weights from payloads " + ", ".join(f"{m:g}" for m in grid) + " kg",
                                    score=math.nan, scores={}, grid=grid)
            continue
        if name in SCENARIO_CONTROLLERS:     # the scenario tree over the range is the design
            if plant_modes is not None and st.residual_modes is None:
                st = st.replace(residual_modes=plant_modes)
            out[name] = scenario_range_design(design, st, sc.reference, payload_range, t_f=sc.t_f,
                                              t_end=sc.t_end, delay=sc.bands["residual_delay"], baseline=baseline,
                                              score=score)
            continue
        # a gain on the residual modes is model-based: a tip mass moves those modes and the
        # gain then pumps them (LQR designed at 0 kg: 12.9 % of the open loop at 0.5 kg), so a
        # design for a payload range keeps its gain on the design modes (issue 27 note)
        st = st.replace(**{k: v for k, v in _RANGE_FILTER.items() if hasattr(st, k)},
                        residual_modes=_nyquist_modes(design))
        out[name] = design_for_range(name, make_controller, design, st, sc.reference, payload_range,
                                     t_f=sc.t_f, t_end=sc.t_end, delay=sc.bands["residual_delay"],
                                     baseline=baseline, score=score, progress=progress)
    return out


def set_scenario_designs(names, scenario, design, uncertainty, settings: dict, *, sim=None,
                         plant_modes: int | None = None) -> dict:
    """The scenario-tree (and range-weighted) designs over an uncertainty set's payload range.

    A multi-stage MPC on a rig whose ``[uncertainty]`` table holds ``m_t`` is the tree over that
    range (its ends and the nominal payload), designed as ``compare --payload-range LO,HI``
    designs it (:func:`range_designs`): the certificate over the set then judges the tree, not
    the plain MPC that a tree of the nominal payload alone is; the H-infinity design
    (:data:`WEIGHTED_CONTROLLERS`) takes the range's plants into its robustness weight. Controllers
    whose settings give their own ``payloads`` keep them.

    Parameters
    ----------
    names : sequence of str
        Controllers of the comparison.
    scenario : Scenario
        The task on the nominal beam.
    design : DesignModel
        The nominal design model (on the rig).
    uncertainty : Uncertainty
        The set; without ``m_t`` (or a zero-width one) nothing is designed.
    settings : dict
        Controller name -> its settings as the comparison chose them (on the rig).
    sim, plant_modes
        As :func:`range_designs`.

    Returns
    -------
    dict
        Controller name -> :class:`controllers.robust.RangeDesign` (empty when nothing applies).

    Raises
    ------
    ParameterError
        One line naming ``uncertainty.m_t`` when the range does not hold the nominal payload.
    """
    from hubbeam_ctrl.core.errors import ParameterError
    if "m_t" not in uncertainty.names:
        return {}
    r = uncertainty["m_t"]
    tree = [n for n in names if n in SCENARIO_CONTROLLERS + WEIGHTED_CONTROLLERS
            and getattr(settings[n], "payloads", None) is None]
    if not tree or r.hi <= r.lo:
        return {}
    nominal = scenario.params.m_t
    if not r.lo <= nominal <= r.hi:
        raise ParameterError(f"uncertainty.m_t = [{r.lo:g}, {r.hi:g}] kg must hold the nominal tip mass "
                             f"m_t = {nominal:g} kg for the scenario tree of {tree[0]}")
    return range_designs(tree, scenario, design, (r.lo, r.hi), {n: settings[n] for n in tree}, sim=sim,
                         plant_modes=plant_modes)
