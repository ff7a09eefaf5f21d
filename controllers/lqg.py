"""LQG: the LQR gain on a steady-state Kalman filter fed by realistic hub and root sensors.

By default (``robust=True``) the filter's model carries the beam's residual modes (see
:mod:`controllers.residual` and docs/controllers.md): a filter on the design modes alone
destabilises the modes it leaves out through the root-moment sensor.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.core.settings import setting

from .analysis import grid_disk_margin
from .base import Controller, DesignModel, LQSettings, Reference, saturate
from .estimator import (
    AppliedTorque,
    KalmanEstimator,
    KalmanNoise,
    plan_offsets,
    plan_worth_predicting,
)
from .filter_model import filter_gain, filter_state_names
from .integral import OffsetFreeEstimator, observer_feedback_matrices
from .lqr import dlqr_gain
from .residual import embedding, estimator_model, residual_design

__all__ = ["LQGSettings", "LQG", "noise_tip_std", "noise_stds", "noise_limited_decay", "quiet_process_noise",
           "DECAY_LADDER", "COMMAND_NOISE_SHARE", "NOISE_SHARE_OF_BAND", "STEP_NOISE_SHARE", "PROCESS_NOISE_LADDER",
           "MARGIN_KEPT"]


@dataclass(frozen=True)
class LQGSettings(KalmanNoise, LQSettings):
    """Settings of :class:`LQG`: those of LQR, the Kalman filter's noise model and its model's modes.

    The sensor noise levels are what the filter assumes; they default to the closed-loop
    simulator's :class:`hubbeam_ctrl.plant.sensors.SensorSettings`.
    """

    robust: bool = setting(True, doc="Model the residual modes in the filter (controllers.residual); "
                                     "False: the filter on the design model alone, which the modes it "
                                     "leaves out destabilise.")
    integral: bool = setting(False, doc="Integral action: the filter also estimates a constant input "
                                        "disturbance torque, which the command cancels (offset-free control, "
                                        "controllers.integral); the default on rigs with friction.")
    disturbance_noise_nm: float | None = setting(None, unit="N m", lo=0.0, lo_open=True, kind=float,
                                                 doc="Random-walk standard deviation per sample of the "
                                                     "disturbance the integral action estimates; None: 1 % "
                                                     "of the torque limit.")
    plan_prediction: bool | None = setting(None, kind=bool,
                                           doc="The filter predicts along the reference: x_pred = x_ref[k+1] "
                                               "+ A (x_hat - x_ref[k]) + B (u - u_ff[k]), so the model's "
                                               "error along a planned slew does not enter the estimate; "
                                               "None: when the reference plans the beam's motion on "
                                               "the nonlinear model (Reference.elastic, "
                                               "reference='optimal') and elastic_reference is on; "
                                               "not along a plan of the design model itself "
                                               "(Reference.planned_on_design), which the filter's "
                                               "own prediction follows.")
    tip_noise_budget_m: float | None = setting(None, unit="m", lo=0.0, lo_open=True, kind=float,
                                               doc="Derive the filter's error_decay from the sensor noise: "
                                                   "the fastest of DECAY_LADDER whose noise-driven tip "
                                                   "standard deviation stays within this budget "
                                                   "(noise_limited_decay; the design replaces error_decay "
                                                   "with it and this with None); None: error_decay as "
                                                   "given; ignored with integral action, without "
                                                   "residual modes (robust=False) and by the gain-scheduled "
                                                   "LQG (controllers.schedule). for_scenario sets "
                                                   "NOISE_SHARE_OF_BAND of the task's tip band (issue 22).")

    @classmethod
    def for_scenario(cls, scenario, **options) -> "LQGSettings":
        """The scenario's defaults (see :meth:`LQSettings.for_scenario`) with the filter's decay
        to be derived from the sensor noise by the design (:attr:`tip_noise_budget_m`, a sixth of
        the task's tip band) unless ``error_decay`` is given. The design derives it with the
        noise it is finally given (a rig's encoder, :func:`hubbeam_ctrl.study.rig_loop.rig_noise`)
        and only for a robust filter without integral action.

        Parameters
        ----------
        scenario : object
            A :class:`hubbeam_ctrl.study.scenarios.Scenario` (read also: ``bands``).
        **options
            Study-wide controller options.
        """
        st = super().for_scenario(scenario, **options)
        band = (getattr(scenario, "bands", None) or {}).get("settle_tip")
        given = "error_decay" in options or "error_decay" in (getattr(scenario, "defaults", None) or {})
        if given or not band or st.tip_noise_budget_m is not None:
            return st
        return dataclasses.replace(st, tip_noise_budget_m=NOISE_SHARE_OF_BAND * band)


def filter_model(design: DesignModel, settings: LQGSettings) -> DesignModel:
    """The model the Kalman filter of an LQG runs on: with residual modes if ``settings.robust``.

    Parameters
    ----------
    design : DesignModel
        The design model of the state feedback.
    settings : LQGSettings

    Returns
    -------
    DesignModel
        :func:`controllers.residual.estimator_model` of ``design``, or ``design`` itself.
    """
    return estimator_model(design, settings.residual_modes) if settings.robust else design


#: Candidate filter decays (x w_1) of the derived default, slowest first (issue 22: the paper's
#: beam's LQG tracks its LQR at 0.7-1.0; the link beam's rate-gyro noise allows only 0.3).
DECAY_LADDER = (0.3, 0.5, 0.7, 1.0)

#: The noise-driven command's standard deviation may use this share of the torque limit (six of
#: them within the quarter of the limit the reference leaves the feedback): a faster filter that
#: needs more chatters at the limits (measured on ``space_boom``: 0.7 left the wheels at their
#: limit 29 s of a 226 s run, disk margin 0.14).
COMMAND_NOISE_SHARE = 0.25 / 6.0
#: The noise-driven command's change from one sample to the next (its standard deviation) may use
#: this share of the torque limit: five of them within a tenth of the limit per sample (issue 36:
#: Table 1's LQG stepped by 21.5 N m in a sample, a 4.6-sigma peak of its sensor noise).
STEP_NOISE_SHARE = 0.1 / 5.0
#: Scales of the filter's process noise (``torque_noise_nm``, ``modal_noise``,
#: ``modal_rate_noise``), the default first: :func:`quiet_process_noise` takes the first whose
#: noise-driven command step is within :data:`STEP_NOISE_SHARE` of the torque limit.
PROCESS_NOISE_LADDER = (1.0, 0.7, 0.5, 0.35, 0.25)
#: A quieter filter may keep no less than this share of the default filter's disk margin.
MARGIN_KEPT = 0.9
#: Share of the task's tip band (``Tolerances.settle_tip`` L) that the tip's noise-driven standard
#: deviation may use (6 sigma within the band).
NOISE_SHARE_OF_BAND = 1.0 / 6.0


def noise_stds(ctrl: "LQG") -> tuple:
    """Standard deviations of the tip deflection [m] and of the command [N m] that the sensor noise
    alone drives in the loop.

    The LQG's filter and gain (:meth:`LQG.feedback_matrices`) closed with its design model (the
    filter's residual modes stay in the controller), white sensor noise at the filter's assumed
    levels (``angle_noise_rad``, ``rate_noise_rad_s``, ``moment_noise_nm`` per sample): the
    stationary covariance from a discrete Lyapunov equation.

    Parameters
    ----------
    ctrl : LQG

    Returns
    -------
    tuple of float
        ``sqrt(c_tip P c_tip')`` [m], the command's ``sqrt(c_u P c_u' + Dc R Dc')`` [N m] and
        its change from one sample to the next, ``std(u_k - u_(k-1))`` [N m]; all inf if that
        loop is not stable.
    """
    import scipy.linalg as sla

    Ac, Bc, Cc, Dc, _, inputs = ctrl.feedback_matrices()
    model = ctrl.design
    if model.sensors is None and model.delay == 0.0:
        A, B, C = model.Ad, model.Bd, model.C_sensors
    else:                                   # the rig's sensors and delay: the previous command is a state
        from .loop_plant import rig_plant
        A, B, C = rig_plant(model, inputs)
    closed = np.block([[A + B @ Dc @ C, B @ Cc], [Bc @ C, Ac]])
    if np.max(np.abs(np.linalg.eigvals(closed))) >= 1.0:
        return math.inf, math.inf, math.inf
    R = ctrl.settings.sensor_covariance(model)
    Bv = np.vstack([B @ Dc, Bc])
    P = sla.solve_discrete_lyapunov(closed, Bv @ R @ Bv.T)
    c = np.concatenate([model.C_tip[0], np.zeros(A.shape[0] - model.n_x + Ac.shape[0])])
    cu = np.hstack([Dc @ C, Cc])[0]
    du = Dc[0]
    u_var = float(cu @ P @ cu) + float(du @ R @ du)
    # u_k - u_(k-1): the lag-one covariance of u is cu Acl P cu' + cu Bv R du' (white noise)
    lag = float(cu @ closed @ P @ cu) + float(cu @ Bv @ R @ du)
    return (math.sqrt(max(float(c @ P @ c), 0.0)), math.sqrt(max(u_var, 0.0)),
            math.sqrt(max(2.0 * (u_var - lag), 0.0)))


def noise_tip_std(ctrl: "LQG") -> float:
    """Standard deviation of the tip deflection [m] that the sensor noise alone drives in the loop
    (:func:`noise_stds`).

    Parameters
    ----------
    ctrl : LQG

    Returns
    -------
    float
        [m]; inf if the loop is not stable.
    """
    return noise_stds(ctrl)[0]





def noise_limited_decay(design: DesignModel, settings: "LQGSettings", budget_m: float) -> float:
    """The fastest filter decay of :data:`DECAY_LADDER` that the sensor noise allows.

    Parameters
    ----------
    design : DesignModel
        The LQG's design model.
    settings : LQGSettings
        Its settings (``error_decay`` is replaced by each candidate in turn).
    budget_m : float
        The tip's noise budget [m] (> 0), e.g. :attr:`LQGSettings.tip_noise_budget_m`.

    Returns
    -------
    float
        The last candidate, in ladder order, whose :func:`noise_tip_std` is within ``budget_m``
        and whose command noise and command step noise are within :data:`COMMAND_NOISE_SHARE`
        and :data:`STEP_NOISE_SHARE` of the torque limit (the ladder stops at the first that is
        not); the first candidate if none is.

    Notes
    -----
    A faster filter forgets the slew's model error sooner but passes more sensor noise to the
    torque. Measured (std / tip band at 0.3 / 0.5 / 0.7 / 1.0, 1.5 x T_opt slews, defaults):
    Table 1's beam 0.089 / 0.090 / 0.091 / 0.093, so 1.0 (its Eq. 44 slew 0.32 / 0.31 / 0.29 /
    0.29, so 0.3); the 1 m lab arm 0.12 / 0.20 / 0.26 / 0.27, so 0.3; the servo link's beam 0.31 /
    0.33 / 0.33 / 0.40, so 0.3; the servo_link rig with its encoder 0.20 / 0.19 / 0.19 / 0.18, so
    0.3.
    """
    best = DECAY_LADDER[0]
    for decay in DECAY_LADDER[1:]:
        trial = LQG(design, dataclasses.replace(settings, error_decay=decay, tip_noise_budget_m=None))
        tip, command, step = noise_stds(trial)
        if not (tip <= budget_m and command <= COMMAND_NOISE_SHARE * trial.tau_max
                and step <= STEP_NOISE_SHARE * trial.tau_max):
            break
        best = decay
    return best


def quiet_process_noise(design: DesignModel, settings: "LQGSettings") -> "LQGSettings":
    """The filter's process noise scaled down until its sensor noise moves the command by at most
    :data:`STEP_NOISE_SHARE` of the torque limit per sample (a standard deviation).

    Parameters
    ----------
    design : DesignModel
        The LQG's design model.
    settings : LQGSettings
        Its settings, with the filter decay the ladder is judged at (``error_decay``).

    Returns
    -------
    LQGSettings
        ``settings`` with ``torque_noise_nm``, ``modal_noise`` and ``modal_rate_noise`` times the
        first scale of :data:`PROCESS_NOISE_LADDER` that meets the share (the quietest if none
        does) or, when that one's disk margin (:func:`controllers.analysis.grid_disk_margin`)
        falls below :data:`MARGIN_KEPT` of the default's, the quietest louder scale that keeps it:
        ``settings`` itself when the default meets the share or no quieter scale keeps the margin.

    Notes
    -----
    The process noise is how little the filter trusts its model: more of it, more of each
    measurement's noise in the estimate and, through the gain, in the command. The decay ladder
    (:func:`noise_limited_decay`) barely moves the step noise (Table 1's beam, default slew:
    std(du) 4.67 / 4.58 / 4.52 N m at 0.3 / 0.2 / 0.1 w_1); the process noise does (4.67 at the
    default scale, 4.08 with a tenth of the torque noise, 3.75 with a tenth of the modal noise).
    A filter that trusts its model more is slower and, with a tip accelerometer and no tachometer,
    costs margin: ``accel_link``'s disk margin 0.51 / 0.36 / 0.26 / 0.20 / 0.16 along the ladder
    (Table 1's 0.86 / 0.83 / 0.82 / 0.81 / 0.82), so that rig keeps the default.
    """
    def scaled(scale):
        rate = settings.modal_noise if settings.modal_rate_noise is None else settings.modal_rate_noise
        return dataclasses.replace(settings, torque_noise_nm=scale * settings.torque_noise_nm,
                                   modal_noise=scale * settings.modal_noise, modal_rate_noise=scale * rate)

    def trial(candidate):
        return LQG(design, dataclasses.replace(candidate, tip_noise_budget_m=None))

    first = trial(settings)
    limit = STEP_NOISE_SHARE * first.tau_max
    if noise_stds(first)[2] <= limit:
        return settings
    # the first rung within the limit (the quietest if none is), then back up the ladder to the
    # first that keeps the margin: the step noise falls and the margin mostly falls along it
    rungs = [(scale, scaled(scale)) for scale in PROCESS_NOISE_LADDER[1:]]
    laws = {}
    pick = len(rungs) - 1
    for i, (_, candidate) in enumerate(rungs):
        laws[i] = trial(candidate)
        if noise_stds(laws[i])[2] <= limit:
            pick = i
            break
    floor = MARGIN_KEPT * grid_disk_margin(first)
    for i in range(pick, -1, -1):
        if grid_disk_margin(laws.get(i) or trial(rungs[i][1])) >= floor:
            return rungs[i][1]
    return settings


class LQG(AppliedTorque, Controller):
    """Output feedback: a :class:`KalmanEstimator` on ``[theta, theta_dot, M_root]`` and the LQR gain.

    The filter works in deviations from the steady rotation at the design spin ``Omega``:
    ``x - [Omega t, 0, Omega, 0]``. Each call updates the estimate with the measurement
    (after predicting with the torque applied since the last call) and returns
    ``tau = sat(tau_ff - K (x_hat - x_ref))``. Along a planned reference (an optimal slew,
    ``settings.plan_prediction``) the prediction follows the plan,
    ``x_ref[k+1] + A (x_hat - x_ref[k]) + B (u - u_ff[k])``: the plan comes from the
    nonlinear model, so the linear model's error along the slew does not enter the estimate.
    With ``settings.robust`` the filter's model (:attr:`filter_model`) has the residual modes of
    :func:`controllers.residual.estimator_modes` and, with ``settings.residual_control``, the
    gain acting on the estimate is the LQR gain of that model (:attr:`K` stays the design
    model's, for reports).

    Parameters
    ----------
    design : DesignModel
        Sampled SFOAM at the design spin rate.
    settings : LQGSettings, optional
        LQR settings plus the filter's noise model.
    reference : Reference, optional
        Hub trajectory and feedforward torque (default: rest at theta = 0).

    Attributes
    ----------
    K : ndarray (nx,)
        LQR gain on the design model.
    P : ndarray (nx, nx)
        LQR Riccati solution.
    filter_model : DesignModel
        The filter's model (``design`` itself unless residual modes are added).
    estimator : KalmanEstimator
        The state estimator on :attr:`filter_model` (gain ``estimator.L``, (nx_est, 3)).
    """

    measurement = "sensors"

    def __init__(self, design: DesignModel, settings: LQGSettings | None = None,
                 reference: Reference | None = None):
        settings = settings or LQGSettings()
        if isinstance(settings, LQGSettings) and settings.tip_noise_budget_m is not None:
            # the rule is the robust filter's without integral action; the others keep error_decay
            if settings.robust and not settings.integral:
                settings = quiet_process_noise(design, dataclasses.replace(settings, error_decay=DECAY_LADDER[0]))
                decay = noise_limited_decay(design, settings, settings.tip_noise_budget_m)
            else:
                decay = settings.error_decay
            settings = dataclasses.replace(settings, error_decay=decay, tip_noise_budget_m=None)
        super().__init__(design, settings, reference)
        self.K, self.P = dlqr_gain(design, settings.weights)
        self.filter_model = filter_model(design, settings)
        if settings.integral:
            noise_d = settings.disturbance_noise_nm or 0.01 * self.tau_max
            self.estimator = OffsetFreeEstimator(self.filter_model, settings, noise_d, design.n_modes)
        else:
            self.estimator = KalmanEstimator(self.filter_model, settings, design.n_modes)
        self._E = embedding(design.n_modes, self.filter_model.n_modes)
        self._ff = 1.0 if settings.feedforward else 0.0
        self._n = self.filter_model.n_x // 2
        self._prepare_reference(settings.elastic_reference)
        self._Ke = self.K @ self._E.T
        self._xref_filter = None
        if settings.residual_control and self.filter_model is not design:
            model, weights = residual_design(design, settings.weights, self.filter_model.n_modes)
            self._Ke = dlqr_gain(model, weights)[0]
            # the residual modes' own quasi-static deflection along the reference
            self._xref_filter = self.filter_model.reference_states(self.reference, settings.elastic_reference)
        self._defect = self._plan_defect() if self.predicts_along_plan else None
        self.reset()

    @property
    def predicts_along_plan(self) -> bool:
        """Whether the filter predicts along the reference (``settings.plan_prediction``)."""
        if self.settings.plan_prediction is not None:
            return bool(self.settings.plan_prediction)
        return plan_worth_predicting(self.reference, self.settings.elastic_reference)

    def _filter_reference(self, k: int) -> np.ndarray:
        """The reference state at sample ``k`` on the filter's model."""
        table = self._xref_filter
        return table[k] if table is not None and k < len(table) else self._E @ self._reference_at(k)[0]

    def _plan_defect(self) -> np.ndarray:
        """:func:`~controllers.estimator.plan_offsets` of the reference table on the filter's model."""
        table = self._xref_filter
        X = np.array([table[k] if table is not None and k < len(table) else self._E @ self._xref[k]
                      for k in range(len(self._tff))])
        return plan_offsets(self.filter_model, X, self._ff * self._tff)

    @property
    def L(self) -> np.ndarray:
        """Kalman filter gain (nx_est, 3) of the estimator."""
        return self.estimator.L

    @property
    def x_hat(self) -> np.ndarray:
        """Current state estimate (deviation from the steady rotation, filter model's states)."""
        return self.estimator.x_hat

    @property
    def x_pred(self) -> np.ndarray:
        """Prediction of the state at the next sample (the initial guess after :meth:`reset`; without
        the plan's offset of ``plan_prediction``)."""
        return self.estimator.x_pred if self._tau is None else self.estimator.predict(self._tau)

    def reset(self) -> None:
        """Start the estimator from the reference's first state; forget the last torque."""
        x, _ = self._reference_at(0)
        x = self._E @ x
        x[self._n] -= self.design.spin
        self.estimator.reset(x)
        self._tau = None

    def start_estimate(self, x_hat, tau: float) -> None:
        """Start the filter from an estimate at this sample and the torque applied at it.

        Parameters
        ----------
        x_hat : array_like
            State estimate ``[theta, q2, theta_dot, q2_dot]`` (deviation from the steady rotation)
            [rad, m, rad/s, m/s]; its modes are the first of the filter's (more are dropped, fewer
            padded with 0: the assumed modes do not depend on their number).
        tau : float
            Torque applied at this sample [N m]; the next call predicts with it.
        """
        x = np.asarray(x_hat, dtype=float)
        m, n = len(x) // 2, self._n
        k = min(m, n)
        start = np.zeros(self.estimator.x_hat.shape)
        start[:k], start[n:n + k] = x[:k], x[m:m + k]
        self.estimator.reset(start)
        self._tau = float(tau)

    def feedback_matrices(self) -> tuple:
        """The filter and gain as one system, sensors -> torque (state: the prediction).

        On the filter's model ``(A, B, C)`` (:attr:`filter_model`), with ``K`` the gain on its
        states: ``x_hat = (I - L C) x_pred + L y``, ``u = -K x_hat``, ``x_pred+ = A x_hat + B u``,
        so ``Ac = (A - B K)(I - L C)``, ``Bc = (A - B K) L``, ``Cc = -K (I - L C)``,
        ``Dc = -K L``.
        """
        fm = self.filter_model
        K = filter_gain(self._Ke[None, :], fm, self.settings, self.settings.integral)
        states = filter_state_names(fm, self.settings, self.settings.integral)
        est = self.estimator
        return (*observer_feedback_matrices(est.A, est.B, est.C, self.L, K), states, self.design.sensor_labels)

    def __call__(self, t: float, y) -> float:
        """Hub torque [N m] at time ``t`` [s] from the sensors ``y = [theta, theta_dot, M_root]``."""
        spin = self.design.spin
        k = int(round(t / self.dt))
        fm = self.filter_model
        yd = fm.sensor_deviation(y, t)
        D = self._defect
        offset = D[k - 1] if D is not None and 0 < k <= len(D) else None
        x_hat = self.estimator.update(yd, self._tau, offset)
        x_act = fm.acting_state(x_hat, x_hat[-1] if self.settings.integral else 0.0)
        K = self._Ke
        d = fm.delay
        xr = self._filter_reference(k) if d == 0.0 else \
            (1.0 - d) * self._filter_reference(k) + d * self._filter_reference(k + 1)
        tff = self._reference_acting(k)[1]
        t_act = t + d * self.dt
        # x_act is a deviation from the steady rotation; x_ref is absolute
        u = K @ (x_act - xr) + K[0] * spin * t_act + K[self._n] * spin
        if self.settings.integral:
            u += x_hat[-1]                      # cancel the estimated disturbance torque
        self._tau = saturate(float(self._ff * tff - u), self.tau_max)
        return self._tau
