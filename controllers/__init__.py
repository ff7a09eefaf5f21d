"""Controllers for the rotating hub-beam: open loop (Eq. 44), PD, LQR, LQG and MPC.

Every controller is built once from a linear SFOAM :class:`DesignModel`, its settings and
a :class:`Reference`, and is then a function of time and measurement at its sample
instants: ``tau = ctrl(t, y)``; ``ctrl.reset()`` starts a new run. The closed-loop
simulator (:func:`hubbeam_ctrl.sim.closedloop.simulate_closed_loop`) runs any of them on the
nonlinear FOAM or CFOAM plant; :func:`hubbeam_ctrl.study.compare.run_compare` compares them.

Examples
--------
>>> from hubbeam_ctrl import Params
>>> from hubbeam_ctrl.sim import simulate_closed_loop
>>> from controllers import DesignModel, LQR, slew_reference
>>> p = Params(n_axial=2, n_transverse=2)
>>> design = DesignModel.build(p, spin=0.0, dt=0.01)
>>> ref = slew_reference(1.0, 10.0, p.total_inertia, 200.0, 0.01, 20.0)
>>> res = simulate_closed_loop("foam", LQR(design, reference=ref), 20.0, params=p)
>>> bool(abs(res.theta[-1] - 1.0) < 1e-3)
True
"""

from .base import Controller, DesignModel, Reference, Weights, saturate
from .lqg import LQG, LQGSettings, kalman_gain
from .lqr import LQR, LQRSettings, dlqr_gain
from .mpc import MPC, QP_SOLVERS, MPCSettings, condensed_matrices
from .openloop import OpenLoop, OpenLoopSettings
from .pd import PD, PDSettings, pd_gains
from .reference import eq44_reference, slew_reference, spinup_reference
from .schedule import (
    DesignSchedule,
    ScheduledLQG,
    ScheduledLQR,
    ScheduledMPC,
    make_scheduled_controller,
    scheduled_lqg_iosystem,
    scheduled_lqr_iosystem,
)
from .shaped import EIOpenLoop, ShapedOpenLoop, ShapedSettings, ZVDOpenLoop, ZVOpenLoop
from .shaping import Shaper, design_shaper, shape_reference

__all__ = [
    "Controller", "DesignModel", "Reference", "Weights", "saturate",
    "OpenLoop", "OpenLoopSettings", "PD", "PDSettings", "pd_gains",
    "LQR", "LQRSettings", "dlqr_gain", "LQG", "LQGSettings", "kalman_gain",
    "MPC", "MPCSettings", "QP_SOLVERS", "condensed_matrices",
    "slew_reference", "spinup_reference", "eq44_reference",
    "CONTROLLERS", "make_controller",
    "Shaper", "design_shaper", "shape_reference", "ShapedOpenLoop", "ShapedSettings",
    "ZVOpenLoop", "ZVDOpenLoop", "EIOpenLoop",
    "DesignSchedule", "ScheduledLQR", "ScheduledLQG", "ScheduledMPC", "make_scheduled_controller",
    "scheduled_lqr_iosystem", "scheduled_lqg_iosystem",
]

#: Controller name -> (class, settings class).
CONTROLLERS = {
    "openloop": (OpenLoop, OpenLoopSettings),
    "pd": (PD, PDSettings),
    "lqr": (LQR, LQRSettings),
    "lqg": (LQG, LQGSettings),
    "mpc": (MPC, MPCSettings),
    "zv": (ZVOpenLoop, ShapedSettings),
    "zvd": (ZVDOpenLoop, ShapedSettings),
    "ei": (EIOpenLoop, ShapedSettings),
}


def make_controller(name: str, design: DesignModel, settings=None, reference: Reference | None = None,
                    shaping=None):
    """Build a controller by name (``openloop``, ``pd``, ``lqr``, ``lqg``, ``mpc``, ``zv``, ``zvd``, ``ei``).

    Parameters
    ----------
    name : str
    design : DesignModel
    settings : dataclass, optional
        The controller's settings (default: its defaults).
    reference : Reference, optional
    shaping : {"zv", "zvd", "ei"} or Shaper, optional
        Filter the reference (and its feedforward) through this input shaper first
        (a name: designed on the design model's first mode, see
        :func:`controllers.shaping.design_shaper`).

    Returns
    -------
    Controller
    """
    from hubbeam_ctrl.core.errors import ParameterError
    if name not in CONTROLLERS:
        raise ParameterError(f"controllers: unknown controller {name!r}; allowed: {', '.join(CONTROLLERS)}")
    cls, settings_cls = CONTROLLERS[name]
    if shaping is not None:
        reference = shape_reference(reference if reference is not None else Reference.rest(design.dt),
                                    shaping if isinstance(shaping, Shaper) else design_shaper(design, shaping))
    return cls(design, settings if settings is not None else settings_cls(), reference)
