"""Gain scheduling over the spin rate: LQR, LQG and MPC designed on a grid of spins.

The SFOAM bending frequencies rise with the spin rate (dynamic stiffening), so a design
made at one spin is wrong everywhere else on a spin-up. A :class:`DesignSchedule` holds
the sampled design models at a grid of spin rates (:mod:`controllers.design_schedule`);
the scheduled controllers interpolate, linearly in the spin rate (the end values outside the
grid), what they need from it:

* :class:`ScheduledLQR`: the gain ``K(Omega)``;
* :class:`ScheduledLQG`: the LQR gain, the Kalman gain and the prediction model
  ``(Ad, Bd)(Omega)``; it works in absolute coordinates (a steady rotation at any rate
  is a solution of every linear model of the grid). Like :class:`LQG`, with
  ``settings.robust`` (the default) the filter's models carry the residual modes
  (:mod:`controllers.residual`; one count for the whole grid, the largest
  :func:`~controllers.residual.estimator_modes` of its spins) and the LQR gains act on
  the design modes only;
* :class:`ScheduledMPC`: the condensed QP's Hessian and gradient (the prediction model is
  held over the horizon), and the fallback LQR gain.

Each scheduled class is the ``scheduled`` entry of its controller in the registry
(:mod:`controllers.registry`): ``make_controller("lqr", design, settings, reference,
schedule=DesignSchedule.for_scenario(scenario, 9))`` builds it with the same settings as
the fixed design (``LQRSettings.for_scenario``).

The scheduling variable is the measured hub rate (``variable="measured"``, default) or
the reference rate (``"reference"``). The elastic reference (the quasi-static deflection
of the reference acceleration) uses the model at the reference rate of each sample.

Interpolating the gains was measured against finer grids: on the spin-up to 3 rad/s in
10 s on the 5-mode FOAM, LQR leaves 0.851 %, 0.897 %, 0.909 % of the feedforward's residual
with 5, 9, 17 spins (the default 9 is within 1.5 % of the converged value; on the 10-mode
evaluation plant 0.890 % and 0.902 % with 9 and 17); the scheduling variable (measured or
reference rate) changes it by less than 0.2 %.

:func:`scheduled_lqr_iosystem` and :func:`scheduled_lqg_iosystem` give the same laws as
python-control ``NonlinearIOSystem`` objects, with the conventions of
``control.create_statefbk_iosystem``'s gain schedules: inputs ``[xd, ud, x]`` (or
``[xd, ud, y]`` for LQG), output ``u = ud - K(mu) (x - xd)``, the scheduling variables
``mu`` picked from the inputs by ``gainsched_indices`` (default: the desired hub rate).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from hubbeam_ctrl.core.errors import HubbeamError, ParameterError

from .base import DesignModel, Reference, Weights, check_positive, saturate, torque_limit

# the design grid lives in design_schedule; its names stay importable from here
from .design_schedule import DEFAULT_SCHEDULE_POINTS, MAX_SCHEDULE_POINTS, VARIABLES, DesignSchedule
from .estimator import KalmanEstimator, KalmanNoise
from .lqg import LQG, LQGSettings, filter_model
from .lqr import LQR, LQRSettings, dlqr_gain
from .mpc import MPC, MPCSettings
from .residual import embedding, estimator_modes

if TYPE_CHECKING:
    import control as ct

__all__ = ["DesignSchedule", "ScheduledKalmanEstimator", "filter_schedule", "ScheduledLQR", "ScheduledLQG",
           "ScheduledMPC", "scheduled_lqr_iosystem", "scheduled_lqg_iosystem", "DEFAULT_SCHEDULE_POINTS",
           "MAX_SCHEDULE_POINTS", "VARIABLES"]

def _check_schedule(schedule, variable):
    if not isinstance(schedule, DesignSchedule):
        raise ParameterError(f"schedule must be a DesignSchedule, got {type(schedule).__name__}")
    if variable not in VARIABLES:
        raise ParameterError(f"variable must be one of {', '.join(VARIABLES)}, got {variable!r}")


class _Scheduled:
    """What the scheduled controllers share: the schedule, the variable, the reference table."""

    def _init_schedule(self, schedule: DesignSchedule, variable: str):
        _check_schedule(schedule, variable)
        self.schedule = schedule
        self.variable = variable

    def _reference_states(self, reference, elastic):
        return self.schedule.reference_states(reference, elastic)

    def stats(self) -> dict:
        return {**super().stats(), "schedule_points": int(self.schedule.spins.size)}

    def feedback_matrices(self) -> tuple:
        """Not available: a gain-scheduled controller is not time-invariant."""
        raise HubbeamError(f"controller {self.name!r} is gain-scheduled over spin rates, not a linear "
                           "time-invariant feedback law")

    def _spin(self, k: int, measured_rate: float) -> float:
        """The scheduling variable at sample ``k`` [rad/s]."""
        if self.variable == "measured":
            return abs(float(measured_rate))
        return abs(float(self._reference_at(k)[0][self.design.n_x // 2]))


class ScheduledLQR(_Scheduled, LQR):
    """LQR with the gain interpolated in the spin rate: ``tau = sat(tau_ff - K(Omega) (x - x_ref))``.

    Parameters
    ----------
    schedule : DesignSchedule
    settings : LQRSettings, optional
    reference : Reference, optional
    variable : {"measured", "reference"}
        Scheduling variable: the measured hub rate or the reference rate.

    Attributes
    ----------
    gains : ndarray (S, nx)
        LQR gain at each spin of the schedule.
    """

    def __init__(self, schedule: DesignSchedule, settings: LQRSettings | None = None,
                 reference: Reference | None = None, variable: str = "measured"):
        self._init_schedule(schedule, variable)
        settings = (settings or LQRSettings()).replace(residual_control=False)   # per-point designs
        super().__init__(schedule.designs[0], settings, reference)
        self.gains = schedule.stack(lambda d: dlqr_gain(d, settings.weights)[0])

    def gain(self, spin: float) -> np.ndarray:
        """Interpolated gain at ``spin`` [rad/s].

        Parameters
        ----------
        spin : float
            Spin rate [rad/s].
        """
        return self.schedule.interpolate(self.gains, spin)

    def __call__(self, t: float, y) -> float:
        k = int(round(t / self.dt))
        xr, tff = self._reference_at(k)
        K = self.gain(self._spin(k, y[self.design.n_x // 2]))
        return saturate(float(self._ff * tff - K @ (y - xr)), self.tau_max)


class ScheduledKalmanEstimator:
    """Kalman filter with its gain and prediction model interpolated in the spin rate.

    The interface of :class:`~controllers.estimator.KalmanEstimator`, in absolute
    coordinates (a steady rotation at any rate is a solution of every linear model of the
    grid); :meth:`update` also takes the spin rate that schedules the gain and the next
    prediction: ``x_hat = x_pred + L(Omega) (y - C(Omega) x_pred)``, then
    ``x_pred+ = A(Omega) x_hat + B(Omega) u``. Each spin's filter is the plain LQG's
    (:class:`~controllers.estimator.KalmanEstimator`, or with ``disturbance_noise``
    :class:`~controllers.integral.OffsetFreeEstimator`) on that spin's design: on a rig
    (:meth:`DesignSchedule.on_rig`) its state is :func:`~controllers.filter_model.filter_matrices`'
    ``[x, u_prev, f, b, d]`` and it reads the rig's own sensors. ``C`` is scheduled too when it
    changes with the spin (a tip accelerometer's row holds the model's stiffness).

    Parameters
    ----------
    schedule : DesignSchedule
    noise : KalmanNoise
        Noise model of every design of the grid.
    design_modes : int, optional
        Transverse modes of the design models when the grid's models carry residual modes
        (see :meth:`~controllers.filter_model.KalmanNoise.covariances`).
    disturbance_noise : float, optional
        Random-walk standard deviation of an input disturbance state per sample [N m]
        (integral action, :class:`~controllers.integral.OffsetFreeEstimator`); None: none.

    Attributes
    ----------
    L : ndarray (S, nz, ny)
        Filter gain (measurement update) at each spin of the schedule.
    models : ndarray (S, nz, nz + 1)
        ``[A, B]`` at each spin.
    A, B, C : ndarray
        The filter's model at the grid's first spin.
    Cs : ndarray (S, ny, nz) or None
        The measurement rows at each spin; None when they do not change (``C`` is then used).
    x_pred, x_hat : ndarray (nz,)
        Prediction used by the last update, and the current estimate.
    """

    def __init__(self, schedule: "DesignSchedule", noise: KalmanNoise, design_modes: int | None = None,
                 disturbance_noise: float | None = None):
        from .integral import OffsetFreeEstimator
        self.schedule = schedule
        if disturbance_noise is None:
            filters = [KalmanEstimator(d, noise, design_modes) for d in schedule.designs]
        else:
            filters = [OffsetFreeEstimator(d, noise, disturbance_noise, design_modes) for d in schedule.designs]
        self.L = np.array([f.L for f in filters])
        self.models = np.array([np.hstack([f.A, f.B]) for f in filters])
        Cs = np.array([f.C for f in filters])
        self.A, self.B = filters[0].A, filters[0].B      # the grid's first spin (a drive's rate row reads A)
        self.C = self._C = Cs[0]
        self.Cs = None if np.array_equal(Cs, np.broadcast_to(Cs[0], Cs.shape)) else Cs
        self.reset()

    @property
    def n_z(self) -> int:
        """Number of filter states."""
        return self.models.shape[1]

    def reset(self, x0=None) -> None:
        """Start again from a state guess, with no measurement yet (the scheduling spin back to 0).

        Parameters
        ----------
        x0 : array_like (nx,), optional
            As :meth:`KalmanEstimator.reset <controllers.estimator.KalmanEstimator.reset>` (the
            states past its length, e.g. ``u_prev``, start at 0).
        """
        x = np.zeros(self.n_z)
        if x0 is not None:
            x0 = np.array(x0, dtype=float)
            x[:len(x0)] = x0
        self.x_pred = x
        self.x_hat = x
        self._spin = 0.0

    def predict(self, u: float) -> np.ndarray:
        """Prediction ``A(mu) x_hat + B(mu) u`` of the next sample's state (ndarray (nz,)) with the
        model at the last update's spin ``mu`` (the estimator is unchanged).

        Parameters
        ----------
        u : float
            Torque held over the coming sample [N m].
        """
        ab = self.schedule.interpolate(self.models, self._spin)
        return ab[:, :-1] @ self.x_hat + ab[:, -1] * u

    def update(self, y, u_prev: float | None, spin: float | None) -> np.ndarray:
        """Take one measurement at spin rate ``spin`` [rad/s] and return the new estimate.

        Parameters
        ----------
        y : ndarray (ny,)
            Measurement of the designs' signals (the beam alone's ``[theta, theta_dot, M_root]``),
            absolute.
        u_prev : float or None
            Torque held since the previous update [N m]; ``None`` right after :meth:`reset`.
        spin : float or None
            Scheduling variable [rad/s]; None: the magnitude of the prediction's hub rate (a rig
            without a rate sensor).

        Returns
        -------
        ndarray (nz,)
        """
        if u_prev is not None:
            self.x_pred = self.predict(u_prev)
        if spin is None:
            spin = abs(float(self.x_pred[self.schedule.n_x // 2]))
        self._spin = spin
        L = self.schedule.interpolate(self.L, spin)
        C = self._C if self.Cs is None else self.schedule.interpolate(self.Cs, spin)
        self.x_hat = self.x_pred + L @ (np.asarray(y, dtype=float) - C @ self.x_pred)
        return self.x_hat


def filter_schedule(schedule: DesignSchedule, settings: LQGSettings) -> tuple:
    """The Kalman filter's models over a schedule and the embedding of the design states in theirs.

    Parameters
    ----------
    schedule : DesignSchedule
    settings : LQGSettings
        With ``robust``, every model gets the same residual modes: ``residual_modes``, or
        the largest :func:`~controllers.residual.estimator_modes` over the grid.

    Returns
    -------
    DesignSchedule
        ``schedule`` itself when no mode is added.
    E : ndarray (nx_est, nx)
        ``x_est = E x_design`` (:func:`controllers.residual.embedding`).
    """
    n = settings.residual_modes
    if settings.robust and n is None:
        n = max(estimator_modes(d) for d in schedule.designs)
    models = tuple(filter_model(d, settings.replace(residual_modes=n)) for d in schedule.designs)
    if models[0] is schedule.designs[0]:
        return schedule, np.eye(schedule.n_x)
    return DesignSchedule(schedule.spins, models), embedding(schedule.n_modes, models[0].n_modes)


class ScheduledLQG(_Scheduled, LQG):
    """LQG with LQR gain, Kalman gain and prediction model interpolated in the spin rate.

    A :class:`ScheduledKalmanEstimator` (absolute coordinates) and
    ``tau = sat(tau_ff - K(Omega) (x_hat - x_ref))``; with ``settings.robust`` the
    estimator's models have the residual modes of :func:`filter_schedule`.

    On a rig (a schedule of :meth:`DesignSchedule.on_rig`, which
    :func:`controllers.registry.make_controller` gives it) the filter is the plain LQG's on each
    spin's design (the rig's own sensors; the previous command, the anti-alias filter, the rate
    sensor's bias and, with ``settings.integral``, the input disturbance as states) and the law is
    the plain LQG's where the command acts (:meth:`DesignModel.acting_state`):
    ``tau = sat(tau_ff(k + d) - K_z(Omega) z_hat + K(Omega) x_ref(k + d))`` with
    ``K_z = filter_gain(K)`` per spin (:func:`controllers.filter_model.filter_gain`), both
    interpolated in the spin. The measured spin is the rate sensor's, or without one the
    magnitude of the filter's predicted hub rate.

    Parameters
    ----------
    schedule : DesignSchedule
    settings : LQGSettings, optional
    reference : Reference, optional
    variable : {"measured", "reference"}
        The measured hub rate (the rate sensor) or the reference rate.

    Attributes
    ----------
    gains : ndarray (S, nz)
        Gain at each spin of the schedule on the filter's states (zero on residual modes; on a rig
        the gain on the whole filter state, :func:`~controllers.filter_model.filter_gain`).
    reference_gains : ndarray (S, nx_est)
        LQR gain at each spin on the filter model's states, which multiplies the reference.
    estimator : ScheduledKalmanEstimator
    """

    def __init__(self, schedule: DesignSchedule, settings: LQGSettings | None = None,
                 reference: Reference | None = None, variable: str = "measured"):
        from .filter_model import filter_gain
        self._init_schedule(schedule, variable)
        settings = (settings or LQGSettings()).replace(residual_control=False)   # per-point designs
        super().__init__(schedule.designs[0], settings, reference)
        models, self._E = filter_schedule(schedule, settings)
        self.filter_model = fm = models.designs[0]
        self._on_rig = fm.sensors is not None or fm.carries_loop or settings.integral
        disturbance = (settings.disturbance_noise_nm or 0.01 * self.tau_max) if settings.integral else None
        self.estimator = ScheduledKalmanEstimator(models, settings, schedule.n_modes, disturbance)
        if self.estimator.Cs is not None and not self._on_rig:
            self.estimator.Cs = None        # the beam alone's filter reads the first spin's rows (as ever)
        self.reference_gains = schedule.stack(lambda d: dlqr_gain(d, settings.weights)[0]) @ self._E.T
        self.gains = self.reference_gains
        if self._on_rig:
            self.gains = np.array([filter_gain(K[None, :], m, settings, settings.integral)[0]
                                   for K, m in zip(self.reference_gains, models.designs)])
        signals = list(fm.signals)
        self._rate_index = signals.index("theta_dot") if "theta_dot" in signals else None
        self._Ke = self.reference_gains[0]      # the loop at the grid's first spin (study.loop_poles)
        self.reset()

    def reset(self) -> None:
        """Start the estimator from the reference's first state; forget the last torque."""
        self.estimator.reset(self._E @ self._reference_at(0)[0])
        self._tau = None

    def __call__(self, t: float, y) -> float:
        """Hub torque [N m] at time ``t`` [s] from the sensors ``y`` (the beam alone's ``[theta, theta_dot,
        M_root]``, or the rig's :attr:`signals`)."""
        k = int(round(t / self.dt))
        if not self._on_rig:
            xr, tff = self._reference_at(k)
            spin = self._spin(k, y[1])
            x_hat = self.estimator.update(y, self._tau, spin)
            K = self.schedule.interpolate(self.gains, spin)
            self._tau = saturate(float(self._ff * tff - K @ (x_hat - self._E @ xr)), self.tau_max)
            return self._tau
        xr, tff = self._reference_acting(k)         # where the command acts (the rig's delay)
        if self.variable == "measured":
            spin = None if self._rate_index is None else abs(float(y[self._rate_index]))
        else:                                       # the reference rate where the command acts
            spin = abs(float(xr[self.design.n_x // 2]))
        z_hat = self.estimator.update(y, self._tau, spin)
        spin = self.estimator._spin
        u = (self.schedule.interpolate(self.gains, spin) @ z_hat
             - self.schedule.interpolate(self.reference_gains, spin) @ (self._E @ xr))
        self._tau = saturate(float(self._ff * tff - u), self.tau_max)
        return self._tau


class ScheduledMPC(_Scheduled, MPC):
    """MPC whose condensed QP (Hessian, gradient) and fallback gain are interpolated in the spin rate.

    The prediction model is the interpolated one, held over the horizon. The soft tip
    bound is not available with a schedule.

    Parameters
    ----------
    schedule : DesignSchedule
    settings : MPCSettings, optional
    reference : Reference, optional
    variable : {"measured", "reference"}
    """

    def __init__(self, schedule: DesignSchedule, settings: MPCSettings | None = None,
                 reference: Reference | None = None, variable: str = "measured"):
        self._init_schedule(schedule, variable)
        settings = (settings or MPCSettings()).replace(residual_control=False)   # per-point designs
        if settings.tip_bound is not None:
            raise ParameterError("tip_bound is not available with a schedule; set it to None")
        super().__init__(schedule.designs[0], settings, reference)
        parts = [self._condensed_qp(d) for d in schedule.designs]
        self.gains = np.array([p[0] for p in parts])
        self._Hs = np.array([p[2] for p in parts])
        self._Gxs = np.array([p[3] for p in parts])
        self._Grs = [p[4] for p in parts]
        self._ref_terms = [self._reference_terms(Gr) for Gr in self._Grs]

    def _qp_data(self, k: int, y: np.ndarray):
        spin = self._spin(k, y[self.design.n_x // 2])
        i, w = self.schedule.locate(spin)
        g_i = self._Gxs[i] @ y - self._reference_term(k, self._ref_terms[i], self._Grs[i])
        if w == 0.0:
            self.K = self.gains[i]
            return self._Hs[i], g_i
        g_j = self._Gxs[i + 1] @ y - self._reference_term(k, self._ref_terms[i + 1], self._Grs[i + 1])
        self.K = (1 - w) * self.gains[i] + w * self.gains[i + 1]
        return (1 - w) * self._Hs[i] + w * self._Hs[i + 1], (1 - w) * g_i + w * g_j


# -- python-control systems ---------------------------------------------------------------------------
def _labels(design: DesignModel):
    xd = [f"xd[{n}]" for n in design.state_names]
    return xd, ["ud[tau]"], list(design.state_names)


def _first_design(schedule: DesignSchedule) -> tuple:
    """The checked schedule's first design and its signal labels ``(xd, ud, x)``."""
    _check_schedule(schedule, "measured")
    d = schedule.designs[0]
    return d, _labels(d)


def _gainsched_indices(indices, inputs, default):
    if indices is None:
        return [default]
    idx = [indices] if isinstance(indices, (int, str, np.integer)) else list(indices)
    out = []
    for i in idx:
        if isinstance(i, str):
            if i not in inputs:
                raise ParameterError(f"gainsched_indices: unknown signal {i!r}")
            out.append(inputs.index(i))
        elif not isinstance(i, (int, np.integer)) or not 0 <= i < len(inputs):
            raise ParameterError(f"gainsched_indices must be signal names or indices in 0..{len(inputs) - 1}")
        else:
            out.append(int(i))
    if len(out) != 1:
        raise ParameterError("gainsched_indices must select exactly one signal (the spin rate)")
    return out


def scheduled_lqr_iosystem(schedule: DesignSchedule, weights: Weights = Weights(), tau_max: float | None = None,
                           gainsched_indices=None, name: str = "scheduled_lqr") -> ct.NonlinearIOSystem:
    """The scheduled LQR as a python-control ``NonlinearIOSystem`` (no states).

    Inputs ``[xd, ud, x]`` (desired state, desired torque, state), output
    ``u = ud - K(mu) (x - xd)`` (clipped to ``+-tau_max`` if given), as
    ``control.create_statefbk_iosystem(sys, (gains, spins), ...)``; linear interpolation in
    ``mu``, the end gains outside the grid.

    Parameters
    ----------
    schedule : DesignSchedule
    weights : Weights
    tau_max : float, optional
        Torque limit [N m].
    gainsched_indices : int or str, optional
        The input that schedules the gain (default ``"xd[theta_dot]"``; ``"theta_dot"``: the
        measured rate).
    name : str
        Name of the system.

    Returns
    -------
    control.NonlinearIOSystem
    """
    import control as ct  # lazily: keeps the CLI's start-up light
    d, (xd, ud, x) = _first_design(schedule)
    inputs = xd + ud + x
    (mu_index,) = _gainsched_indices(gainsched_indices, inputs, inputs.index("xd[theta_dot]"))
    gains = schedule.stack(lambda dm: dlqr_gain(dm, weights)[0])
    nx = d.n_x
    limit = math.inf if tau_max is None else check_positive("tau_max", tau_max, "N m")

    def output(t, states, u, params):
        K = schedule.interpolate(gains, abs(u[mu_index]))
        return np.array([np.clip(u[nx] - K @ (u[nx + 1:] - u[:nx]), -limit, limit)])

    return ct.NonlinearIOSystem(None, output, inputs=inputs, outputs=["tau"], name=name,
                                dt=schedule.dt)


def scheduled_lqg_iosystem(schedule: DesignSchedule, settings: LQGSettings = LQGSettings(),
                           gainsched_indices=None, name: str = "scheduled_lqg") -> ct.NonlinearIOSystem:
    """The scheduled LQG as a discrete-time python-control ``NonlinearIOSystem``.

    State: the predicted state ``x_pred``. Inputs ``[xd, ud, y]`` with ``y = [theta,
    theta_dot, M_root]``; output ``u = sat(ud - K(mu) (x_hat - xd))`` with ``x_hat = x_pred +
    L(mu) (y - C x_pred)``; update ``x_pred+ = Ad(mu) x_hat + Bd(mu) u`` (as
    :class:`ScheduledLQG`, with the residual modes of :func:`filter_schedule` if
    ``settings.robust``).

    Parameters
    ----------
    schedule : DesignSchedule
    settings : LQGSettings
        Weights, noise levels and ``tau_max``.
    gainsched_indices : int or str, optional
        Default ``"xd[theta_dot]"``; ``"y[theta_dot]"``: the measured rate.
    name : str
        Name of the discrete-time system (sampled at ``schedule.dt``).

    Returns
    -------
    control.NonlinearIOSystem
    """
    import control as ct  # lazily: keeps the CLI's start-up light
    d, (xd, ud, _) = _first_design(schedule)
    inputs = xd + ud + ["y[theta]", "y[theta_dot]", "y[root_moment]"]
    (mu_index,) = _gainsched_indices(gainsched_indices, inputs, inputs.index("xd[theta_dot]"))
    models, E = filter_schedule(schedule, settings)
    K = schedule.stack(lambda dm: dlqr_gain(dm, settings.weights)[0]) @ E.T
    L = models.stack(lambda dm: KalmanEstimator(dm, settings, schedule.n_modes).L)
    AB = models.stack(lambda dm: np.hstack([dm.Ad, dm.Bd]))
    C, nx = models.designs[0].C_sensors, d.n_x
    tau_max = torque_limit(settings.tau_max, d.params)

    def law(states, u):
        mu = abs(u[mu_index])
        x_hat = states + schedule.interpolate(L, mu) @ (u[nx + 1:] - C @ states)
        tau = saturate(float(u[nx] - schedule.interpolate(K, mu) @ (x_hat - E @ u[:nx])), tau_max)
        return x_hat, tau, mu

    def update(t, states, u, params):
        x_hat, tau, mu = law(states, u)
        ab = schedule.interpolate(AB, mu)
        return ab[:, :-1] @ x_hat + ab[:, -1] * tau

    def output(t, states, u, params):
        return np.array([law(states, u)[1]])

    return ct.NonlinearIOSystem(update, output, inputs=inputs, outputs=["tau"],
                                states=[f"xpred[{n}]" for n in models.designs[0].state_names], name=name,
                                dt=schedule.dt)
