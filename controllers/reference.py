"""The hub reference (:class:`Reference`), and those of the two scenarios: a rest-to-rest slew and a spin-up.

Each gives the hub angle and rate to follow and the feedforward torque that drives the
*rigid* body (inertia ``J_total``) along them; the feedback controllers add what the
flexible plant needs on top.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.validation import check_finite, check_positive
from hubbeam_ctrl.plant.maneuvers import SpinUp

__all__ = ["Reference", "slew_reference", "spinup_reference", "eq44_reference", "slew_shape_constant",
           "optimal_reference"]


@dataclass(frozen=True, eq=False)
class Reference:
    """A hub reference sampled at the controller's instants ``t_k = k dt``.

    Beyond the last sample the reference continues at its final rate with its final
    feedforward torque.

    Attributes
    ----------
    dt : float
        Sample time [s].
    theta : ndarray (K,)
        Reference hub angle [rad].
    theta_dot : ndarray (K,)
        Reference hub rate [rad/s].
    theta_ddot : ndarray (K,)
        Reference hub acceleration [rad/s^2].
    torque : ndarray (K,)
        Feedforward torque [N m] that drives the rigid body along the reference.
    description : str
    elastic : ndarray (K, 2 m) or None
        Planned modal coordinates and rates ``[q2, q2_dot]`` [m, m/s] of a reference that
        knows the beam's motion (an optimal slew); None: the quasi-static deflection of
        :meth:`DesignModel.reference_states`.
    planned_on_design : bool
        The planned motion is the design model's own response to the feedforward
        (:func:`controllers.planning.planned_slew_reference`): a filter that predicts with the
        applied torque already follows it, so the filters do not predict along it by default
        (``plan_prediction``); False for a plan of the nonlinear model (an optimal slew).
    plan : tuple or None
        ``(angle, duration, tau_max, n_modes)`` of a plan on the design model
        (:func:`controllers.planning.planned_slew_reference`), so that a controller can plan the
        same task for other parameters (:func:`controllers.planning.replanned`); None otherwise.
    hub_damping : float
        Hub damping [N m s/rad] the feedforward ``torque`` already overcomes
        (:meth:`with_hub_damping`); 0: the undamped hub's torque.
    """

    dt: float
    theta: np.ndarray
    theta_dot: np.ndarray
    theta_ddot: np.ndarray
    torque: np.ndarray
    description: str = ""
    elastic: np.ndarray | None = None
    planned_on_design: bool = False
    plan: tuple | None = None
    hub_damping: float = 0.0

    @classmethod
    def from_profile(cls, profile, dt: float, t_end: float, description: str = "") -> "Reference":
        """Sample ``profile(t) -> (theta, theta_dot, theta_ddot, torque)`` on ``0..t_end``.

        Parameters
        ----------
        profile : callable
            ``profile(t)`` of an array of times [s] -> ``(theta, theta_dot, theta_ddot, torque)``
            [rad, rad/s, rad/s^2, N m].
        dt : float
            Sample time [s], > 0.
        t_end : float
            Last sample [s].
        description : str
            What the reference is (for reports).
        """
        dt = check_positive("dt", dt, "s")
        t = dt * np.arange(int(round(t_end / dt)) + 1)
        th, thd, thdd, tau = (np.asarray(a, dtype=float) * np.ones_like(t) for a in profile(t))
        return cls(dt, th, thd, thdd, tau, description)

    @classmethod
    def rest(cls, dt: float, theta: float = 0.0) -> "Reference":
        """Stay at rest at ``theta`` [rad].

        Parameters
        ----------
        dt : float
            Sample time [s].
        theta : float
            Hub angle to hold [rad].
        """
        z = np.zeros(1)
        return cls(dt, z + theta, z, z, z, "rest")

    @property
    def t(self) -> np.ndarray:
        """Sample instants [s]."""
        return self.dt * np.arange(len(self.theta))

    def index(self, t: float) -> int:
        """Sample index of time ``t`` [s] (rounded).

        Parameters
        ----------
        t : float
            Time [s].
        """
        return int(round(t / self.dt))

    def with_hub_damping(self, b: float) -> "Reference":
        """The same motion for a hub damped by ``b``: the feedforward adds the damping's torque over
        each sample, ``b (theta[k+1] - theta[k]) / dt`` (the sample's mean rate; the last sample's
        rate after the table), to what :attr:`hub_damping` already holds.

        Parameters
        ----------
        b : float
            Linear hub damping [N m s/rad], >= 0 (:attr:`controllers.DesignModel.hub_damping`).

        Returns
        -------
        Reference
            ``self`` when ``b`` is the damping it already has.
        """
        b = float(b)
        if b == self.hub_damping:
            return self
        rate = np.append(np.diff(self.theta) / self.dt, self.theta_dot[-1:])
        return dataclasses.replace(self, torque=self.torque + (b - self.hub_damping) * rate, hub_damping=b)

    def window(self, k: int, n: int):
        """Reference at samples ``k..k+n-1``: ``(theta, theta_dot, torque)`` arrays.

        Parameters
        ----------
        k : int
            First sample.
        n : int
            Number of samples (the last value is held beyond the table).
        """
        K = len(self.theta)
        if k + n <= K:
            return self.theta[k:k + n], self.theta_dot[k:k + n], self.torque[k:k + n]
        idx = np.arange(k, k + n)
        inside = np.minimum(idx, K - 1)
        extra = (idx - inside) * self.dt
        return (self.theta[inside] + self.theta_dot[-1] * extra, self.theta_dot[inside],
                self.torque[inside])

    def at(self, t):
        """``(theta, theta_dot, torque)`` at time(s) ``t`` [s] (nearest sample).

        Parameters
        ----------
        t : float or array_like
            Time(s) [s].
        """
        t = np.asarray(t, dtype=float)
        K = len(self.theta)
        k = np.rint(t / self.dt).astype(int)
        inside = np.clip(k, 0, K - 1)
        extra = np.maximum(k - (K - 1), 0) * self.dt
        return (self.theta[inside] + self.theta_dot[-1] * extra, self.theta_dot[inside],
                self.torque[inside])

    def theta_at(self, t):
        """Reference hub angle at ``t`` [rad].

        Parameters
        ----------
        t : float or array_like
            Time(s) [s].
        """
        return self.at(t)[0]

    def theta_dot_at(self, t):
        """Reference hub rate at ``t`` [rad/s].

        Parameters
        ----------
        t : float or array_like
            Time(s) [s].
        """
        return self.at(t)[1]


def _shape(u, flatness):
    """Acceleration shape on ``u = t/T`` in [0, 1]: ``tanh(k sin 2 pi u) / tanh(k)``."""
    if flatness <= 1e-6:
        return np.sin(2 * math.pi * u)
    return np.tanh(flatness * np.sin(2 * math.pi * u)) / math.tanh(flatness)


def slew_shape_constant(flatness: float) -> float:
    """``c`` with rest-to-rest angle ``= c a_max T^2`` for the shape of :func:`slew_reference`.

    ``c = 1/(2 pi)`` for a sine (``flatness = 0``), tending to ``1/4`` (bang-bang).

    Parameters
    ----------
    flatness : float
        Shape of the acceleration profile [-], in [0, 1) (0: a sine).
    """
    u = np.linspace(0.0, 1.0, 20001)
    s = _shape(u, flatness)
    # angle(1) = int_0^1 (1 - u) s(u) du
    w = (1.0 - u) * s
    return float(np.sum(0.5 * (w[1:] + w[:-1]) * np.diff(u)))


def slew_reference(angle: float, duration: float, inertia: float, tau_max: float, dt: float,
                   t_end: float, flatness: float = 3.0, smoothing: float = 0.0) -> Reference:
    """Smooth rest-to-rest reference of the rigid body.

    Hub acceleration ``a(t) = a_max tanh(k sin(2 pi t/T)) / tanh(k)`` for ``0 <= t <= T``
    (``k = flatness``; ``k -> 0`` is the Eq. 44 sine, large ``k`` approaches bang-bang),
    with ``a_max`` chosen so that the hub turns by ``angle`` in ``T = duration``. A flatter
    shape needs less peak torque for the same angle and time (k = 3: 75 % of the sine's),
    leaving the feedback controllers a margin below ``tau_max``.

    Parameters
    ----------
    angle : float
        Rotation [rad].
    duration : float
        Maneuver time T [s], > 0.
    inertia : float
        Rigid-body inertia [kg m^2] (``Params.total_inertia``).
    tau_max : float
        Torque budget [N m]; the feedforward ``inertia * a_max`` must stay below it.
    dt : float
        Sample time [s].
    t_end : float
        Last sample [s].
    flatness : float
        Shape parameter k >= 0 [-].
    smoothing : float
        Length [s] of a moving average applied to the acceleration (0: none). The shape
        then spans ``duration - smoothing`` and the average stretches it back to
        ``duration``; the jerk becomes continuous and the angle is unchanged.

    Returns
    -------
    Reference
    """
    angle = check_finite("angle", angle, "rad")
    T = check_positive("tf", duration, "s")
    J = check_positive("inertia", inertia, "kg m^2")
    check_positive("tau_max", tau_max, "N m")
    if not (isinstance(flatness, (int, float)) and math.isfinite(flatness) and flatness >= 0):
        raise ParameterError(f"flatness must be a finite number >= 0, got {flatness!r}")
    if not (isinstance(smoothing, (int, float)) and 0 <= smoothing < 0.5 * T):
        raise ParameterError(f"smoothing must be in [0, tf/2) [s], got {smoothing!r}")
    Ts = T - smoothing
    c = slew_shape_constant(flatness)
    a_max = angle / (c * Ts ** 2)
    peak = J * abs(a_max)
    if peak > tau_max:
        raise ParameterError(
            f"tau_max = {tau_max:g} N m is below the {peak:.4g} N m the reference needs to turn "
            f"{angle:.4g} rad in tf = {T:g} s; raise tau_max or tf")
    # fine grid, exact double integration by the trapezoidal rule, then sampling
    n_fine = max(20001, int(T / dt) * 20 + 1)
    tf_grid = np.linspace(0.0, T, n_fine)
    h = T / (n_fine - 1)
    acc = a_max * _shape(np.clip(tf_grid / Ts, 0, 1), flatness)
    if smoothing > 0:
        m = max(1, int(round(smoothing / h)))
        acc = np.convolve(acc, np.full(m, 1.0 / m))[:n_fine]
    vel = np.concatenate([[0.0], np.cumsum(0.5 * (acc[1:] + acc[:-1]) * h)])
    pos = np.concatenate([[0.0], np.cumsum(0.5 * (vel[1:] + vel[:-1]) * h)])
    pos *= angle / pos[-1] if pos[-1] != 0 else 1.0     # remove the quadrature's last digits

    def profile(t):
        inside = t <= T
        th = np.where(inside, np.interp(t, tf_grid, pos), angle)
        thd = np.where(inside, np.interp(t, tf_grid, vel), 0.0)
        a = np.where(inside, np.interp(t, tf_grid, acc), 0.0)
        return th, thd, a, J * a

    return Reference.from_profile(profile, dt, t_end,
                                  f"slew {angle:.4g} rad in {T:g} s (flatness {flatness:g}, smoothing {smoothing:g} s, "
                                  f"peak feedforward {peak:.4g} N m)")


def eq44_reference(tau_m: float, t_f: float, inertia: float, dt: float, t_end: float) -> Reference:
    """The rigid-body motion under the Eq. 44 torque ``tau_m sin(2 pi t/t_f)`` (its own feedforward).

    Parameters
    ----------
    tau_m : float
        Torque amplitude [N m].
    t_f : float
        Maneuver time [s].
    inertia : float
        Rigid-body inertia [kg m^2].
    dt, t_end : float
        Sample time and last sample [s].
    """
    T = check_positive("tf", t_f, "s")
    J = check_positive("inertia", inertia, "kg m^2")
    w = 2 * math.pi / T
    angle = tau_m * T ** 2 / (2 * math.pi * J)

    def profile(t):
        inside = t <= T
        th = np.where(inside, tau_m / J * (t / w - np.sin(w * t) / w ** 2), angle)
        thd = np.where(inside, tau_m / J * (1 - np.cos(w * t)) / w, 0.0)
        tau = np.where(inside, tau_m * np.sin(w * t), 0.0)
        return th, thd, tau / J, tau

    return Reference.from_profile(profile, dt, t_end, f"Eq. 44 rigid motion ({angle:.4g} rad)")


def spinup_reference(w_f: float, t_f: float, inertia: float, dt: float, t_end: float,
                     tau_max: float | None = None) -> Reference:
    """The corrected Eq. 43 spin-up (Kane, Ryan and Banerjee) to ``w_f`` in ``t_f``, then hold.

    Feedforward ``inertia * theta_ddot`` (peak ``2 inertia w_f / t_f``).

    Parameters
    ----------
    w_f : float
        Final rate [rad/s].
    t_f : float
        Spin-up time [s].
    inertia : float
        Rigid-body inertia [kg m^2].
    dt, t_end : float
        Sample time and last sample [s].
    tau_max : float, optional
        Torque budget [N m]; raises if the feedforward alone exceeds it.
    """
    T = check_positive("tf", t_f, "s")
    J = check_positive("inertia", inertia, "kg m^2")
    if not (isinstance(w_f, (int, float)) and math.isfinite(w_f)):
        raise ParameterError(f"wf must be a finite number [rad/s], got {w_f!r}")
    peak = 2 * J * abs(w_f) / T
    if tau_max is not None and peak > tau_max:
        raise ParameterError(
            f"tau_max = {tau_max:g} N m is below the {peak:.4g} N m the spin-up to {w_f:g} rad/s "
            f"in tf = {T:g} s needs; raise tau_max or tf")
    spin = SpinUp(float(w_f), T)

    def profile(t):
        th, thd, thdd = spin(t)
        return th, thd, thdd, J * thdd

    return Reference.from_profile(profile, dt, t_end,
                                  f"spin-up to {w_f:g} rad/s in {T:g} s (peak feedforward {peak:.4g} N m)")


def optimal_reference(opt, dt: float, t_end: float) -> Reference:
    """The hub motion of an optimal slew as reference, its optimal torque as feedforward.

    The feedforward is the torque the optimisation found on the nonlinear design model
    (:func:`hubbeam_ctrl.limit.time_optimal_slew` or :func:`~hubbeam_ctrl.limit.min_vibration_slew`),
    averaged over each controller sample (the controller holds it for ``dt``), so that the
    feedback only corrects the difference between that model and the plant. Angle and rate
    are the design model's hub angle and rate (a cubic Hermite interpolation of the grid
    values, whose derivative is the acceleration); after the slew the reference rests at
    the slew angle with no torque. The planned bending (the design model's modal coordinates
    and rates) goes with it (:attr:`Reference.elastic`): the controller tracks it (its first
    modes, if the controller's design model has fewer) instead of the quasi-static deflection.

    Parameters
    ----------
    opt : OptimalSlew
        The optimal slew.
    dt : float
        Controller sample time [s], > 0.
    t_end : float
        Last sample [s], at least the slew's duration.

    Returns
    -------
    Reference
    """
    from scipy.interpolate import CubicHermiteSpline

    from hubbeam_ctrl.limit.slew import OptimalSlew  # the limit layer loads SciPy and IPOPT: on use

    if not isinstance(opt, OptimalSlew):
        raise ParameterError(f"opt must be an OptimalSlew, got {type(opt).__name__}")
    dt = check_positive("dt", dt, "s")
    T = opt.duration_s
    if not (isinstance(t_end, (int, float)) and math.isfinite(t_end) and t_end >= T):
        raise ParameterError(f"t_end must be >= the slew's duration {T:.5g} s, got {t_end!r}")
    spline = CubicHermiteSpline(opt.t, opt.theta, opt.theta_dot)
    acc = spline.derivative()
    edges = np.concatenate([opt.t[:-1], [T]])
    work = np.concatenate([[0.0], np.cumsum(opt.tau * np.diff(edges))])   # int_0^t tau [N m s]

    def profile(t):
        inside = t <= T
        tc = np.clip(t, 0.0, T)
        th = np.where(inside, spline(tc), opt.slew_angle)
        thd = np.where(inside, spline(tc, 1), 0.0)
        a = np.where(inside, acc(tc), 0.0)
        upper = np.clip(t + dt, 0.0, T)
        tau = (np.interp(upper, edges, work) - np.interp(tc, edges, work)) / dt
        return th, thd, a, np.where(inside, tau, 0.0)

    ref = Reference.from_profile(profile, dt, t_end,
                                 f"{opt.kind} slew {opt.slew_angle:.4g} rad in {T:.4g} s "
                                 f"({opt.ratio:.3f} x the rigid bound; optimal feedforward)")
    tc = np.clip(ref.t, 0.0, T)
    modal = [CubicHermiteSpline(opt.t, q, qd) for q, qd in zip(opt.q2.T, opt.q2_dot.T)]
    after = (ref.t > T)[:, None]
    q2 = np.where(after, 0.0, np.column_stack([m(tc) for m in modal]))
    q2d = np.where(after, 0.0, np.column_stack([m(tc, 1) for m in modal]))
    return dataclasses.replace(ref, elastic=np.hstack([q2, q2d]))
