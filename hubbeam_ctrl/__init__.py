"""hubbeam-ctrl: control design for rotating flexible hub-beam systems.

Plant side of the toolbox: parameters, modal basis, the four nonlinear models (CFOAM,
FOAM, TLAM, SFOAM) defined by their energies, simulation, modal analysis and the CLI.
The controllers live in the sibling package ``controllers``.

Examples
--------
>>> from hubbeam_ctrl import Params, simulate, SpinUp
>>> res = simulate("foam", SpinUp(w_f=2.8, t_f=30.0), t_end=40.0, params=Params(m_t=0.0))
>>> round(res.summary()["peak_tip_m"], 2)
0.2
"""

from hubbeam_ctrl.core.errors import HubbeamError, ParameterError
from hubbeam_ctrl.linear.export import load_model, save_model
from hubbeam_ctrl.linear.statespace import LinearModel, compare_poles, discretize, linearize, reduce
from hubbeam_ctrl.plant.basis import ModalBasis, modal_basis
from hubbeam_ctrl.plant.linearization import first_order_matrices, second_order_linearization
from hubbeam_ctrl.plant.maneuvers import ConstantSpin, SpinUp, TorquePulse, UserManeuver
from hubbeam_ctrl.plant.modal import campbell, critical_speed, critical_speed_map, modal_analysis, natural_frequencies
from hubbeam_ctrl.plant.models import MODEL_NAMES, HubBeamModel, build_model
from hubbeam_ctrl.plant.params import Params, load_params, save_params
from hubbeam_ctrl.sim.results import Result, SimulationResult, load_result
from hubbeam_ctrl.sim.simulate import SimulationSettings, simulate

__version__ = "0.1.0"

__all__ = [
    "Params", "load_params", "save_params", "ModalBasis", "modal_basis",
    "HubBeamModel", "build_model", "MODEL_NAMES",
    "SpinUp", "TorquePulse", "ConstantSpin", "UserManeuver",
    "simulate", "SimulationSettings", "Result", "SimulationResult", "load_result",
    "modal_analysis", "natural_frequencies", "campbell", "critical_speed", "critical_speed_map",
    "second_order_linearization", "first_order_matrices",
    "linearize", "LinearModel", "discretize", "reduce", "compare_poles", "save_model", "load_model",
    "HubbeamError", "ParameterError",
]
