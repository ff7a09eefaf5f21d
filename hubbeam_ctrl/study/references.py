"""The reference every controller of a comparison tracks: the scenario's, or a slew's plan on the
nonlinear model when asked for (``reference="optimal"``) or when the linear plan cannot stay in the
models' range."""

from __future__ import annotations

from hubbeam_ctrl.core.errors import HubbeamError, ParameterError
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
    slew near the time-optimal one) or needs more than the rig's DC motor can give (its voltage limit
    against the back-EMF), the minimum-vibration slew of the nonlinear model on the rig (as
    ``reference="optimal"``), said in a note. Measured on ``servo_payload`` at 1.0 and 1.05 T*:
    with the linear plan every run left FOAM's range and stopped ("diverged", 0.58-0.97 L); with
    the nonlinear plan LQR and MPC settle."""
    from controllers.planning import DEFLECTION_LIMIT
    if kind != "task" or sc.name != "slew":
        return ref, []
    share, need = linear_plan_tip_share(ref, sc.params.L), _voltage_share(ref, rig)
    if share is not None and share > DEFLECTION_LIMIT * (1 + 1e-6):
        text = (f"the slew planned on the linear design model bends the tip by {100 * share:.0f} % of L, past the "
                f"models' range ({100 * DEFLECTION_LIMIT:.0f} % of L)")
    elif need is not None and need[0] > 1.0 + 1e-6:
        text = (f"the slew planned on the linear design model needs {need[0] * rig.drive.V_max:.3g} V of the "
                f"drive's {rig.drive.V_max:g} V (the back-EMF at its peak rate {need[1]:.3g} rad/s)")
    else:
        return ref, []
    try:
        optimal = _reference(sc, "optimal", rig)
    except HubbeamError as exc:       # refused, or its check on FOAM failed to integrate (a 4.9 m boom's plan)
        return ref, [f"{text}; the nonlinear plan failed too ({str(exc).splitlines()[0]}): the runs may leave "
                     "the range"]
    return optimal, [f"{text}: every controller tracks the minimum-vibration slew of the nonlinear model instead "
                     "(reference='optimal')"]


def _voltage_share(ref, rig) -> tuple | None:
    """``(largest |V| / V_max, peak hub rate [rad/s])`` the tracked plan needs from the rig's DC motor
    (the drive's static inverse with back-EMF, not clipped, for the plan's torque plus the sliding
    friction along it), or None on a torque drive or for a
    reference that is not planned on the design model. Found on a random rig (a 1 m steel link on a
    397:1 geared motor, no-load speed 1.21 rad/s at the hub): the smooth plan of the default slew
    peaked at 1.48 rad/s, every feedback design sat at 24 V for 0.8-0.9 s and lagged 0.05-0.07 rad
    at t_f; tracking the nonlinear plan on the rig they lag 5 mrad."""
    if rig is None or rig.drive.is_ideal or not getattr(ref, "planned_on_design", False):
        return None
    import numpy as np

    from hubbeam_ctrl.sim.hardware import Hardware, friction_torque
    hw = Hardware.from_rig(rig)
    rate = ref.theta_dot[:len(ref.torque)]
    # the drive gives the plan's torque and the friction's along it (found on a random rig: a 4.5 m steel link
    # on a 5000:1 motor, Coulomb friction 38 % of the stall torque; its plan needed 20 V of back-EMF and 9 V
    # against friction of 24 V, and every feedback design sat at 24 V for 20 s)
    volts = hw.voltage_needed(ref.torque + friction_torque(rate, hw.values()), rate)
    return float(np.max(np.abs(volts))) / rig.drive.V_max, float(np.max(np.abs(ref.theta_dot)))


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
