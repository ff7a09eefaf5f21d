"""The Kalman filter's model: the noise it assumes and its sampled state-space model on a rig.

:class:`KalmanNoise` is the noise model (sensor noise, process noise, the prescribed degree of
stability, the rate sensor's bias); :func:`filter_matrices` the filter's sampled model
``z = [x, u_prev, f, b, d]`` on the rig's sensors (the computation delay's previous command, the
anti-alias filter's outputs, the rate sensor's bias, an input disturbance), with
:func:`filter_state_names` and :func:`filter_gain` saying what each state is and how a state
feedback acts on it. :mod:`controllers.estimator` builds the filters on it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.settings import Settings, setting
from hubbeam_ctrl.plant.sensors import SensorSettings

from .base import DesignModel, check_psd
from .sensing import with_anti_alias

__all__ = ["KalmanNoise", "filter_matrices", "estimates_rate_bias", "filter_state_names", "filter_gain",
           "extra_state_gains", "RATE_BIAS_FLOOR"]

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
        # the disturbance is a hub torque: a sensor that reads the torque directly (the accelerometer's
        # feedthrough) reads it as it reads the command; without this column the filter's integral leaked
        # (the compensator's pole at 1 +- 1e-5 on rigs with a tip accelerometer, a finite hold at rest)
        Cd = np.zeros((C.shape[0], 1))
        if model.carries_loop and model.D_sensors is not None:
            Cd[:, 0] = np.asarray(model.D_sensors, dtype=float)[:, 0]
        A, B, C = Aa, np.vstack([B, [[0.0]]]), np.hstack([C, Cd])
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


