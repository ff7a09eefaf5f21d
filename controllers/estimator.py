"""State estimation for output feedback: the steady-state Kalman filter as a component.

:class:`KalmanEstimator` is built once from the design model and a :class:`KalmanNoise`
model and then fed one measurement per sample::

    est = KalmanEstimator(design, KalmanNoise())
    est.reset(x0)
    x_hat = est.update(y, u_prev)      # predict with the torque held since the last sample,
                                       # then correct with the measurement y

The gain comes from :func:`control.dlqe`'s Riccati solution (the a-priori covariance);
the filter is written in its measurement-update form, so ``x_hat`` already uses ``y``.

By default the filter has a **prescribed degree of stability** (the dual of the LQR with a
prescribed degree of stability; Anderson and Moore treat both): the Riccati equation is
solved for the model ``A exp(sigma dt)`` with
``sigma = error_decay * w_1`` (:attr:`KalmanNoise.error_decay`, ``w_1`` the first flexible
mode of the filter's model, free hub), so every pole of the estimation error
``A (I - L C)`` lies within ``exp(-sigma dt)``: the model error of a fast slew dies out at
least at ``sigma``, whatever the noise model. The plain Kalman filter left a pole near the
hub-clamped frequency (the zero of torque to hub angle) at nearly the structure's own damping:
on the 0.381 m servo link 3.0 Hz with 4.6 % damping with the task's noise levels
(:func:`filter_poles`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.settings import Settings, setting
from hubbeam_ctrl.plant.sensors import SensorSettings

from .base import DesignModel, check_psd
from .riccati import dlqe
from .scaling import first_mode
from .sensing import with_anti_alias

__all__ = ["KalmanNoise", "KalmanEstimator", "kalman_gain", "solve_kalman", "filter_matrices", "error_decay_rate",
           "decay_model", "estimates_rate_bias", "filter_state_names", "filter_gain", "filter_poles",
           "extra_state_gains",
           "plan_offsets", "plan_worth_predicting"]

#: The sensors' own specification: the filter's assumed sensor noise defaults to it.
_SENSORS = SensorSettings()


@dataclass(frozen=True)
class KalmanNoise(Settings):
    """Noise model of the Kalman filter: sensor noise it assumes and process noise.

    The sensor noise levels default to the simulator's sensors
    (:class:`hubbeam_ctrl.plant.sensors.SensorSettings`).
    """

    angle_noise_rad: float = setting(_SENSORS.angle_noise_rad, unit="rad", lo=0.0, lo_open=True,
                                     doc="Assumed hub-angle sensor noise, standard deviation.")
    rate_noise_rad_s: float = setting(_SENSORS.rate_noise_rad_s, unit="rad/s", lo=0.0, lo_open=True,
                                      doc="Assumed hub-rate sensor noise, standard deviation.")
    moment_noise_nm: float = setting(_SENSORS.moment_noise_nm, unit="N m", lo=0.0, lo_open=True,
                                     doc="Assumed root-moment sensor noise, standard deviation.")
    torque_noise_nm: float = setting(1.0, unit="N m", lo=0.0, lo_open=True,
                                     doc="Process noise: white torque disturbance at the hub, standard "
                                         "deviation per sample (stands for model error: FOAM's "
                                         "stiffening and Q_theta, the axial modes). Until the residual "
                                         "modes came, 5 N m; 1 N m halves the tip motion the sensor "
                                         "noise causes (docs/controllers.md).")
    modal_noise: float = setting(1e-5, unit="m or m/s", lo=0.0,
                                 doc="Process noise on each modal coordinate and rate per sample, "
                                     "standard deviation (until the residual modes came, 1e-4).")
    modal_rate_noise: float | None = setting(None, unit="m/s", lo=0.0, kind=float,
                                             doc="Process noise on each modal rate per sample; None: "
                                                 "modal_noise.")
    residual_noise: float = setting(0.3, lo=0.0, lo_open=True, hi=1.0,
                                    doc="Process noise on the residual modes of the filter's model (those "
                                        "beyond the design's), relative to modal_noise and "
                                        "modal_rate_noise: the filter keeps them in its model without "
                                        "trusting its model of them more than the sensors (measured: "
                                        "0.36 % of the open loop's residual on the paper's beam against "
                                        "4.2 % at 1; the 1 m arm's tip 1.5e-4 m against 3.5e-4 m at 0.01).")
    accel_noise_m_s2: float = setting(0.05, unit="m/s^2", lo=0.0, lo_open=True,
                                      doc="Assumed tip-accelerometer noise, standard deviation (a rig's "
                                          "sensors.accel_noise replaces it).")
    rate_bias_walk: float | None = setting(None, unit="rad/s/sqrt(s)", lo=0.0, kind=float,
                                           doc="Random walk of the rate sensor's bias (a gyro's drift); a "
                                               "value (0 for a constant bias) makes the filter estimate "
                                               "the bias as a state (filter_matrices), None: the rate "
                                               "sensor has no bias. A rig's sensors.rate_bias or "
                                               "rate_bias_walk sets it (study.rig_loop.rig_noise).")
    model_error: np.ndarray | None = setting(None, kind=object,
                                             doc="Extra process-noise covariance for model error (n_x x n_x "
                                                 "of the filter's model, symmetric positive semidefinite), "
                                                 "e.g. the spread of the models over a payload range "
                                                 "(controllers.robust.model_error_covariance); None: none.")
    error_decay: float = setting(0.3, lo=0.0, hi=2.0,
                                 doc="Prescribed degree of stability of the filter, relative to the first "
                                     "flexible mode's natural frequency w_1 of its model: every pole of the "
                                     "estimation error decays at least at error_decay * w_1 (the Riccati "
                                     "equation is solved for A exp(error_decay w_1 dt)); 0: the plain Kalman "
                                     "filter. At 0.3 the paper's beam's LQG settles 1.5 x its time-optimal "
                                     "slew with the optimal reference in 5.8 s instead of 8.5 s (issue 22). "
                                     "The default flows derive the LQG's from its sensor noise "
                                     "(LQGSettings.tip_noise_budget_m).")

    def covariances(self, design: DesignModel, design_modes: int | None = None):
        """Process and measurement noise covariances ``(Qn, Rn)`` on ``design``.

        Parameters
        ----------
        design : DesignModel
        design_modes : int, optional
            Transverse modes of the controller's design model when ``design`` is a filter's
            model with residual modes beyond them (their noise is scaled by
            :attr:`residual_noise`); default all of ``design``'s.

        Returns
        -------
        Qn : ndarray (nx, nx)
            ``torque_noise^2 Bd Bd'`` plus ``modal_noise^2`` on the modal coordinates and
            ``modal_rate_noise^2`` (default ``modal_noise^2``) on their rates, plus
            :attr:`model_error` if given.
        Rn : ndarray (ny, ny)
            Diagonal: the sensors' variances [rad^2, (rad/s)^2, (N m)^2], one per signal of
            ``design.signals`` (an accelerometer's [(m/s^2)^2]).
        """
        nx = design.n_x
        n = nx // 2
        Qn = self.torque_noise_nm ** 2 * (design.Bd @ design.Bd.T)
        rate = self.modal_noise if self.modal_rate_noise is None else self.modal_rate_noise
        scale = np.ones(n - 1)
        if design_modes is not None:
            scale[design_modes:] = self.residual_noise
        Qn[np.r_[1:n], np.r_[1:n]] += (self.modal_noise * scale) ** 2
        Qn[np.r_[n + 1:nx], np.r_[n + 1:nx]] += (rate * scale) ** 2
        if self.model_error is not None:
            Qn = Qn + check_psd("model_error", self.model_error, nx)
        return Qn, self.sensor_covariance(design)

    def sensor_covariance(self, design: DesignModel) -> np.ndarray:
        """The measurement noise covariance of ``design``'s sensors (``design.signals``).

        Parameters
        ----------
        design : DesignModel

        Returns
        -------
        ndarray (ny, ny)
            Diagonal [rad^2, (rad/s)^2, (N m)^2, (m/s^2)^2 per signal].
        """
        if design.sensors is None:
            return np.diag([self.angle_noise_rad ** 2, self.rate_noise_rad_s ** 2, self.moment_noise_nm ** 2])
        std = {"angle": self.angle_noise_rad, "rate": self.rate_noise_rad_s, "moment": self.moment_noise_nm,
               "accel": self.accel_noise_m_s2}
        return np.diag([std[design.sensors.kind(s)] ** 2 for s in design.signals])


def error_decay_rate(design: DesignModel, noise: KalmanNoise) -> float:
    """The estimation error's prescribed decay rate ``sigma = error_decay * w_1`` [1/s].

    Parameters
    ----------
    design : DesignModel
        The filter's model; ``w_1`` is its first flexible natural frequency (free hub, design
        spin, :func:`controllers.scaling.first_mode`).
    noise : KalmanNoise
        Its :attr:`~KalmanNoise.error_decay`.

    Returns
    -------
    float
        ``sigma`` [1/s]; 0 for the plain Kalman filter.

    Examples
    --------
    >>> from controllers import DesignModel
    >>> round(error_decay_rate(DesignModel.build(n_modes=2), KalmanNoise()), 3)   # 0.3 x 0.46 Hz
    0.866
    """
    if not isinstance(noise, KalmanNoise):
        raise ParameterError(f"noise must be a KalmanNoise, got {type(noise).__name__}")
    return noise.error_decay * first_mode(design) if noise.error_decay > 0 else 0.0


def decay_model(A: np.ndarray, rate: float, dt: float) -> np.ndarray:
    """The model the filter's Riccati equation is solved for: ``A exp(rate dt)``.

    A filter designed on it and run on ``A`` has every pole of its estimation error within
    ``exp(-rate dt)``, i.e. decaying at least at ``rate``.

    Parameters
    ----------
    A : ndarray (n, n)
        Sampled state matrix.
    rate : float
        Prescribed decay rate [1/s] (:func:`error_decay_rate`); 0 or less: ``A`` itself.
    dt : float
        Sample time [s].

    Returns
    -------
    ndarray (n, n)

    Examples
    --------
    >>> float(decay_model(np.eye(1), math.log(2.0), 1.0)[0, 0])
    2.0
    """
    return A * math.exp(rate * dt) if rate > 0 else A


def _kalman_design(design: DesignModel, noise: KalmanNoise, design_modes: int | None = None):
    """Filter gain ``L`` (measurement update) and a-priori covariance ``P`` via :func:`control.dlqe`."""
    A, _, C, Qn, Rn = filter_matrices(design, noise, design_modes)
    return solve_kalman(decay_model(A, error_decay_rate(design, noise), design.dt), C, Qn, Rn)


#: The bias's own process noise never falls below this fraction of the rate sensor's noise per
#: sample (a constant bias, rate_bias_walk = 0, still has a stabilisable Riccati equation).
RATE_BIAS_FLOOR = 1e-3


def estimates_rate_bias(model: DesignModel, noise: KalmanNoise) -> bool:
    """Whether the filter carries the rate sensor's bias as a state: ``noise.rate_bias_walk`` is
    set and the model reads the hub rate (``theta_dot``).

    Parameters
    ----------
    model : DesignModel
    noise : KalmanNoise

    Returns
    -------
    bool
    """
    return getattr(noise, "rate_bias_walk", None) is not None and "theta_dot" in model.signals


def filter_state_names(model: DesignModel, noise: KalmanNoise, integral: bool = False) -> list:
    """Names of the filter's states ``z = [x, u_prev, f, b, d]`` (:func:`filter_matrices`).

    Parameters
    ----------
    model : DesignModel
    noise : KalmanNoise
    integral : bool
        The filter carries an input disturbance (integral action).

    Returns
    -------
    list of str
        ``<state>_est`` for the model's states, then ``u_prev``, ``<signal>_filtered`` (the
        anti-alias filter's outputs), ``rate_bias_est`` [rad/s] and ``d_est`` [N m] where the
        filter has them.
    """
    filtered = [] if model.sensors is None else [f"{s}_filtered" for s in model.sensors.filtered]
    return ([f"{s}_est" for s in model.state_names] + (["u_prev"] if model.carries_loop else []) + filtered
            + (["rate_bias_est"] if estimates_rate_bias(model, noise) else []) + (["d_est"] if integral else []))


def filter_gain(K, model: DesignModel, noise: KalmanNoise, integral: bool = False) -> np.ndarray:
    """A gain on the acting state as a gain on the whole filter state ``[x, u_prev, f, b, d]``.

    The anti-alias filter's states and the bias of the rate sensor are not fed back (0); an
    estimated input disturbance is
    cancelled (1: ``u = -K x - d``).

    Parameters
    ----------
    K : ndarray (1, n_x)
        Gain on the model's state where the command acts (:meth:`DesignModel.acting_state`).
    model : DesignModel
        The filter's model.
    noise : KalmanNoise
    integral : bool
        The filter carries an input disturbance.

    Returns
    -------
    ndarray (1, nz)
    """
    K = np.atleast_2d(K)
    extra = extra_state_gains(model, noise, integral, K)
    K = model.action_gain(K)
    return np.hstack([K, [extra]]) if extra else K


def extra_state_gains(model: DesignModel, noise: KalmanNoise, integral: bool = False, K=None) -> list:
    """The feedback's gains on the filter's states after ``[x, u_prev]``: 0 on the anti-alias
    filter's outputs and the rate sensor's bias; on an input disturbance ``d`` 1 (cancelled) plus,
    with a computation delay, ``K Gamma_d`` (it acts with the previous command until the new one
    does: :meth:`DesignModel.acting_state`).

    Parameters
    ----------
    model : DesignModel
    noise : KalmanNoise
    integral : bool
    K : ndarray (1, n_x), optional
        The gain on the acting state (needed with ``integral`` on a model with a delay).

    Returns
    -------
    list of float
    """
    filtered = 0 if model.sensors is None else len(model.sensors.filtered)
    d = 1.0
    if integral and model.delay > 0.0:
        d += float((np.atleast_2d(K) @ model.action_map()[1])[0])
    return [0.0] * filtered + [0.0] * estimates_rate_bias(model, noise) + [d] * bool(integral)


def filter_matrices(model: DesignModel, noise: KalmanNoise, design_modes: int | None = None,
                    disturbance_noise: float | None = None) -> tuple:
    """The filter's sampled model ``z+ = A z + B u``, ``y = C z`` and its noise covariances.

    The state is ``z = [x, u_prev, f, b, d]``: the model's state; the previous command when the model
    carries a computation delay or an accelerometer (:attr:`DesignModel.carries_loop`), known
    exactly (no noise), so the prediction is the fractional-delay zero-order hold
    (:func:`hubbeam_ctrl.linear.delay.delay_inputs`) and the accelerometer's feedthrough is a
    state's row; the rig's anti-alias filter's output for each filtered signal
    (:func:`controllers.sensing.with_anti_alias`, deterministic); the rate sensor's bias when
    :attr:`KalmanNoise.rate_bias_walk` is set (:func:`estimates_rate_bias`: it adds to the rate row and walks with
    ``rate_bias_walk sqrt(dt)`` per sample; the prescribed degree of stability covers it, so a
    constant bias is learnt at the filter's own rate); a constant input disturbance torque with
    ``disturbance_noise`` (:mod:`controllers.integral`), acting without delay.

    Parameters
    ----------
    model : DesignModel
    noise : KalmanNoise
    design_modes : int, optional
        See :meth:`KalmanNoise.covariances`.
    disturbance_noise : float, optional
        Random-walk standard deviation of the disturbance per sample [N m]; None: no disturbance.

    Returns
    -------
    tuple of ndarray
        ``(A, B, C, Qn, Rn)``.
    """
    if not isinstance(noise, KalmanNoise):
        raise ParameterError(f"noise must be a KalmanNoise, got {type(noise).__name__}")
    Qx, Rn = noise.covariances(model, design_modes)
    nx = model.n_x
    if not model.carries_loop:
        A, B, C, Q = model.Ad, model.Bd, model.C_sensors, Qx
    else:
        from hubbeam_ctrl.linear.delay import delay_inputs
        Phi, G0, G1 = delay_inputs(model.A, model.B, model.dt, model.delay)
        A = np.zeros((nx + 1, nx + 1))
        A[:nx, :nx], A[:nx, nx:] = Phi, G1
        B = np.vstack([G0, [[1.0]]])
        D = np.zeros((model.C_sensors.shape[0], 1)) if model.D_sensors is None else model.D_sensors
        C = np.hstack([model.C_sensors, D])
        Q = np.zeros((nx + 1, nx + 1))
        Q[:nx, :nx] = Qx
    if estimates_rate_bias(model, noise):      # y_rate = theta_dot + b, b a random walk
        n = A.shape[0]
        Ab = np.eye(n + 1)
        Ab[:n, :n] = A
        A, B = Ab, np.vstack([B, [[0.0]]])
        C = np.hstack([C, np.zeros((C.shape[0], 1))])
        C[model.signals.index("theta_dot"), n] = 1.0
        Qb = np.zeros((n + 1, n + 1))
        Qb[:n, :n] = Q
        per_sample = noise.rate_bias_walk * math.sqrt(model.dt)
        Qb[n, n] = max(per_sample, RATE_BIAS_FLOOR * noise.rate_noise_rad_s) ** 2
        Q = Qb
    if disturbance_noise is not None:
        n = A.shape[0]
        Aa = np.zeros((n + 1, n + 1))
        Aa[:n, :n], Aa[:nx, n] = A, model.Bd[:, 0]
        Aa[n, n] = 1.0
        A, B, C = Aa, np.vstack([B, [[0.0]]]), np.hstack([C, np.zeros((C.shape[0], 1))])
        Qa = np.zeros((n + 1, n + 1))
        Qa[:n, :n], Qa[n, n] = Q, float(disturbance_noise) ** 2
        Q = Qa
    n = A.shape[0]
    A, B, C = with_anti_alias(A, B, C, model.sensors, model.dt)
    nf = A.shape[0] - n
    if nf:                                     # the filter's states after [x, u_prev]: [x, u_prev, f, b, d]
        p = nx + int(model.carries_loop)
        order = np.r_[0:p, n:n + nf, p:n]
        A, B, C = A[np.ix_(order, order)], B[order], C[:, order]
        Qf = np.zeros((n + nf, n + nf))
        Qf[:n, :n] = Q
        Q = Qf[np.ix_(order, order)]
    return A, B, C, Q, Rn


def plan_offsets(model: DesignModel, states: np.ndarray, torque: np.ndarray) -> np.ndarray:
    """What a planned trajectory does beyond the model's prediction, sample by sample.

    A filter that adds ``d[k]`` to its prediction ``Ad x_hat[k] + Bd u[k]`` predicts along the
    plan, ``x_ref[k+1] + Ad (x_hat[k] - x_ref[k]) + Bd (u[k] - u_ff[k])``: the plan comes from
    the nonlinear model, and only the linear model's error in the deviation from it is left.

    Parameters
    ----------
    model : DesignModel
        The filter's model (``Ad``, ``Bd``, ``spin``, ``dt``).
    states : ndarray (K, nx)
        Planned states ``x_ref[k]`` on ``model``'s coordinates, absolute hub angle and rate.
    torque : ndarray (K,)
        Planned torque ``u_ff[k]`` [N m] the controller adds as feedforward (0 without one).

    Returns
    -------
    ndarray (K - 1, nx)
        ``d[k] = x_ref[k+1] - Ad x_ref[k] - Bd u_ff[k]`` in the filter's coordinates (deviations
        from the steady rotation at ``model.spin``).

    Examples
    --------
    >>> from controllers import DesignModel
    >>> d = DesignModel.build(n_modes=1)
    >>> x = [np.zeros(4)]
    >>> for k in range(3):                     # a trajectory of the model itself: no offset
    ...     x.append(d.Ad @ x[-1] + d.Bd[:, 0] * 10.0)
    >>> float(np.max(np.abs(plan_offsets(d, np.array(x), np.full(4, 10.0))))) < 1e-12
    True
    """
    X = np.array(states, dtype=float)
    n = model.n_x // 2
    X[:, 0] -= model.spin * model.dt * np.arange(len(X))       # deviations from the steady rotation
    X[:, n] -= model.spin
    u = np.asarray(torque, dtype=float)
    return X[1:] - X[:-1] @ model.Ad.T - np.outer(u[:-1], model.Bd[:, 0])


def plan_worth_predicting(reference, elastic_reference: bool) -> bool:
    """The default of ``plan_prediction``: a plan of the beam's motion from outside the design model.

    Parameters
    ----------
    reference : Reference
        The controller's reference.
    elastic_reference : bool
        Whether the controller tracks the reference's planned bending.

    Returns
    -------
    bool
        True when the reference carries planned bending (:attr:`Reference.elastic`) that is not
        the design model's own response (:attr:`Reference.planned_on_design`).

    Notes
    -----
    A plan of the nonlinear model (an optimal slew) carries what the linear model would predict
    wrongly along it. A plan of the design model itself (:attr:`Reference.planned_on_design`)
    is what the filter's own prediction gives on the design modes, and it has no residual
    modes: predicting along it would hold the filter's residual modes at rest against the
    torque that drives them (on the paper's beam an offset of up to 2.9e-3 per sample in the
    residual modes against 3.1e-4 in the design modes), which delays the LQG's settling by 0.15 s
    (6.26 s against 6.11 s at 1.5 x the time-optimal slew, ``benchmarks/bench_limit_targets.py``).
    """
    return (bool(elastic_reference) and getattr(reference, "elastic", None) is not None
            and not getattr(reference, "planned_on_design", False))


def filter_poles(A: np.ndarray, C: np.ndarray, L: np.ndarray, dt: float) -> np.ndarray:
    """Poles of a measurement-update filter's estimation error, as continuous-time equivalents.

    The a-priori error obeys ``e[k+1] = A (I - L C) e[k]``; its eigenvalues ``z`` are returned
    as ``s = log(z) / dt`` (decay rate ``-Re s``, damping ``-Re s / |s|``), one per complex
    pair (``Im s >= 0``), sorted by ``|s|``.

    Parameters
    ----------
    A : ndarray (n, n)
        Sampled state matrix the filter predicts with (the true model, not the Riccati one).
    C : ndarray (ny, n)
    L : ndarray (n, ny)
        Measurement-update gain.
    dt : float
        Sample time [s].

    Returns
    -------
    ndarray of complex
        [1/s].

    Examples
    --------
    >>> from controllers import DesignModel
    >>> d = DesignModel.build(n_modes=2)
    >>> s = filter_poles(d.Ad, d.C_sensors, kalman_gain(d, KalmanNoise()), d.dt)
    >>> bool(np.all(-s.real >= error_decay_rate(d, KalmanNoise()) * (1 - 1e-9)))
    True
    """
    z = np.linalg.eigvals(A @ (np.eye(A.shape[0]) - L @ C)).astype(complex)
    s = np.log(z) / dt
    s = s[s.imag >= 0]
    return s[np.argsort(np.abs(s))]


def solve_kalman(A: np.ndarray, C: np.ndarray, Qn: np.ndarray, Rn: np.ndarray):
    """Steady-state Kalman gain in measurement-update form and the a-priori covariance.

    Parameters
    ----------
    A : ndarray (n, n)
        Sampled state matrix.
    C : ndarray (ny, n)
        Output matrix.
    Qn : ndarray (n, n)
        Process-noise covariance per sample (in state units).
    Rn : ndarray (ny, ny)
        Measurement-noise covariance.

    Returns
    -------
    L : ndarray (n, ny)
        ``x_hat = x_pred + L (y - C x_pred)``.
    P : ndarray (n, n)
        A-priori error covariance (:func:`control.dlqe`'s Riccati solution).
    """
    try:
        _, P, poles = dlqe(A, np.eye(A.shape[0]), C, Qn, Rn)     # control.dlqe's numbers, without its import
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise ParameterError(f"the Kalman filter's Riccati equation has no solution ({exc}); "
                             "check the noise levels") from None
    if np.max(np.abs(poles)) >= 1.0:
        raise ParameterError("the Kalman filter is not stable; check the noise levels")
    # dlqe's gain A P C' (C P C' + Rn)^-1 corrects the next prediction; the filter here
    # corrects the current estimate: P C' (C P C' + Rn)^-1 (= A^-1 times dlqe's gain)
    L = P @ C.T @ np.linalg.inv(C @ P @ C.T + Rn)
    return L, np.asarray(P)


def kalman_gain(design: DesignModel, noise: KalmanNoise) -> np.ndarray:
    """Steady-state Kalman filter gain (measurement update) for the three hub sensors.

    Parameters
    ----------
    design : DesignModel
        Sampled design model (``Ad``, ``Bd``, ``C_sensors``).
    noise : KalmanNoise
        Noise model (an :class:`~controllers.lqg.LQGSettings` is one).

    Returns
    -------
    ndarray (nx, 3)
        ``x_hat = x_pred + L (y - C x_pred)``.

    Examples
    --------
    >>> from controllers import DesignModel
    >>> kalman_gain(DesignModel.build(n_modes=2), KalmanNoise()).shape
    (6, 3)
    """
    return _kalman_design(design, noise)[0]


class KalmanEstimator:
    """Steady-state Kalman filter on the sampled design model (deviation coordinates).

    Parameters
    ----------
    design : DesignModel
        Sampled design model: ``x[k+1] = Ad x[k] + Bd u[k]``, ``y = C_sensors x``.
    noise : KalmanNoise
        Noise model the gain is designed for.
    design_modes : int, optional
        Transverse modes of the controller's design model when ``design`` carries residual
        modes beyond them (see :meth:`KalmanNoise.covariances`).

    Attributes
    ----------
    L : ndarray (nx, 3)
        Filter gain (measurement update).
    P : ndarray (nx, nx)
        A-priori error covariance of the steady-state filter (of the Riccati equation's model
        ``Ad exp(sigma dt)`` when :attr:`KalmanNoise.error_decay` > 0).
    x_pred : ndarray (nx,)
        Prediction used by the last update (the initial guess after :meth:`reset`).
    x_hat : ndarray (nx,)
        Current estimate.

    Examples
    --------
    >>> from controllers import DesignModel
    >>> d = DesignModel.build(n_modes=2)
    >>> est = KalmanEstimator(d, KalmanNoise())
    >>> x = np.r_[0.01, 0.001, 0, 0, 0, 0]         # 10 mrad off, first mode deflected
    >>> for k in range(1000):                       # 10 s of measurements, no torque
    ...     x_hat = est.update(d.C_sensors @ x, None if k == 0 else 0.0)
    ...     err = np.max(np.abs(x_hat - x))
    ...     x = d.Ad @ x
    >>> bool(err < 1e-5)
    True
    """

    def __init__(self, design: DesignModel, noise: KalmanNoise, design_modes: int | None = None):
        self.A, self.B, self.C, Qn, Rn = filter_matrices(design, noise, design_modes)
        self.L, self.P = solve_kalman(decay_model(self.A, error_decay_rate(design, noise), design.dt),
                                      self.C, Qn, Rn)
        self._A, self._b = self.A, self.B[:, 0]
        self._IminusLC = np.eye(self.A.shape[0]) - self.L @ self.C
        self.reset()

    def reset(self, x0=None) -> None:
        """Start again from a state guess, with no measurement yet.

        Parameters
        ----------
        x0 : array_like (nx,), optional
            Initial guess of the (deviation) state; default zero.
        """
        x = np.zeros(len(self._b))
        if x0 is not None:
            x0 = np.asarray(x0, dtype=float)
            x[:len(x0)] = x0
        self.x_pred = x
        self.x_hat = x

    def predict(self, u: float) -> np.ndarray:
        """Prediction of the next sample's state ``Ad x_hat + Bd u`` (the estimator is unchanged).

        Parameters
        ----------
        u : float
            Torque held over the coming sample [N m].

        Returns
        -------
        ndarray (nx,)
        """
        return self._A @ self.x_hat + self._b * u

    def update(self, y, u_prev: float | None, offset=None) -> np.ndarray:
        """Take one measurement and return the new estimate.

        Parameters
        ----------
        y : ndarray (3,)
            Measurement ``[theta, theta_dot, M_root]`` in the model's (deviation) coordinates.
        u_prev : float or None
            Torque held since the previous update [N m]; ``None`` for the first sample after
            :meth:`reset` (the guess is then the prediction).
        offset : array_like (n_x,), optional
            Added to the prediction ``Ad x_hat + Bd u_prev`` of the model's states (not to a
            carried previous command): what a planned trajectory does that the model does not
            (see :class:`controllers.lqg.LQG`'s ``plan_prediction``).

        Returns
        -------
        ndarray (nx,)
            ``x_hat``.
        """
        if u_prev is not None:
            self.x_pred = self.predict(u_prev)
            if offset is not None:         # on the model's states (none on a carried previous command)
                self.x_pred = self.x_pred.copy()
                self.x_pred[:len(offset)] += offset
        self.x_hat = self._IminusLC @ self.x_pred + self.L @ y
        return self.x_hat


class AppliedTorque:
    """Mixin of a controller with a filter: the torque it predicts with is the one applied
    (``_tau``), which a wrapper may set (:meth:`applied`) after overriding the controller's output."""

    _tau: float | None = None

    def applied(self, tau: float) -> None:
        """The filter's next prediction uses ``tau`` as this sample's torque
        (:meth:`controllers.base.Controller.applied`).

        Parameters
        ----------
        tau : float
            The torque applied [N m].
        """
        self._tau = float(tau)
