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

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError

from .base import DesignModel
from .filter_model import KalmanNoise, filter_matrices
from .riccati import dlqe
from .scaling import first_mode

__all__ = ["KalmanEstimator", "kalman_gain", "solve_kalman", "error_decay_rate", "decay_model", "filter_poles",
           "plan_offsets", "plan_worth_predicting"]


#: The most a prescribed decay rate asks of one sample: ``sigma dt <= ln 2`` (the error halves each
#: sample). Found on a random slow boom (3.4 m CFRP on a 3.9 kg m^2 body, a star tracker and a gyro at
#: 10 Hz) whose first flexible mode (13.5 Hz) lies above the sampling frequency: 0.3 w_1 asked the
#: error to shrink 12.9-fold a sample, and the Riccati equation of that model was too ill conditioned
#: to solve ("no solution"; every default LQG and observer-fed run refused). Below it on every rig whose
#: first mode is under 37 % of the sampling frequency (the presets: at most 7 %, space_boom).
MAX_DECAY_PER_SAMPLE = math.log(2.0)


def error_decay_rate(design: DesignModel, noise: KalmanNoise) -> float:
    """The estimation error's prescribed decay rate ``sigma = error_decay * w_1`` [1/s], at most
    :data:`MAX_DECAY_PER_SAMPLE` ``/ dt``.

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
    if noise.error_decay <= 0:
        return 0.0
    return min(noise.error_decay * first_mode(design), MAX_DECAY_PER_SAMPLE / design.dt)


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
