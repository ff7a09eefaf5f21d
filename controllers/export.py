"""Save and load linear controllers as state-space systems (``.mat``, ``.npz``, ``.json``).

The layout is the plant models' (:mod:`hubbeam_ctrl.linear.export`), with the controller's
matrices ``Ac, Bc, Cc, Dc`` (``xc[k+1] = Ac xc[k] + Bc e[k]``, ``u[k] = Cc xc[k] + Dc e[k]``),
the sample time ``dt`` [s], the names and units of its states, inputs (what it measures,
named like the design model's states or outputs) and output ``tau`` [N m], and metadata:
the controller's name, its torque limit, its settings, the design point and the design
model's parameters. Writes are atomic; the round trip is bit for bit.

Conventions (as :meth:`controllers.base.Controller.to_statespace`): ``e = y - y_ref`` is the
measurement's deviation from the reference and ``u = tau - tau_ff`` the torque beyond the
feedforward; the saturation at ``tau_max_nm`` is not part of the linear system. In MATLAB::

    S = load('ctrl.mat');
    K = ss(S.Ac, S.Bc, S.Cc, S.Dc, S.dt, 'StateName', S.state_names, ...
           'InputName', S.input_names, 'OutputName', S.output_names);

Examples
--------
>>> import tempfile, pathlib
>>> from controllers import DesignModel, LQG
>>> ctrl = LQG(DesignModel.build(n_modes=2))
>>> path = pathlib.Path(tempfile.mkdtemp()) / "lqg.npz"
>>> back = load_controller(save_controller(ctrl, path))
>>> back.input_names, back.output_names, back.n_states     # the filter carries residual modes
(['theta', 'theta_dot', 'root_moment'], ['tau'], 22)
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

from hubbeam_ctrl.core.errors import HubbeamError, ParameterError
from hubbeam_ctrl.core.jsonio import json_ready
from hubbeam_ctrl.linear.export import FORMATS, _real_matrix, load_system, save_system
from hubbeam_ctrl.linear.statespace import OUTPUTS, SystemViews, state_unit
from hubbeam_ctrl.plant.params import Params

from .base import Controller

__all__ = ["ControllerModel", "save_controller", "load_controller", "controller_model", "FORMATS"]

_TAG = "hubbeam-controller"
_VERSION = 1
_MATRICES = ("Ac", "Bc", "Cc", "Dc")


def _unit(name: str) -> str:
    """Unit of a controller signal or state (sensor names, design states, ``*_est`` states)."""
    if name in OUTPUTS:
        return OUTPUTS[name][0]
    if name == "tau":
        return "N m"
    return state_unit(name[:-4] if name.endswith("_est") else name)


@dataclass(frozen=True, eq=False)
class ControllerModel(SystemViews):
    """A linear controller as plain data: its python-control system and what made it.

    Attributes
    ----------
    sys : control.StateSpace
        Sampled system, inputs the measured deviations, output ``tau`` [N m].
    metadata : dict
        ``controller``, ``tau_max_nm``, ``design_spin_rad_s``, ``design_modes``,
        ``settings``, ``params``, the name and unit lists, ``dt``, and what it measures:
        ``measurement`` (``"sensors"`` or ``"state"``), ``reads_sensors_only`` (1 or 0) and ``sensors``
        (e.g. ``"theta [rad], theta_dot [rad/s], root_moment [N m]"``; for the full-state LQR,
        why no sensor gives its inputs and how to export it with its observer).

    Equality (``==``) is exact: same matrices bit for bit and same metadata.
    """

    sys: object
    metadata: dict

    Ac = property(lambda self: self.A, doc="State matrix (n, n).")
    Bc = property(lambda self: self.B, doc="Input matrix (n, inputs).")
    Cc = property(lambda self: self.C, doc="Output matrix (1, n).")
    Dc = property(lambda self: self.D, doc="Feedthrough (1, inputs).")

    @property
    def params(self) -> Params:
        """Parameters of the design model."""
        return Params(**self.metadata["params"])

    def __eq__(self, other):
        if not isinstance(other, ControllerModel):
            return NotImplemented
        mats = [(getattr(self, k), getattr(other, k)) for k in _MATRICES]
        return (all(a.shape == b.shape and a.tobytes() == b.tobytes() for a, b in mats)
                and self.metadata == other.metadata)

    __hash__ = None


#: The hub sensors of the closed loop (and of a rig with a strain gauge at the root), in order.
SENSORS = ("theta", "theta_dot", "root_moment")


def _sensor_metadata(ctrl: Controller, inputs: list) -> dict:
    """What the controller measures: ``measurement``, ``reads_sensors_only`` and ``sensors``
    (the sensors it expects with their units, or why it cannot run on the rig's sensors)."""
    only = all(name in SENSORS for name in inputs)
    if only:
        text = ", ".join(f"{name} [{_unit(name)}]" for name in inputs)
    else:
        text = ("none: the inputs are the design model's states (modal coordinates no sensor measures); "
                "`hubbeam codegen --controller lqr` exports this LQR with its Kalman observer on "
                "theta [rad], theta_dot [rad/s], root_moment [N m] (hubbeam_ctrl.deploy.ObservedLQR)")
    return {"measurement": getattr(ctrl, "measurement", "state"), "reads_sensors_only": int(only),
            "sensors": text}


def controller_model(ctrl: Controller) -> ControllerModel:
    """The linear controller ``ctrl`` as a :class:`ControllerModel`.

    Parameters
    ----------
    ctrl : Controller
        PD, LQR or LQG (:meth:`~controllers.base.Controller.to_statespace`).

    Returns
    -------
    ControllerModel
    """
    if not isinstance(ctrl, Controller):
        raise ParameterError(f"controller must be a Controller, got {type(ctrl).__name__}")
    if getattr(ctrl, "settings", None) is not None and hasattr(ctrl.settings, "horizon"):
        raise HubbeamError(f"controller {ctrl.name!r} is not a linear time-invariant feedback law: an MPC "
                           "solves a constrained QP at every sample (its unconstrained law, "
                           "ctrl.to_statespace(), is for analysis only)")
    sys = ctrl.to_statespace()
    d = ctrl.design
    states, inputs = list(sys.state_labels), list(sys.input_labels)
    meta = {
        "controller": ctrl.name, "name": sys.name, "dt": float(ctrl.dt),
        "state_names": states, "input_names": inputs, "output_names": ["tau"],
        "state_units": [_unit(s) for s in states], "input_units": [_unit(s) for s in inputs],
        "output_units": ["N m"], "tau_max_nm": float(ctrl.tau_max),
        "design_model": "sfoam", "design_spin_rad_s": float(d.spin), "design_modes": int(d.n_modes),
        "settings_type": type(ctrl.settings).__name__,
        "settings": json_ready(dataclasses.asdict(ctrl.settings)),
        "params": json_ready(d.params.to_dict()), "param_units": Params.units(),
        "convention": "input e = measurement - reference, output u = tau - tau_ff, "
                      "unsaturated (the controller clips tau at tau_max_nm)",
        **_sensor_metadata(ctrl, inputs),
    }
    return ControllerModel(sys, meta)


def save_controller(ctrl, path) -> Path:
    """Write a linear controller to ``.mat``, ``.npz`` or ``.json`` (by extension), atomically;
    returns the path written.

    Parameters
    ----------
    ctrl : Controller or ControllerModel
        PD, LQR or LQG, or a model from :func:`controller_model` / :func:`load_controller`.
    path : str or Path
        Refused (:class:`ParameterError`, no file left behind): an unknown extension, a missing
        or unwritable folder. A controller that is not linear (open loop, MPC) raises
        :class:`HubbeamError`.
    """
    model = ctrl if isinstance(ctrl, ControllerModel) else controller_model(ctrl)
    return save_system(path, {k: getattr(model, k) for k in _MATRICES}, model.metadata, _TAG, _VERSION,
                       model.params)


def load_controller(path) -> ControllerModel:
    """Read a controller written by :func:`save_controller`.

    Parameters
    ----------
    path : str or Path
        A ``.mat``, ``.npz`` or ``.json`` file; anything else, or a damaged file, is one line of
        :class:`ParameterError` naming it.

    Returns
    -------
    ControllerModel
        Equal, bit for bit, to what was saved.
    """
    import control
    mats, meta = load_system(path, _MATRICES, _TAG, "hubbeam controller file", _VERSION)
    dt = meta.get("dt")
    if isinstance(dt, bool) or not isinstance(dt, (int, float)) or not (math.isfinite(dt) and dt > 0):
        raise ParameterError(f"path: {path} is not a valid hubbeam controller file (dt {str(dt)[:40]} is not "
                             "a finite sample time > 0 s)")
    try:
        sys = control.ss(*(_real_matrix(k, mats[k]) for k in _MATRICES), float(meta["dt"]),
                         states=list(meta["state_names"]), inputs=list(meta["input_names"]),
                         outputs=list(meta["output_names"]), name=meta["name"])
        Params(**meta["params"])
    except (KeyError, TypeError, ValueError) as exc:
        raise ParameterError(f"path: {path} is not a valid hubbeam controller file ({exc})") from None
    meta = {k: v for k, v in meta.items() if k not in ("format", "version", *_MATRICES)}
    return ControllerModel(sys, meta)
