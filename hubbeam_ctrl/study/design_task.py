"""The task and the design model of one design (``hubbeam design``, ``hubbeam codegen``): the
scenario built once from the beam, the task's values and the sample time (the rig's, else
:func:`~hubbeam_ctrl.study.yardstick.task_dt`), and the sampled SFOAM model at its design spin.

Example::

    >>> from hubbeam_ctrl.plant.params import Params
    >>> sc, design = task_and_design(Params(n_axial=2, n_transverse=2), t_f=8.0)
    >>> sc.dt, design.n_modes
    (0.01, 2)
"""

from __future__ import annotations

from controllers import DesignModel
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.study.scenarios import make_scenario
from hubbeam_ctrl.study.yardstick import task_dt

__all__ = ["task_and_design"]


def task_and_design(params, scenario: str = "slew", *, rig=None, tau_max: float | None = None,
                    dt: float | None = None, design_modes: int | None = None, slew_angle: float | None = None,
                    t_f: float | None = None, w_f: float | None = None) -> tuple:
    """The scenario of a task and the design model sampled at its ``dt``; the simulated time is ``3 t_f``.

    A slew with no ``t_f`` on a rig with hardware is the rig's default slew, the task
    ``hubbeam compare --rig`` runs (:func:`~hubbeam_ctrl.study.yardstick.rig_default_slew`: by
    ``slew_angle``, default pi/2 rad), and one with a ``t_f`` and no ``slew_angle`` turns that default
    angle in ``t_f`` (as ``compare`` does); any other task with no ``t_f`` lasts 10 s.

    Parameters
    ----------
    params : Params
        The design's beam (a rig's ``plant_params``: the rotor reflected).
    scenario : {"slew", "spinup"}
        The task.
    rig : Rig, optional
        Its ``timing.dt`` is the default sample time; its drive the torque limit in the message.
    tau_max : float, optional
        Torque budget [N m], at most ``params.tau_max`` (default: that).
    dt : float, optional
        Sample time [s] (default: the rig's, else :func:`~hubbeam_ctrl.study.yardstick.task_dt`).
    design_modes : int, optional
        Transverse modes of the design model, 1..20 (default ``params.n_transverse``).
    slew_angle : float, optional
        Slew angle [rad], not 0 (default: the Eq. 44 angle of ``tau_max`` in ``t_f``).
    t_f : float, optional
        Maneuver time [s] (default: the rig's default slew, else 10).
    w_f : float, optional
        Spin-up final rate [rad/s] (default 3).

    Returns
    -------
    scenario : hubbeam_ctrl.study.scenarios.Scenario
    design : controllers.DesignModel
        Sampled at the scenario's ``dt`` [s] with ``design_modes`` transverse modes.
    """
    if tau_max is not None and tau_max > params.tau_max:
        whose = "the rig's drive" if rig is not None else "the motor's tau_max of the parameters"
        raise ParameterError(f"tau_max must be in (0, {params.tau_max:g}] N m ({whose}), got {tau_max:g}")
    if dt is None:
        dt = rig.timing.dt if rig is not None and rig.timing.dt else task_dt(params)
    modes = design_modes if design_modes is not None else params.n_transverse
    if not 1 <= modes <= 20:
        raise ParameterError(f"design_modes must be an integer in 1..20, got {modes}")
    if slew_angle is not None and slew_angle == 0:
        raise ParameterError("slew_angle must be a finite number != 0 [rad]")
    if scenario == "slew" and rig is not None and not rig.is_ideal:
        from hubbeam_ctrl.study.yardstick import DEFAULT_RIG_SLEW_RAD, rig_default_slew
        if t_f is None:
            slew = rig_default_slew(rig, slew_angle)[0]
            slew_angle, t_f = slew.angle, slew.duration
        elif slew_angle is None:        # a duration alone: the rig's default angle, as compare turns it
            slew_angle = DEFAULT_RIG_SLEW_RAD
    t_f = 10.0 if t_f is None else t_f
    sc = make_scenario(scenario, plant="foam", params=params, tau_max=tau_max, t_f=t_f, t_end=3 * t_f, dt=dt,
                       w_f=3.0 if w_f is None else w_f, slew_angle=slew_angle)
    return sc, DesignModel.build(params, sc.design_spin, dt, modes)
