"""The values of an optimal slew: how it is computed (:class:`OptimalSettings`), what it
found (:class:`OptimalSlew`), and the limits of its inputs. The solvers are
:mod:`hubbeam_ctrl.limit.optimal`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hubbeam_ctrl.core.settings import Settings, setting
from hubbeam_ctrl.plant.models import AXIAL_TREATMENTS
from hubbeam_ctrl.plant.params import MAX_MODES, Params

__all__ = ["OptimalSettings", "OptimalSlew", "DEFAULT_TOLERANCE", "default_tolerance"]

#: Default residual tip vibration, relative to the beam length (the issue's 0.1 % of L).
DEFAULT_TOLERANCE = 1e-3

#: Smallest residual tolerance, relative to the beam length (the NLP divides the residual energy
#: by the tolerance squared).
MIN_TOLERANCE = 1e-9

#: Smallest slew angle [rad] (as a task's, :data:`hubbeam_ctrl.study.tasks.MIN_TARGET`).
MIN_SLEW_ANGLE = 1e-6

#: Longest slew time [s] (as a task's ``tf``).
MAX_DURATION = 1e6


@dataclass(frozen=True)
class OptimalSettings(Settings):
    """How the optimal slew is computed and checked."""

    intervals: int = setting(40, lo=4, hi=2000, doc="Collocation intervals N of the slew (torque constant "
                                                    "on each).")
    degree: int = setting(3, lo=1, hi=9, doc="Radau collocation points per interval.")
    coarse_intervals: int = setting(0, lo=0, hi=2000,
                                    doc="Intervals of the first, coarse solve whose result warm-starts "
                                        "the fine one (0: no coarse solve).")
    model: str = setting("foam", choices=("foam", "cfoam", "tlam"), doc="Design model of the optimisation.")
    axial: str = setting("quasi-static", choices=AXIAL_TREATMENTS,
                         doc="Axial coordinates of the design model (quasi-static: no stiff axial modes).")
    modes: int | None = setting(None, lo=1, hi=MAX_MODES, kind=int,
                                doc="Transverse modes of the design model (None: params.n_transverse).")
    plant_modes: int | None = setting(None, lo=1, hi=MAX_MODES, kind=int,
                                      doc="Transverse modes of the evaluation plant (None: 3 more than "
                                          "the design, at most 20).")
    check: bool = setting(True, doc="Apply the optimal torque to the evaluation plant and report its "
                                    "residual.")
    max_iter: int = setting(1000, lo=1, doc="IPOPT iteration limit per solve.")
    torque_smoothing: float = setting(0.0, lo=0.0, doc="Minimum vibration only: weight of the torque's squared "
                                                        "steps (scaled by tau_max) added to the residual's "
                                                        "objective, which picks one plan among the many that "
                                                        "leave the model at rest (0: none).")
    max_wall_s: float | None = setting(None, unit="s", lo=0.0, lo_open=True, kind=float,
                                       doc="IPOPT's wall-clock limit per solve (None: none; building the NLP "
                                           "before it is not counted); past it the result is the last iterate, "
                                           "not converged. A real-time re-plan's deadline.")
    deflection_limit: float = setting(0.3, lo=0.0, lo_open=True, hi=10.0,
                                      doc="Largest abs(v_tip) during the slew, relative to L, kept at every grid "
                                          "point (0.3: the models' validated range; a light link driven by its "
                                          "full torque would otherwise bend past it, where the model is not "
                                          "the beam).")


@dataclass(frozen=True, eq=False)
class OptimalSlew:
    """An optimal rest-to-rest slew and how well it did.

    Attributes
    ----------
    kind : {"time-optimal", "min-vibration"}
        Which problem was solved (:func:`~hubbeam_ctrl.limit.optimal.time_optimal_slew` or
        :func:`~hubbeam_ctrl.limit.optimal.min_vibration_slew`).
    slew_angle : float
        Theta [rad].
    duration_s : float
        Slew time T [s].
    t : ndarray (N+1,)
        Grid times [s].
    tau : ndarray (N,)
        Torque on each interval ``[t_k, t_k+1)`` [N m].
    theta, theta_dot, v_tip : ndarray (N+1,)
        Hub angle [rad], hub rate [rad/s] and tip deflection in the hub frame [m] of the
        design model at the grid times.
    q2, q2_dot : ndarray (N+1, n2)
        Transverse modal coordinates [m] and rates [m/s] of the design model at the grid times.
    tolerance : float
        Allowed residual tip vibration [m].
    residual_design : float
        Residual tip amplitude of the design model at ``T`` (modal bound) [m].
    residual_plant : float or None
        Largest ``|v_tip|`` of the evaluation plant after ``T`` [m] (None: not checked).
    final_angle_plant : float or None
        Mean hub angle of the evaluation plant after ``T`` [rad].
    rigid_bound_s : float
        The rigid body's shortest slew [s] (:func:`rigid_bound`): ``2 sqrt(Theta J / tau_max)``,
        or on a DC drive the bang-bang within its voltage (back-EMF), current and friction.
    converged : bool
        Whether IPOPT reported success.
    message : str
        IPOPT's return status, and what was kept if it did not converge.
    solve_s : float
        Wall time of the optimisation [s].
    iterations : int
        IPOPT iterations (all solves).
    design : str
        The design model (name, modes, axial treatment).
    plant : str
        The evaluation plant, or "" if not checked.
    params : Params
    """

    kind: str
    slew_angle: float
    duration_s: float
    t: np.ndarray
    tau: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    v_tip: np.ndarray
    q2: np.ndarray
    q2_dot: np.ndarray
    tolerance: float
    residual_design: float
    residual_plant: float | None
    final_angle_plant: float | None
    rigid_bound_s: float
    converged: bool
    message: str
    solve_s: float
    iterations: int
    design: str
    plant: str
    params: Params = field(repr=False)

    @property
    def ratio(self) -> float:
        """``duration_s / rigid_bound_s`` [-]."""
        return self.duration_s / self.rigid_bound_s

    def torque(self, t):
        """The optimal torque at times ``t`` [s] (piecewise constant, 0 outside ``[0, T)``) [N m].

        Parameters
        ----------
        t : float or array_like
            Times [s].
        """
        t = np.asarray(t, dtype=float)
        k = np.clip(np.floor(t / self.duration_s * len(self.tau)).astype(int), 0, len(self.tau) - 1)
        return np.where((t >= 0) & (t < self.duration_s), self.tau[k], 0.0)

    def to_dict(self) -> dict:
        """Plain-data summary (JSON-ready, without the trajectories)."""
        return {"kind": self.kind, "slew_angle": self.slew_angle, "duration_s": self.duration_s,
                "rigid_bound_s": self.rigid_bound_s, "ratio": self.ratio, "tolerance_m": self.tolerance,
                "residual_design_m": self.residual_design, "residual_plant_m": self.residual_plant,
                "final_angle_plant": self.final_angle_plant, "converged": self.converged,
                "message": self.message, "solve_s": self.solve_s, "iterations": self.iterations,
                "design": self.design, "plant": self.plant, "tau_max": self.params.tau_max}


def default_tolerance(params: Params) -> float:
    """Default residual tip vibration: :data:`DEFAULT_TOLERANCE` times the beam length [m].

    Parameters
    ----------
    params : Params
        Beam (``L``).
    """
    return DEFAULT_TOLERANCE * params.L
