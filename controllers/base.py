"""What every controller shares: the design model, the reference, the weights, the interface.

A controller is built once from a :class:`DesignModel` (the linear SFOAM about a spin
rate, sampled at the controller's period), its settings and a :class:`Reference` (the
hub trajectory to follow and its feedforward torque). It is then a function of time and
measurement at its sample instants::

    ctrl = LQR(design, LQRSettings(), reference)
    ctrl.reset()
    tau = ctrl(t, y)           # hub torque [N m] to hold until the next sample

Coordinates. The design model's state is the SFOAM state
``x = [theta, q2_1..q2_m, theta_dot, q2_dot_1..q2_dot_m]`` (rad, m, rad/s, m/s). About a
spin rate ``Omega`` the linear model describes deviations from the steady rotation
``theta = Omega t``; with the reference ``x_ref = [theta_ref, 0, theta_dot_ref, 0]`` the
tracking error ``e = x - x_ref`` is the same in absolute and deviation coordinates, so the
full-state controllers work directly on the plant's measured state.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from hubbeam_ctrl.core.errors import HubbeamError, ParameterError
from hubbeam_ctrl.core.settings import Settings, setting
from hubbeam_ctrl.core.validation import check_positive
from hubbeam_ctrl.plant.params import MAX_MODES, Params

from .design_model import DesignModel, _zoh  # noqa: F401 - re-exported: every controller takes one
from .reference import Reference  # noqa: F401 - re-exported: every controller follows one

__all__ = ["DesignModel", "Reference", "Weights", "Controller", "saturate", "torque_limit", "ControllerSettings",
           "TrackingSettings", "LQSettings", "check_positive", "check_psd"]


# -- validation helpers -----------------------------------------------------------------


def check_psd(name: str, M, n: int, definite: bool = False) -> np.ndarray:
    """Check that ``M`` is a symmetric positive (semi)definite ``n x n`` matrix.

    Parameters
    ----------
    name : str
        The matrix's name as the caller spelled it (starts the message).
    M : array_like (n, n)
        The matrix.
    n : int
        Required size.
    definite : bool
        Require positive definite (default: semidefinite).

    Raises
    ------
    ParameterError
        Naming ``name`` and the smallest eigenvalue.
    """
    M = np.asarray(M, dtype=float)
    if M.shape != (n, n) or not np.all(np.isfinite(M)):
        raise ParameterError(f"{name} must be a finite {n} x {n} matrix, got shape {M.shape}")
    if not np.allclose(M, M.T, rtol=1e-10, atol=1e-12 * max(1.0, np.abs(M).max())):
        raise ParameterError(f"{name} must be symmetric")
    lam = np.linalg.eigvalsh(0.5 * (M + M.T))
    tol = 1e-12 * max(1.0, np.abs(lam).max())
    if definite and lam.min() <= tol:
        raise ParameterError(f"{name} must be positive definite; smallest eigenvalue {lam.min():.3g}")
    if lam.min() < -tol:
        raise ParameterError(f"{name} must be positive semidefinite; smallest eigenvalue {lam.min():.3g}")
    return 0.5 * (M + M.T)


def saturate(tau: float, tau_max: float) -> float:
    """Clip a torque to ``[-tau_max, tau_max]`` [N m] (NaN passes through).

    Parameters
    ----------
    tau : float
        Torque [N m].
    tau_max : float
        Limit [N m], > 0.
    """
    return tau_max if tau > tau_max else (-tau_max if tau < -tau_max else tau)


def torque_limit(tau_max, params: Params, name: str = "tau_max") -> float:
    """The torque limit a controller saturates at: its own, or the motor's ``params.tau_max``.

    Parameters
    ----------
    tau_max : float or None
        The controller's setting [N m]; ``None`` means the motor's limit.
    params : Params
        The design model's parameters (``params.tau_max`` is the motor's limit [N m]).
    name : str
        The setting's name for the error message.

    Returns
    -------
    float
        [N m], ``0 < limit <= params.tau_max``.

    Raises
    ------
    ParameterError
        If ``tau_max`` is above the motor's limit (a controller cannot command more
        torque than the motor has).

    Examples
    --------
    >>> torque_limit(None, Params(tau_max=1.5)), torque_limit(1.0, Params(tau_max=1.5))
    (1.5, 1.0)
    """
    motor = params.tau_max
    if tau_max is None:
        return motor
    tau_max = check_positive(name, tau_max, "N m")
    if tau_max > motor * (1.0 + 1e-9):   # a rounding above it is the limit (a rig's drive gives 13.361999...)
        raise ParameterError(f"{name} must be in (0, {motor:g}] N m (the motor's Params.tau_max), "
                             f"got {tau_max:g}")
    return min(tau_max, motor)


# -- weights -----------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Weights(Settings):
    """Quadratic weights of LQR, LQG and MPC: ``sum e'Q e + R (tau - tau_ff)^2``.

    ``Q = angle diag + rate diag + tip c_tip' c_tip + tip_rate c_rate' c_rate`` on the
    tracking error ``e = x - x_ref``, unless ``state_matrix`` gives the whole ``Q``.
    The defaults were tuned on the default slew (see the README, "Default weights").
    """

    _setting_prefix = "weights."

    angle: float = setting(1e4, unit="1/rad^2", lo=0.0, doc="Weight on the hub-angle error.")
    rate: float = setting(1e5, unit="1/(rad/s)^2", lo=0.0, doc="Weight on the hub-rate error.")
    tip: float = setting(3e3, unit="1/m^2", lo=0.0, doc="Weight on the tip deflection v_tip.")
    tip_rate: float = setting(3e3, unit="1/(m/s)^2", lo=0.0, doc="Weight on the tip-deflection rate.")
    modal: float = setting(1e4, unit="1/m^2 or 1/(m/s)^2", lo=0.0,
                           doc="Weight on every modal coordinate and rate (helps damp the higher "
                               "modes that barely move the tip).")
    modal_rate: float | None = setting(None, unit="1/(m/s)^2", lo=0.0, kind=float,
                                       doc="Weight on every modal rate; None: modal (the rates weighted "
                                           "like the coordinates).")
    torque: float = setting(2.5e-5, unit="1/(N m)^2", lo=0.0, lo_open=True,
                            doc="Weight on the torque beyond the feedforward.")
    state_matrix: np.ndarray | None = setting(None, kind=object,
                                              doc="Full state weight Q (n_x x n_x, symmetric positive "
                                                  "semidefinite) that replaces the scalar state weights; "
                                                  "checked against the design model by matrices().")

    def matrices(self, design: DesignModel):
        """State and input weights ``(Q, R)`` for ``design`` (validated).

        Parameters
        ----------
        design : DesignModel
            The design model the weights are for (its state size and rows).
        """
        nx = design.n_x
        if self.state_matrix is not None:
            Q = check_psd("weights.state_matrix", self.state_matrix, nx)
        else:
            n = nx // 2
            Q = np.zeros((nx, nx))
            Q[0, 0] = self.angle
            Q[n, n] = self.rate
            c, cd = design.C_tip
            Q += self.tip * np.outer(c, c) + self.tip_rate * np.outer(cd, cd)
            Q[np.r_[1:n], np.r_[1:n]] += self.modal
            Q[np.r_[n + 1:nx], np.r_[n + 1:nx]] += self.modal if self.modal_rate is None else self.modal_rate
        return Q, np.array([[self.torque]])


# -- settings shared by the controllers --------------------------------------------------------
@dataclass(frozen=True)
class ControllerSettings(Settings):
    """Base of every controller's settings, with the hook that picks a scenario's defaults."""

    @classmethod
    def for_scenario(cls, scenario, **options) -> "ControllerSettings":
        """Default settings for a closed-loop scenario.

        The default fills the fields named ``tau_max`` (from ``scenario.tau_max``), those of
        the scenario's scaled defaults (``scenario.defaults``: weights, noise levels, PD
        bandwidth from the beam and the task, see :func:`controllers.scaling.scaled_defaults`)
        and any of ``options`` that the class has; subclasses override it when the scenario
        decides more (e.g. :class:`~controllers.openloop.OpenLoopSettings`).

        Parameters
        ----------
        scenario : object
            A :class:`hubbeam_ctrl.study.scenarios.Scenario` (read: ``tau_max``, ``t_f``,
            ``baseline``, ``defaults``).
        **options
            Study-wide controller options (``horizon``, ``solver``...); those the class
            has no field for are ignored.

        Returns
        -------
        ControllerSettings
        """
        names = {f.name for f in fields(cls)}
        given = {"tau_max": scenario.tau_max, **(getattr(scenario, "defaults", None) or {}), **options}
        return cls(**{k: v for k, v in given.items() if k in names})


@dataclass(frozen=True)
class TrackingSettings(ControllerSettings):
    """Settings of every feedback controller that follows a reference under a torque limit."""

    tau_max: float | None = setting(None, unit="N m", lo=0.0, lo_open=True, kind=float,
                                    doc="Torque limit: the output never exceeds +-tau_max; at most the "
                                        "motor's Params.tau_max of the design model. None: that limit.")
    feedforward: bool = setting(True, doc="Use the reference's rigid-body feedforward torque.")


@dataclass(frozen=True)
class LQSettings(TrackingSettings):
    """Settings shared by the quadratic-cost designs (LQR, LQG, MPC)."""

    weights: Weights = setting(factory=Weights, doc="State and torque weights (see Weights).")
    elastic_reference: bool = setting(True, doc="Track the quasi-static deflection the reference "
                                                "acceleration causes instead of a straight beam "
                                                "(see DesignModel.reference_states).")
    residual_control: bool = setting(False, doc="Compute the gain (and the MPC's plan) on the design model "
                                                "with the default evaluation plant's residual modes and the "
                                                "design's weights (controllers.residual.residual_design), "
                                                "so the sampled loop is stable on every mode it models "
                                                "(the default of for_scenario, i.e. of compare, sweeps and "
                                                "the CLI); False: on the design modes alone (LQG: the "
                                                "design's gain padded with zeros), which the residual "
                                                "modes' spillover destabilises (issue 27). Gain-scheduled "
                                                "designs ignore it.")

    residual_modes: int | None = setting(None, kind=int, lo=1, hi=MAX_MODES,
                                         doc="Transverse modes of the model with residual modes (the LQG's "
                                             "filter when robust; the gain's with residual_control), from "
                                             "the design's modes to 20; None: those of the default "
                                             "evaluation plant (every mode below the sampling frequency, "
                                             "the first above it, at least three more than the design). "
                                             "compare() and sweeps set it to the evaluation plant's modes.")

    @classmethod
    def for_scenario(cls, scenario, **options) -> "LQSettings":
        """The scenario's defaults (see :meth:`ControllerSettings.for_scenario`) with
        ``residual_control = True``: the default designs are stable on the default evaluation
        plant's modes (issue 27).

        Parameters
        ----------
        scenario : object
            A :class:`hubbeam_ctrl.study.scenarios.Scenario`.
        **options
            Study-wide controller options (``horizon``, ``solver``...).
        """
        return super().for_scenario(scenario, **{"residual_control": True, **options})


# -- the interface ----------------------------------------------------------------------------
class Controller:
    """Base class of every controller: ``ctrl(t, y) -> tau``, ``ctrl.reset()``.

    Parameters
    ----------
    design : DesignModel
        The sampled linear SFOAM model (gives ``dt`` and ``n_modes``).
    settings : dataclass
        The controller's own frozen settings.
    reference : Reference, optional
        Hub trajectory and feedforward torque (none: regulate to rest at theta = 0).

    Attributes
    ----------
    name : str
        Short name used in tables (``"lqr"``...): the registry key, set by
        :func:`controllers.register_controller` unless the class sets its own.
    measurement : {"state", "sensors"}
        What the simulator hands over: the plant's SFOAM-ordered state, or the noisy
        sensors ``[theta, theta_dot, M_root]`` (see
        :func:`hubbeam_ctrl.sim.closedloop.simulate_closed_loop`).
    dt : float
        Sample time [s].
    n_modes : int
        Transverse modes of the design model (the evaluation plant's rule counts from them).
    state_modes : int
        Transverse modes read from the plant with ``measurement="state"`` (the design's, or
        those of the model with residual modes the gain was computed on).
    """

    name = "controller"
    measurement = "state"

    def __init__(self, design: DesignModel, settings, reference: Reference | None = None):
        if not isinstance(design, DesignModel):
            raise ParameterError(f"design must be a DesignModel, got {type(design).__name__}")
        if reference is None:
            reference = Reference.rest(design.dt)
        if not isinstance(reference, Reference):
            raise ParameterError(f"reference must be a Reference, got {type(reference).__name__}")
        if abs(reference.dt - design.dt) > 1e-12 * design.dt:
            raise ParameterError(f"reference.dt = {reference.dt:g} s differs from the design "
                                 f"model's dt = {design.dt:g} s")
        self.design = design
        self.settings = settings
        # a design that carries the hub's damping (a DC drive's back-EMF) is driven by the torque at rest
        self.reference = reference.with_hub_damping(design.hub_damping)
        self.dt = design.dt
        self.n_modes = design.n_modes
        self.state_modes = design.n_modes
        self.tau_max = torque_limit(getattr(settings, "tau_max", None), design.params)

    def _prepare_reference(self, elastic: bool, extra: int = 0) -> None:
        """Tabulate reference states and feedforward torques (plus ``extra`` samples)."""
        self._xref, self._tff = self._tabulate(self.reference, elastic, extra)

    def _tabulate(self, ref: "Reference", elastic: bool, extra: int = 0) -> tuple:
        """``(X, tau_ff)``: the design states and feedforward torques of ``ref`` at its samples plus
        ``extra`` more (held at its end)."""
        K = len(ref.theta) + extra + 1
        th, thd, tff = ref.window(0, K)
        X = np.zeros((K, self.design.n_x))
        X[: len(ref.theta)] = self._reference_states(ref, elastic)
        n = self.design.n_x // 2
        X[len(ref.theta):, 0] = th[len(ref.theta):]
        X[len(ref.theta):, n] = thd[len(ref.theta):]
        if elastic and len(ref.theta) > 1:      # hold the last deflection
            X[len(ref.theta):, 1:n] = X[len(ref.theta) - 1, 1:n]
        return X, np.asarray(tff, dtype=float)

    def _reference_states(self, reference: "Reference", elastic: bool) -> np.ndarray:
        """Reference states at the reference's samples (a scheduled controller overrides it)."""
        return self.design.reference_states(reference, elastic)

    def _reference_at(self, k: int):
        """``(x_ref, tau_ff)`` at sample ``k`` from the table (extended beyond its end)."""
        K = len(self._tff)
        if k < K:
            return self._xref[k], self._tff[k]
        x = self._xref[-1].copy()
        x[0] += x[self.design.n_x // 2] * (k - K + 1) * self.dt
        return x, self._tff[-1]

    def _reference_acting(self, k: int):
        """``(x_ref, tau_ff)`` where this sample's command acts: at ``k + delay`` (interpolated
        between samples ``k`` and ``k + 1``; sample ``k`` without a delay)."""
        d = self.design.delay
        if d == 0.0:
            return self._reference_at(k)
        x0, t0 = self._reference_at(k)
        x1, t1 = self._reference_at(k + 1)
        return (1.0 - d) * x0 + d * x1, (1.0 - d) * t0 + d * t1

    @property
    def signals(self):
        """The rig signals a sensor-reading controller reads, in order (None: the closed loop's
        default three)."""
        if self.measurement != "sensors" or self.design.sensors is None:
            return None
        return self.design.signals

    def reset(self) -> None:
        """Prepare a new run (clears estimator and solver memory)."""

    def __call__(self, t: float, y) -> float:
        """Hub torque [N m] at time ``t`` [s] from measurement ``y``."""
        raise NotImplementedError

    def applied(self, tau: float) -> None:
        """Record that ``tau``, not the torque just returned, was applied at this sample.

        A wrapper that overrides the output (:class:`controllers.payload_learning.PayloadLearning`
        playing a plan's feedforward) says so, and a controller with a filter predicts with it;
        one without memory of its torque ignores it.

        Parameters
        ----------
        tau : float
            The torque applied [N m].
        """

    def stats(self) -> dict:
        """Run statistics (e.g. QP fallbacks) since the last :meth:`reset`."""
        return {}

    def feedback_matrices(self) -> tuple:
        """``(Ac, Bc, Cc, Dc, state_names, input_names)`` of the linear feedback law.

        Implemented by the linear controllers (PD, LQR, LQG; MPC gives its unconstrained law);
        see :meth:`to_statespace`.

        Raises
        ------
        HubbeamError
            For a controller that is not linear and time-invariant (open loop, MPC).
        """
        raise HubbeamError(f"controller {self.name!r} is not a linear time-invariant feedback law; "
                           "only PD, LQR, LQG and (unconstrained) MPC can be given as a state-space system")

    def to_statespace(self):
        """The feedback law as a sampled python-control system with named signals.

        ``xc[k+1] = Ac xc[k] + Bc e[k]``, ``u[k] = Cc xc[k] + Dc e[k]``, sample time ``dt``:
        input ``e`` the measurement the controller reads (named like the design model's
        states or outputs: ``theta``, ``theta_dot``, ``root_moment``...; in deviation from
        the reference), output ``tau`` [N m] (the torque beyond the feedforward). The
        controller's own torque is ``tau_ff + u``, clipped at :attr:`tau_max`; this system
        is the unsaturated law, so a user can close loops and compute margins with
        python-control (``control.feedback(plant, ctrl.to_statespace(), sign=1)`` or
        ``control.interconnect`` by signal name).

        Returns
        -------
        control.StateSpace

        Raises
        ------
        HubbeamError
            For the open loop and the shaped profiles (no feedback law).
        """
        import control
        Ac, Bc, Cc, Dc, states, inputs = self.feedback_matrices()
        return control.ss(Ac, Bc, Cc, Dc, self.dt, states=list(states), inputs=list(inputs),
                          outputs=["tau"], name=self.name)

    def __repr__(self):
        return f"{type(self).__name__}(dt={self.dt:g}, n_modes={self.n_modes}, settings={self.settings!r})"
