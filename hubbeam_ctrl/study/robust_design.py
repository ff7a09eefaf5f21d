"""Designs that pass the robust certificate: a search over the design's own choices with the
worst-case spectral radius over the uncertainty set as the objective.

A controller designed for the nominal rig can lose stability somewhere in the set (Table 1's
LQG at 0.5 kg: mode 6, which its filter models at the nominal payload's frequency). The
choices that decide that are few and physical:

``design_at``
    The nominal rig, the points a quarter, half and three quarters along the set's
    diagonal (from every range's low end to its high end), the nominal design's worst plant.
``structure``
    ``plant``: the gain (and MPC's plan, LQG's filter) on the plant's modes (the default);
    ``design``: the gain on the design modes only; ``range``: that gain and a filter on the
    modes below Nyquist and the first above, trusting its model of the residual modes no
    more than the sensors (residual noise 1).
``plan_at``
    A planned slew's reference and feedforward planned on the nominal rig or at the middle of
    the set (a payload other than the plan's shifts the rigid angle the feedforward reaches,
    in proportion to the inertia: planning at the middle halves the worst shift).
``model_error``
    LQG: the multi-model filter over the set's payloads (shares 0.003, 0.03).
``weighting``, ``vibration_weight``
    The weights as given or the deflection rates only; the weights on the tip and modal
    deflection rates scaled by 1, 4 or 1/4.
``tracking_weight``
    The weight on the hub-angle error scaled by 1, 10 or 100: how fast the feedback corrects
    the angle a wrong feedforward leaves (a payload other than the plan's).
``error_decay``
    The filter's prescribed decay: the default or the plain Kalman filter (0).
``roll_off``
    PD: a first-order low-pass on its feedback torque with its corner at 2, 1 or 1/2 times
    the design model's first bending frequency (``PDSettings.roll_off_hz``), or none.

:func:`design_for_set` measures every pair of ``design_at`` and ``structure`` (their effects
combine: on Table 1's LQG over 0-0.5 kg neither the design-mode gain, the Nyquist filter nor
the residual noise alone helps, the three together certify it), then changes one group of
the other knobs at a time from the best pair (coordinate descent over :data:`GROUPS`,
:data:`PASSES` passes). A candidate is ranked first by the robust certificate
(:func:`~hubbeam_ctrl.study.worst_case.certify_set`, the loop as it runs): certified ones
before the others, which are ranked by their worst radius; among the certified, by the
caller's score (the study passes the worst nonlinear residual over the set's corners and
centre, :func:`~hubbeam_ctrl.study.robust_check.residual_score`), else by the radius.
Every candidate is kept with its radius and score, so the report shows the measured
alternatives; nothing is called robust that the certificate does not accept.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np

from controllers import make_controller
from controllers.design_model import DesignModel
from controllers.robust import multi_model_filter, rates_only
from hubbeam_ctrl.core.errors import HubbeamError
from hubbeam_ctrl.core.progress import progress_bar
from hubbeam_ctrl.plant.rig import Rig
from hubbeam_ctrl.plant.uncertainty import Uncertainty
from hubbeam_ctrl.study.range_design import _nyquist_modes
from hubbeam_ctrl.study.rig_loop import on_rig, rig_closed_loop, rig_design, task_noise
from hubbeam_ctrl.study.worst_case import RADIUS_MARGIN, WorstCase, certify_set

__all__ = ["KNOBS", "PAIRED", "GROUPS", "PASSES", "SetDesign", "design_for_set", "innermost"]

#: The knobs and their values, in search order (the first value is the nominal design's).
KNOBS = {
    "design_at": ("nominal", 0.25, 0.5, 0.75, "worst"),
    "structure": ("plant", "design", "range"),
    "plan_at": ("nominal", 0.5),
    "model_error": (None, 0.003, 0.03),
    "weighting": ("full", "rates"),
    "vibration_weight": (1.0, 4.0, 0.25),
    "tracking_weight": (1.0, 10.0, 100.0),
    "error_decay": ("default", 0.0),
    "roll_off": ("none", 2.0, 1.0, 0.5),
}
#: Knobs measured in every combination before the coordinate descent over the others.
PAIRED = ("design_at", "structure")
#: The coordinate descent's steps: each group's knobs change together (every combination).
GROUPS = (("plan_at",), ("tracking_weight",), ("model_error",), ("weighting", "vibration_weight"), ("error_decay",),
          ("roll_off",))
#: Coordinate-descent passes over :data:`KNOBS`.
PASSES = 2


def innermost(controller):
    """The designed controller inside the rig's wrappers (observer, voltage command).

    Parameters
    ----------
    controller : Controller
        As it runs (``ObservedFeedback``, ``VoltageCommand`` keep theirs in ``inner``).

    Returns
    -------
    Controller
    """
    while hasattr(controller, "inner"):
        controller = controller.inner
    return controller


@dataclass(frozen=True)
class SetDesign:
    """A design chosen over an uncertainty set.

    Attributes
    ----------
    name : str
        The controller.
    controller : Controller
        As it runs on the rig.
    choice : dict
        Knob -> value (:data:`KNOBS`).
    certificate : WorstCase
        Its robust certificate (with margins).
    nominal_radius : float
        The worst radius of the nominal design over the set [-].
    tried : tuple
        ``(label, worst radius, score)`` of every candidate measured (score None: not
        certified, or no score asked for).
    """

    name: str
    controller: object
    choice: dict
    certificate: WorstCase
    nominal_radius: float
    tried: tuple = field(default_factory=tuple)

    def label(self) -> str:
        """The knobs that differ from the nominal design (``"nominal design"`` if none)."""
        return _label(self.choice)


def _label(choice: dict) -> str:
    changed = [f"{k}={v}" for k, v in choice.items() if v != KNOBS[k][0]]
    return ", ".join(changed) if changed else "nominal design"


class _Builder:
    """Candidate controllers as the comparison built its nominal one (same task, rig, noise)."""

    def __init__(self, comparison, name: str, rig: Rig, uncertainty: Uncertainty, worst_values: dict):
        self.cmp, self.name, self.rig, self.set = comparison, name, rig, uncertainty
        self.sc, self.modes = comparison.scenario, comparison.plant.modes
        base = innermost(comparison.controllers[name])
        self.settings, self.design = base.settings, base.design
        self.on_a_rig = comparison.rig is not None and not rig.is_ideal
        self.hardware = rig_closed_loop(rig, self.sc.closed_loop_settings())[1]
        self.noise = task_noise(self.sc, rig)
        self.points = {"nominal": None, "worst": dict(worst_values)}
        for f in KNOBS["design_at"]:
            if isinstance(f, float):
                self.points[f] = {r.name: r.lo + f * (r.hi - r.lo) for r in uncertainty.ranges}
        self.is_lqg = hasattr(self.settings, "robust")

    def values(self, knob: str) -> tuple:
        """The values of ``knob`` that apply to this controller (the first: the nominal design's)."""
        st, values = self.settings, KNOBS[knob]
        if knob == "plan_at":
            planned = self.sc.name == "slew" and getattr(self.sc.reference, "planned_on_design", False)
            return values if planned else values[:1]
        if knob == "model_error":
            return values if self.is_lqg and "m_t" in self.set.names else values[:1]
        if knob == "structure":
            if not (hasattr(st, "residual_control") and st.residual_control):
                return values[:1]
            return values if (self.is_lqg or self.on_a_rig) else values[:2]
        if knob == "error_decay":
            return values if (self.is_lqg or self.on_a_rig) else values[:1]
        if knob == "roll_off":
            return values if hasattr(st, "roll_off_hz") else values[:1]
        if knob in ("weighting", "vibration_weight", "tracking_weight"):
            return values if hasattr(st, "weights") else values[:1]
        return values

    def design_model(self, at: str) -> DesignModel:
        values = self.points[at]
        if values is None:
            return self.design
        point = self.set.apply(self.rig, values)
        d = DesignModel.build(point.plant_params, self.sc.design_spin, self.sc.dt, self.design.n_modes)
        return rig_design(d, point) if self.on_a_rig else d

    def reference(self, choice: dict):
        """The reference of a candidate: the task's, or the same task planned at the design point."""
        sc, at = self.sc, choice["plan_at"]
        if at == "nominal":
            return sc.reference
        from hubbeam_ctrl.study.scenarios import make_scenario
        point = self.set.apply(self.rig, self.points[at])
        return make_scenario(sc.name, plant=sc.plant, params=point.plant_params, tau_max=sc.tau_max, t_f=sc.t_f,
                             t_end=sc.t_end, dt=sc.dt, slew_angle=sc.target).reference

    def build(self, choice: dict):
        d = self.design_model(choice["design_at"])
        st, noise = self.settings, self.noise
        if choice["roll_off"] != "none":
            from controllers.scaling import first_mode
            st = st.replace(roll_off_hz=float(choice["roll_off"]) * first_mode(d) / (2 * np.pi))
        if choice["weighting"] == "rates":
            st = st.replace(weights=rates_only(st.weights))
        if choice["tracking_weight"] != 1.0 and st.weights.state_matrix is None:
            st = st.replace(weights=st.weights.replace(angle=float(choice["tracking_weight"]) * st.weights.angle))
        if choice["vibration_weight"] != 1.0:
            w, k = st.weights, float(choice["vibration_weight"])
            if w.state_matrix is None:
                rate = w.modal if w.modal_rate is None else w.modal_rate
                st = st.replace(weights=w.replace(tip_rate=k * w.tip_rate, modal_rate=k * rate))
        if choice["structure"] in ("design", "range"):
            st = st.replace(residual_control=False)
        if self.is_lqg:
            if choice["structure"] == "range":
                st = st.replace(residual_modes=min(self.modes, _nyquist_modes(d)), residual_noise=1.0)
            if choice["error_decay"] != "default":
                st = st.replace(error_decay=float(choice["error_decay"]))
            if choice["model_error"] is not None:
                r = self.set["m_t"]
                st = multi_model_filter(d, st, [r.lo, r.hi], self.sc.reference, float(choice["model_error"]))
        else:
            if choice["structure"] == "range":
                noise = noise.replace(residual_noise=1.0)
            if choice["error_decay"] != "default":
                noise = noise.replace(error_decay=float(choice["error_decay"]))
        ctrl = make_controller(self.name, d, st, self.reference(choice))
        return on_rig(ctrl, self.rig, noise, self.hardware) if self.on_a_rig else ctrl


def design_for_set(comparison, name: str, rig: Rig, uncertainty: Uncertainty | None = None, *,
                   spins=(), score=None, progress: bool = False) -> SetDesign:
    """Search the design choices of ``name`` for the smallest worst-case radius over the set.

    Parameters
    ----------
    comparison : Comparison
        A comparison that ran ``name`` on ``rig`` (its task, evaluation plant and nominal design).
    name : str
        A controller with a linear law (``lqr``, ``lqg``, ``mpc``...).
    rig : Rig
        The nominal rig, without its uncertainty (``Rig(beam=params)`` for the beam alone).
    uncertainty : Uncertainty, optional
        The set (default the comparison's rig's).
    spins : sequence of float
        Spin rates [rad/s] the certificate linearises at besides the design spin.
    score : callable, optional
        ``score(ctrl) -> float``, lower is better (e.g. the worst nonlinear residual over
        points of the set relative to each point's open loop,
        :func:`~hubbeam_ctrl.study.robust_check.residual_score`): among the certified
        candidates the best score wins; a candidate that is not certified is ranked by its
        radius after every certified one. Default: the radius alone. A score with
        ``takes_bound`` (:class:`~hubbeam_ctrl.study.robust_check.ResidualScore`) is called
        with ``bound=`` the best score so far and may stop its runs there: the same choice,
        fewer runs.
    progress : bool
        A progress bar over the candidates (stderr, on a terminal).

    Returns
    -------
    SetDesign
    """
    uncertainty = uncertainty if uncertainty is not None else comparison.rig.uncertainty
    rig = rig.replace(uncertainty=Uncertainty())
    modes = comparison.plant.modes

    def measure(ctrl, margins=False) -> WorstCase:
        return certify_set(ctrl, rig, uncertainty, plant_modes=modes, spins=spins, name=name,
                           local_starts=1, margins=margins)

    nominal = comparison.robust.get(name) or measure(comparison.controllers[name])
    builder = _Builder(comparison, name, rig, uncertainty, nominal.worst.values)
    values = {k: builder.values(k) for k in KNOBS}
    current = {k: v[0] for k, v in KNOBS.items()}
    def objective(ctrl, radius: float) -> tuple:
        if radius > 1.0 - RADIUS_MARGIN or score is None:
            return (1 if radius > 1.0 - RADIUS_MARGIN else 0, radius)
        if getattr(score, "takes_bound", False) and best[0][0] == 0:   # runs past the best stop
            return (0, float(score(ctrl, bound=best[0][1] - 1e-9)))
        return (0, float(score(ctrl)))

    best = ((1, math.inf), comparison.controllers[name])
    first = objective(comparison.controllers[name], nominal.worst.radius)
    best = (first, comparison.controllers[name])
    tried = [(_label(current), nominal.worst.radius, first[1] if first[0] == 0 and score else None)]
    seen = {_label(current)}
    pairs = [dict(zip(PAIRED, combo)) for combo in itertools.product(*(values[k] for k in PAIRED))]
    groups = [g for g in GROUPS if any(len(values[k]) > 1 for k in g)]
    combos = {g: [dict(zip(g, c)) for c in itertools.product(*(values[k] for k in g))] for g in groups}
    total = len(pairs) - 1 + PASSES * sum(len(c) - 1 for c in combos.values())

    def attempt(choice, bar):
        nonlocal best, current
        label = _label(choice)
        if label in seen:
            return False
        seen.add(label)
        bar.update(1)
        try:
            ctrl = builder.build(choice)
            radius = measure(ctrl).worst.radius
            value = objective(ctrl, radius)
        except (HubbeamError, np.linalg.LinAlgError, ValueError) as exc:
            tried.append((label + f" (failed: {str(exc)[:80]})", float("inf"), None))
            return False
        tried.append((label, radius, value[1] if value[0] == 0 and score else None))
        if value < (best[0][0], best[0][1] - 1e-9):
            best, current = (value, ctrl), choice
            return True
        return False

    with progress_bar(total, f"robust {name}", enabled=progress) as bar:
        start = dict(current)
        for pair in pairs:
            attempt({**start, **pair}, bar)
        for _ in range(PASSES):
            changed = False
            for g in groups:
                for combo in combos[g]:
                    if any(current[k] != v for k, v in combo.items()):
                        changed |= attempt({**current, **combo}, bar)
            if not changed:
                break
        bar.update(max(0, bar.total - bar.n))
    return SetDesign(name, best[1], dict(current), measure(best[1], margins=True), nominal.worst.radius,
                     tuple(tried))
