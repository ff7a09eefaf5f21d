"""The reference every controller of a comparison tracks: the scenario's, or a slew's plan on the
nonlinear model when asked for (``reference="optimal"``) or when the linear plan cannot stay in the
models' range."""

from __future__ import annotations

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.study.yardstick import linear_plan_note, linear_plan_tip_share

__all__ = ["tracked_reference"]


def tracked_reference(sc, kind: str, rig) -> tuple:
    """``(reference, notes)`` the controllers of a comparison track.

    Parameters
    ----------
    sc : Scenario
        The comparison's scenario.
    kind : {"task", "rigid", "planned", "optimal"}
        ``DesignChoice.reference``.
    rig : Rig or None
        The rig (the nonlinear plan carries its drive).

    Returns
    -------
    tuple
        ``(controllers.Reference, list of str)``: the reference, and the report's notes on it (the
        switch to the nonlinear plan, or a linear plan that bends the tip past
        :data:`~hubbeam_ctrl.study.yardstick.LINEAR_PLAN_TIP_SHARE` of L).
    """
    ref, notes = _within_range(sc, _reference(sc, kind, rig), kind, rig)
    return ref, notes or linear_plan_note(ref, sc.params.L)


def _within_range(sc, ref, kind: str, rig) -> tuple:
    """``(reference, notes)``: the task's slew planned on the linear design model, or, when that plan
    cannot keep the tip within the models' range (``controllers.planning.DEFLECTION_LIMIT`` of L: a
    slew near the time-optimal one), the minimum-vibration slew of the nonlinear model (as
    ``reference="optimal"``), said in a note. Measured on ``servo_payload`` at 1.0 and 1.05 T*:
    with the linear plan every run left FOAM's range and stopped ("diverged", 0.58-0.97 L); with
    the nonlinear plan LQR and MPC settle."""
    from controllers.planning import DEFLECTION_LIMIT
    share = linear_plan_tip_share(ref, sc.params.L) if kind == "task" and sc.name == "slew" else None
    if share is None or share <= DEFLECTION_LIMIT * (1 + 1e-6):
        return ref, []
    text = (f"the slew planned on the linear design model bends the tip by {100 * share:.0f} % of L, past the "
            f"models' range ({100 * DEFLECTION_LIMIT:.0f} % of L)")
    try:
        optimal = _reference(sc, "optimal", rig)
    except ParameterError as exc:
        return ref, [f"{text}; the nonlinear plan failed too ({str(exc).splitlines()[0]}): the runs may leave "
                     "the range"]
    return optimal, [f"{text}: every controller tracks the minimum-vibration slew of the nonlinear model instead "
                     "(reference='optimal')"]


def _reference(sc, kind: str, rig):
    """The tracked reference: the scenario's, or the minimum-vibration slew of the beam in ``t_f``."""
    if kind != "optimal":
        return sc.reference
    if sc.name != "slew":
        raise ParameterError(f"reference = 'optimal' applies to a slew, not a {sc.name}")
    from controllers import optimal_reference
    from hubbeam_ctrl.limit import min_vibration_slew
    opt = min_vibration_slew(rig if rig is not None else sc.params, sc.target, sc.t_f, name="t_f")
    return optimal_reference(opt, sc.dt, sc.t_end)
