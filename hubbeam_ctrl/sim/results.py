"""Simulation results: plain arrays plus the parameters and settings that made them."""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.fileio import atomic_write
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.sim.outputs import derived_outputs

__all__ = ["SimulationResult", "HubStateViews", "load_result", "CSV_COLUMNS"]

#: Columns of the CSV export, in order, with units.
CSV_COLUMNS = {"t": "s", "theta": "rad", "theta_dot": "rad/s", "v_tip": "m", "u_tip": "m",
               "tau": "N m", "q_theta": "N m"}


def _describe(obj) -> str:
    if obj is None:
        return "none"
    if dataclasses.is_dataclass(obj):
        return repr(obj)
    return f"{type(obj).__name__}"


class HubStateViews:
    """Views of the hub's angle and rate for results holding ``q`` and ``v`` (N, n_q)."""

    @property
    def theta(self) -> np.ndarray:
        """Hub angle [rad]."""
        return self.q[:, 0]

    @property
    def theta_dot(self) -> np.ndarray:
        """Hub rate [rad/s]."""
        return self.v[:, 0]


@dataclass
class SimulationResult(HubStateViews):
    """Time series of one simulation.

    Attributes
    ----------
    model : str
        Model name.
    hub : str
        ``"free"`` or ``"prescribed"``.
    t : ndarray (N,)
        Time [s].
    q, v, a : ndarray (N, n_q)
        Generalised coordinates ``[theta, q1, q2]`` [rad, m], rates and accelerations.
    v_tip : ndarray (N,)
        Transverse tip displacement ``w2(L)`` in the hub frame [m].
    u_tip : ndarray (N,)
        Axial tip displacement ``w1(L) + wc(L)`` in the hub frame [m].
    tau : ndarray (N,)
        Hub torque [N m] (applied, or required by a prescribed motion).
    q_theta : ndarray (N,)
        The paper's inertia force on the hub ``Q_theta`` [N m].
    energy : ndarray (N,)
        ``T + U`` [J].
    angular_momentum : ndarray (N,)
        ``dT/d theta_dot`` [kg m^2/s].
    params : Params
    settings : dict
        Maneuver and integrator settings.
    diverged : bool
        True when the run stopped early (left the model's range, integrator failure or
        time limit); ``message`` says which.
    message : str
    wall_s : float
        Wall time of the integration [s].
    """

    model: str
    hub: str
    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    v_tip: np.ndarray
    u_tip: np.ndarray
    tau: np.ndarray
    q_theta: np.ndarray
    energy: np.ndarray
    angular_momentum: np.ndarray
    params: Params
    settings: dict = field(default_factory=dict)
    diverged: bool = False
    message: str = "completed"
    wall_s: float = 0.0

    @classmethod
    def from_states(cls, model, t, q, v, a, *, hub, maneuver=None, settings=None, diverged=False,
                    message="completed", wall_s=0.0, extra_settings=None, tau=None,
                    backend=None) -> "SimulationResult":
        """Build a result from states, evaluating the model's outputs on all samples.

        The outputs come from one mapped call (:func:`~hubbeam_ctrl.sim.outputs.derived_outputs`
        on ``backend``); ``tau`` [N m], when given (the applied torque of a free hub), is
        taken as it is, else it is the torque the accelerations ``a`` take.
        """
        out = derived_outputs(model, q, v, a if tau is None else None, backend)
        v_tip, u_tip, q_theta = out["v_tip"], out["u_tip"], out["q_theta"]
        energy, momentum = out["energy"], out["angular_momentum"]
        tau = out["tau"] if tau is None else np.broadcast_to(np.asarray(tau, dtype=float), (len(t),)).copy()
        s = {"maneuver": _describe(maneuver)}
        if settings is not None:
            s.update(dataclasses.asdict(settings))
        if extra_settings:
            s.update(extra_settings)
        return cls(model=model.name, hub=hub, t=t, q=q, v=v, a=a, v_tip=v_tip, u_tip=u_tip,
                   tau=tau, q_theta=q_theta, energy=energy, angular_momentum=momentum,
                   params=model.params, settings=s, diverged=diverged, message=message,
                   wall_s=wall_s)

    def window(self, t_start: float, t_stop: float | None = None) -> np.ndarray:
        """Boolean mask of samples with ``t_start <= t <= t_stop`` (``None``: to the end)."""
        stop = self.t[-1] if t_stop is None else t_stop
        return (self.t >= t_start - 1e-12) & (self.t <= stop + 1e-12)

    def summary(self, residual_window_s: float = 10.0) -> dict:
        """Key figures: peak and residual tip deflection, final hub state, flags.

        Parameters
        ----------
        residual_window_s : float
            The residual is ``max |v_tip|`` over the last ``residual_window_s`` seconds.

        Returns
        -------
        dict
            ``peak_tip_m``, ``residual_tip_m``, ``peak_axial_m``, ``final_theta_rad``,
            ``final_theta_dot_rad_s``, ``diverged``, ``message``, ``wall_s``.
        """
        last = self.window(self.t[-1] - residual_window_s)
        return {
            "model": self.model,
            "peak_tip_m": float(np.max(np.abs(self.v_tip))),
            "residual_tip_m": float(np.max(np.abs(self.v_tip[last]))),
            "peak_axial_m": float(np.max(np.abs(self.u_tip))),
            "final_theta_rad": float(self.theta[-1]),
            "final_theta_dot_rad_s": float(self.theta_dot[-1]),
            "diverged": bool(self.diverged),
            "message": self.message,
            "wall_s": float(self.wall_s),
        }

    # -- saving ------------------------------------------------------------------
    def columns(self) -> dict:
        """The CSV columns (see :data:`CSV_COLUMNS`) as arrays."""
        return {name: np.asarray(getattr(self, name)) for name in CSV_COLUMNS}

    def save(self, path) -> Path:
        """Save atomically to ``.csv`` (the :data:`CSV_COLUMNS`) or ``.npz`` (everything).

        Parameters
        ----------
        path : str or Path

        Returns
        -------
        Path
        """
        path = Path(path)
        suffix = path.suffix.lower()
        if suffix == ".csv":
            cols = self.columns()
            data = np.column_stack(list(cols.values()))
            header = ",".join(cols)

            def write(tmp):
                with open(tmp, "w", encoding="utf-8") as fh:
                    np.savetxt(fh, data, delimiter=",", header=header, comments="", fmt="%.10e")
            return atomic_write(path, write)
        if suffix == ".npz":
            arrays = {k: getattr(self, k) for k in ("t", "q", "v", "a", "v_tip", "u_tip", "tau",
                                                    "q_theta", "energy", "angular_momentum")}

            def write(tmp):
                with open(tmp, "wb") as fh:
                    np.savez(fh, metadata=json.dumps(self._metadata()), **arrays)
            return atomic_write(path, write)
        raise ParameterError(f"out: unknown extension {suffix!r}; allowed: .csv, .npz")

    def _metadata(self) -> dict:
        return {"model": self.model, "hub": self.hub, "params": self.params.to_dict(),
                "settings": self.settings, "diverged": self.diverged, "message": self.message,
                "wall_s": self.wall_s}


def load_result(path) -> SimulationResult:
    """Load a :class:`SimulationResult` saved as ``.npz``.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    SimulationResult
    """
    path = Path(path)
    if path.suffix.lower() != ".npz":
        raise ParameterError(f"path: only .npz results can be loaded, got {path.suffix!r}")
    with np.load(path, allow_pickle=False) as data:
        meta = json.loads(str(data["metadata"]))
        arrays = {k: data[k] for k in data.files if k != "metadata"}
    return SimulationResult(model=meta["model"], hub=meta["hub"], params=Params.from_dict(meta["params"]),
                            settings=meta["settings"], diverged=meta["diverged"],
                            message=meta["message"], wall_s=meta["wall_s"], **arrays)
