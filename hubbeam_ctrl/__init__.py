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

import importlib

__version__ = "0.1.0"

#: Public name -> module that defines it. The modules are imported on first use (PEP 562),
#: so ``import hubbeam_ctrl`` (and the CLI's start-up) does not pull in python-control,
#: SciPy's signal package or CasADi before a command needs them.
_EXPORTS = {
    "hubbeam_ctrl.core.errors": ("HubbeamError", "ParameterError"),
    "hubbeam_ctrl.linear.export": ("load_model", "save_model"),
    "hubbeam_ctrl.linear.pole_comparison": ("compare_poles",),
    "hubbeam_ctrl.linear.statespace": ("LinearModel", "linearize"),
    "hubbeam_ctrl.linear.transforms": ("discretize", "reduce"),
    "hubbeam_ctrl.plant.basis": ("ModalBasis", "modal_basis"),
    "hubbeam_ctrl.plant.linearization": ("first_order_matrices", "second_order_linearization"),
    "hubbeam_ctrl.plant.maneuvers": ("ConstantSpin", "SpinUp", "TorquePulse", "UserManeuver"),
    "hubbeam_ctrl.plant.modal": ("campbell", "critical_speed", "critical_speed_map", "modal_analysis",
                                 "natural_frequencies"),
    "hubbeam_ctrl.plant.models": ("MODEL_NAMES", "HubBeamModel", "build_model"),
    "hubbeam_ctrl.plant.params": ("Params", "load_params", "save_params"),
    "hubbeam_ctrl.plant.rig": ("Rig", "load_rig", "save_rig"),
    "hubbeam_ctrl.sim.results": ("Result", "SimulationResult", "load_result"),
    "hubbeam_ctrl.sim.simulate": ("SimulationSettings", "simulate"),
}
_WHERE = {name: module for module, names in _EXPORTS.items() for name in names}

__all__ = [name for names in _EXPORTS.values() for name in names]


def __getattr__(name):
    """Import the module that defines the public ``name`` on first access (PEP 562)."""
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module 'hubbeam_ctrl' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
