"""Controllers for the rotating hub-beam: open loop (Eq. 44), PD, LQR, LQG, MPC, input-shaped slews.

Every controller is built once from a linear SFOAM :class:`DesignModel`, its settings and
a :class:`Reference`, and is then a function of time and measurement at its sample
instants: ``tau = ctrl(t, y)``; ``ctrl.reset()`` starts a new run. Each controller is
registered once in :mod:`controllers.registry` (:data:`CONTROLLERS`); comparisons, the CLI
and the plots read it. The closed-loop
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

from .base import (
    Controller,
    ControllerSettings,
    DesignModel,
    LQSettings,
    Reference,
    TrackingSettings,
    Weights,
    saturate,
)
from .estimator import KalmanEstimator, KalmanNoise, kalman_gain
from .hinf import HInf, HInfSettings
from .lqg import LQG, LQGSettings
from .lqr import LQR, LQRSettings, dlqr_gain
from .mpc import MPC, QP_SOLVERS, MPCSettings, condensed_matrices
from .msmpc import MultiStageMPC, MultiStageMPCSettings
from .nmpc import NMPC, NMPCSettings
from .openloop import OpenLoop, OpenLoopSettings
from .pd import PD, PDSettings, pd_gains
from .planning import planned_slew_reference
from .reference import eq44_reference, optimal_reference, slew_reference, spinup_reference
from .registry import (
    CONTROLLERS,
    ControllerSpec,
    controller_names,
    controller_styles,
    make_controller,
    register_controller,
    unregister_controller,
)
from .schedule import (
    DesignSchedule,
    ScheduledLQG,
    ScheduledLQR,
    ScheduledMPC,
    filter_schedule,
    scheduled_lqg_iosystem,
    scheduled_lqr_iosystem,
)
from .shaped import EIOpenLoop, ShapedOpenLoop, ShapedSettings, ZVDOpenLoop, ZVOpenLoop
from .shaping import SHAPERS, Shaper, as_shaper, design_shaper, shape_reference

__all__ = [
    "Controller", "DesignModel", "Reference", "Weights", "saturate",
    "ControllerSettings", "TrackingSettings", "LQSettings",
    "OpenLoop", "OpenLoopSettings", "PD", "PDSettings", "pd_gains",
    "LQR", "LQRSettings", "dlqr_gain", "LQG", "LQGSettings",
    "KalmanEstimator", "KalmanNoise", "kalman_gain",
    "MPC", "MPCSettings", "QP_SOLVERS", "condensed_matrices", "MultiStageMPC", "MultiStageMPCSettings",
    "NMPC", "NMPCSettings", "HInf", "HInfSettings",
    "slew_reference", "spinup_reference", "eq44_reference", "optimal_reference", "planned_slew_reference",
    "CONTROLLERS", "ControllerSpec", "register_controller", "unregister_controller",
    "make_controller", "controller_names", "controller_styles",
    "Shaper", "SHAPERS", "as_shaper", "design_shaper", "shape_reference", "ShapedOpenLoop", "ShapedSettings",
    "ZVOpenLoop", "ZVDOpenLoop", "EIOpenLoop",
    "DesignSchedule", "ScheduledLQR", "ScheduledLQG", "ScheduledMPC",
    "scheduled_lqr_iosystem", "scheduled_lqg_iosystem", "filter_schedule",
]
