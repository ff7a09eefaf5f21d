"""The design model: the linear SFOAM about a spin rate, sampled at the controller's period, with
the rig's sensors and computation delay (:meth:`DesignModel.on_rig`).

Every controller is built from one (:mod:`controllers.base`); estimators read its sensor rows,
laws act where its delay puts the command.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.validation import check_positive
from hubbeam_ctrl.plant.params import Params

__all__ = ["DesignModel"]

#: Outputs of the design model's linearisation: the three sensors, then the tip.
_DESIGN_OUTPUTS = ("theta", "theta_dot", "root_moment", "tip_deflection", "tip_rate")


def _zoh(A: np.ndarray, B: np.ndarray, dt: float) -> tuple:
    """Zero-order-hold ``(Ad, Bd)`` exactly as python-control's ``sample(dt, "zoh")`` computes them
    (:func:`scipy.signal.cont2discrete`: one matrix exponential of ``[[A, B], [0, 0]] dt``)."""
    import warnings

    import scipy.linalg
    em = np.vstack((np.hstack((A, B)), np.hstack((np.zeros((B.shape[1], A.shape[0])),
                                                  np.zeros((B.shape[1], B.shape[1]))))))
    with np.errstate(all="ignore"), warnings.catch_warnings():     # overflow is checked by the caller
        warnings.simplefilter("ignore", RuntimeWarning)
        ms = scipy.linalg.expm(dt * em)[:A.shape[0], :]
    return ms[:, 0:A.shape[1]], ms[:, A.shape[1]:]


@dataclass(frozen=True, eq=False)
class DesignModel:
    """The linear SFOAM design model, continuous and sampled (zero-order hold).

    Build it with :meth:`build`.

    Attributes
    ----------
    params : Params
        Parameters of the design model (``n_transverse`` = ``n_modes``).
    spin : float
        Spin rate of the linearisation [rad/s].
    dt : float
        Sample time [s].
    n_modes : int
        Transverse modes ``m``; the state has ``2 (1 + m)`` entries.
    A, B : ndarray
        Continuous state matrices of ``dx/dt = A x + B tau``.
    Ad, Bd : ndarray
        Sampled ones, ``x[k+1] = Ad x[k] + Bd tau[k]``.
    C_sensors : ndarray (ny, nx)
        Rows giving the sensors the estimator reads: ``[theta, theta_dot, M_root]`` [rad, rad/s,
        N m] by default, the rig's own set after :meth:`on_rig` (:attr:`sensors`).
    C_tip : ndarray (2, nx)
        Rows giving the tip deflection ``v_tip`` [m] and its rate [m/s].
    inertia : float
        Rigid-body inertia of hub, beam and tip mass ``params.total_inertia`` [kg m^2].
    state_names : list of str
    M2, K2 : ndarray (1 + m, 1 + m)
        Second-order mass and stiffness matrices ``M dq'' + G dq' + K dq = B tau``.
    linear_model : hubbeam_ctrl.linear.statespace.LinearModel
        The sampled model as a python-control system (``.sys``); built on first use (a
        property), so that designing a controller does not import python-control.
    sensors : controllers.sensing.SensorLayout or None
        The signals of :attr:`C_sensors` (None: the default three, hub angle and rate, root moment).
    D_sensors : ndarray (ny, 1) or None
        Feedthrough of the previous command into the sensors (a tip accelerometer; None: none).
    delay : float
        Computation delay as a fraction of the sample [-], in [0, 1]: the command computed at a
        sample acts ``delay * dt`` later (the rig's ``timing.delay``).
    hub_damping : float
        Linear damping of the hub in ``A`` [N m s/rad] (:meth:`on_rig`): a DC drive's back-EMF and
        the viscous friction; its input is then the drive's torque at rest, ``tau - b theta_dot``
        reaching the hub. 0: the beam alone's.
    """

    params: Params
    spin: float
    dt: float
    n_modes: int
    A: np.ndarray
    B: np.ndarray
    Ad: np.ndarray
    Bd: np.ndarray
    C_sensors: np.ndarray
    C_tip: np.ndarray
    inertia: float
    state_names: list
    M2: np.ndarray = None
    K2: np.ndarray = None
    sensors: object = None
    D_sensors: np.ndarray = None
    delay: float = 0.0
    hub_damping: float = 0.0
    _linear_model: object = field(default=None, repr=False, init=False)
    _action: tuple = field(default=None, repr=False, init=False)

    @classmethod
    def build(cls, params: Params = Params(), spin: float = 0.0, dt: float = 0.01,
              n_modes: int | None = None) -> "DesignModel":
        """Linearise SFOAM about steady spin and sample it.

        Parameters
        ----------
        params : Params
            System parameters (Table 1 by default).
        spin : float
            Spin rate of the linearisation [rad/s] (0 for a slew).
        dt : float
            Controller sample time [s], > 0.
        n_modes : int, optional
            Transverse modes of the design model (default ``params.n_transverse``).

        Returns
        -------
        DesignModel

        Examples
        --------
        >>> d = DesignModel.build(n_modes=2)
        >>> d.Ad.shape, d.state_names[:2]
        ((6, 6), ['theta', 'q2_1'])
        """
        from hubbeam_ctrl.linear.statespace import linear_matrices
        from hubbeam_ctrl.plant.linearization import second_order_linearization
        from hubbeam_ctrl.plant.models import build_model
        dt = check_positive("dt", dt, "s")
        if not isinstance(params, Params):
            raise ParameterError(f"params must be a Params, got {type(params).__name__}")
        if not (isinstance(spin, (int, float)) and math.isfinite(spin)):
            raise ParameterError(f"spin must be a finite number [rad/s], got {spin!r}")
        m = params.n_transverse if n_modes is None else n_modes
        p = params.replace(n_transverse=m)
        A, B, C, _, states = linear_matrices("sfoam", float(spin), p, _DESIGN_OUTPUTS, state_names=True)
        Ad, Bd = _zoh(A, B, dt)        # linearize + discretize's numbers (control's sample, zoh), bit for bit
        if not (np.all(np.isfinite(Ad)) and np.all(np.isfinite(Bd))):
            growth = float(np.max(np.linalg.eigvals(A).real))
            raise ParameterError(f"dt = {dt:g} s is too long for this model: its fastest-growing mode "
                                 f"(real part {growth:.4g} 1/s) overflows the sampled matrices")
        so = second_order_linearization(build_model("sfoam", p), float(spin), "free")
        return cls(params=p, spin=float(spin), dt=dt, n_modes=p.n_transverse,
                   A=A, B=B, Ad=Ad, Bd=Bd, C_sensors=C[:3], C_tip=C[3:], inertia=p.total_inertia,
                   state_names=list(states), M2=so.M, K2=so.K)

    @property
    def linear_model(self):
        """The sampled model as a :class:`~hubbeam_ctrl.linear.statespace.LinearModel` (a named
        python-control system, ``.sys``), built on first use: the same matrices as ``Ad``, ``Bd``."""
        if self._linear_model is None:
            from hubbeam_ctrl.linear.statespace import linearize
            from hubbeam_ctrl.linear.transforms import discretize
            lm = linearize("sfoam", self.spin, self.params, _DESIGN_OUTPUTS)
            object.__setattr__(self, "_linear_model", discretize(lm, self.dt))
        return self._linear_model

    @property
    def n_x(self) -> int:
        """Number of states ``2 (1 + n_modes)``."""
        return self.A.shape[0]

    @property
    def signals(self) -> tuple:
        """Names of the sensor signals of :attr:`C_sensors`, in the closed loop's names."""
        from .sensing import DEFAULT_LAYOUT
        return (self.sensors or DEFAULT_LAYOUT).signals

    @property
    def sensor_labels(self) -> list:
        """Input names of a sensor-reading law (:meth:`Controller.feedback_matrices`): the beam
        alone's ``theta, theta_dot, root_moment``, else :attr:`signals`."""
        return ["theta", "theta_dot", "root_moment"] if self.sensors is None else list(self.signals)

    @property
    def carries_loop(self) -> bool:
        """The filter needs the previous command as a state: a delay or an accelerometer."""
        return self.delay > 0.0 or (self.D_sensors is not None and bool(np.any(self.D_sensors)))

    def on_rig(self, sensors=None, delay: float = 0.0, hub_damping: float = 0.0) -> "DesignModel":
        """The same model reading the rig's sensors with the rig's computation delay and, when
        given, the hub's linear damping (a DC drive's back-EMF and viscous friction).

        Parameters
        ----------
        sensors : controllers.sensing.SensorLayout, optional
            The signals the estimator reads (default: the three of the beam alone).
        delay : float
            Computation delay as a fraction of the sample [-], in [0, 1].
        hub_damping : float
            Linear damping of the hub [N m s/rad], >= 0: ``A`` gets ``-b B e_rate^T`` (the input is
            the torque at rest, the hub gets ``tau - b theta_dot``) and is sampled again. 0: none.

        Returns
        -------
        DesignModel
            ``self`` when nothing changes (the beam alone's model, bit for bit).
        """
        from .sensing import DEFAULT_LAYOUT
        if not (isinstance(delay, (int, float)) and 0.0 <= delay <= 1.0):
            raise ParameterError(f"timing.delay must be in [0, 1] (a fraction of the sample), got {delay!r}")
        if not (isinstance(hub_damping, (int, float)) and math.isfinite(hub_damping) and hub_damping >= 0.0):
            raise ParameterError(f"hub_damping must be a finite number >= 0 [N m s/rad], got {hub_damping!r}")
        layout = sensors or DEFAULT_LAYOUT
        same_damping = float(hub_damping) == self.hub_damping
        if (layout.is_default and delay == 0.0 and self.sensors is None and self.delay == 0.0
                and same_damping):
            return self
        A, Ad, Bd = self.A, self.Ad, self.Bd
        if not same_damping:
            n = self.n_x // 2
            A = A.copy()
            A[:, n] -= (float(hub_damping) - self.hub_damping) * self.B[:, 0]
            Ad, Bd = _zoh(A, self.B, self.dt)
        if layout.is_default:           # the beam alone's three sensors: the model's own rows and names
            C, D, layout = (self.C_sensors if self.sensors is None else layout.rows(
                A, self.B, self.params, self.spin, self.C_tip[0])[0]), None, None
        else:
            C, D = layout.rows(A, self.B, self.params, self.spin, self.C_tip[0])
        return dataclasses.replace(self, A=A, Ad=Ad, Bd=Bd, C_sensors=C, D_sensors=D, sensors=layout,
                                   delay=float(delay), hub_damping=float(hub_damping))

    def like(self, other: "DesignModel") -> "DesignModel":
        """This model (e.g. with more modes, or another beam) on ``other``'s rig: its sensors, delay
        and hub damping (:meth:`on_rig`).

        Parameters
        ----------
        other : DesignModel

        Returns
        -------
        DesignModel
        """
        return self.on_rig(other.sensors, other.delay, other.hub_damping)

    def sensor_deviation(self, y, t: float) -> np.ndarray:
        """The measurement ``y`` of :attr:`signals` in deviation coordinates about the steady
        rotation (the angle less ``spin t``, the rate less ``spin``).

        Parameters
        ----------
        y : array_like (ny,)
            Measured signals [rad, rad/s, N m, m/s^2].
        t : float
            Time [s].

        Returns
        -------
        ndarray (ny,)
        """
        yd = np.array(y, dtype=float)
        if self.sensors is None:
            yd[0] -= self.spin * t
            yd[1] -= self.spin
            return yd
        for k, s in enumerate(self.signals):
            if s == "theta":
                yd[k] -= self.spin * t
            elif s == "theta_dot":
                yd[k] -= self.spin
        return yd

    def acting_state(self, z_hat, disturbance: float = 0.0) -> np.ndarray:
        """The state where this sample's command starts to act, from a filter state
        ``z = [x, u_prev, ...]`` (:func:`controllers.filter_model.filter_matrices`); ``x`` itself
        without a delay.

        Parameters
        ----------
        z_hat : ndarray
            Filter estimate whose first :attr:`n_x` entries are the state (deviation coordinates).
        disturbance : float
            The estimated input disturbance torque [N m] (integral action), which acts with the
            previous command until then (without it a delayed loop with integral action kept an
            offset at rest: 0.12 rad per N m on ``servo_link`` with a torque drive).

        Returns
        -------
        ndarray (n_x,)
        """
        x = np.asarray(z_hat[:self.n_x], dtype=float)
        if self.delay == 0.0:
            return x
        Phi, G = self.action_map()
        return Phi @ x + G * (float(z_hat[self.n_x]) + float(disturbance))

    def action_gain(self, K) -> np.ndarray:
        """A gain on the acting state (:meth:`acting_state`) as a gain on the filter state
        ``[x, u_prev]`` (``[x]`` when the model does not carry the previous command).

        Parameters
        ----------
        K : ndarray (1, n_x)

        Returns
        -------
        ndarray (1, n_x) or (1, n_x + 1)
        """
        K = np.atleast_2d(K)
        if not self.carries_loop:
            return K
        Phi, G = self.action_map()
        return np.hstack([K @ Phi, K @ G[:, None]])

    def action_map(self) -> tuple:
        """``(Phi_d, Gamma_d)``: the state where this sample's command starts to act.

        ``x(t_k + delay dt) = Phi_d x[k] + Gamma_d u[k-1]``: the previous command acts until then.
        On the grid shifted by the delay, ``x(s_{k+1}) = Ad x(s_k) + Bd u[k]`` exactly, so the
        design's gain applied to this state is the delay-free law (a predictor).

        Returns
        -------
        Phi_d : ndarray (n_x, n_x)
        Gamma_d : ndarray (n_x,)
        """
        if self._action is None:
            if self.delay == 0.0:
                action = (np.eye(self.n_x), np.zeros(self.n_x))
            else:
                Phi, G = _zoh(self.A, self.B, self.delay * self.dt)
                action = (Phi, G[:, 0])
            object.__setattr__(self, "_action", action)
        return self._action

    def with_delay(self, delay: float) -> tuple:
        """The sampled model with a computation delay as one extra state, the previous command.

        ``z = [x, tau_prev]``, ``z+ = Ad_z z + Bd_z tau``: the command computed at a sample
        acts ``delay * dt`` later (:func:`hubbeam_ctrl.linear.delay.delay_augmented`, the
        standard fractional-delay zero-order hold); ``delay = 0`` gives ``Ad``, ``Bd`` with a
        zero column and row appended.

        Parameters
        ----------
        delay : float
            Computation delay as a fraction of the sample [-], in [0, 1] (``timing.delay``).

        Returns
        -------
        Ad_z : ndarray (n_x + 1, n_x + 1)
        Bd_z : ndarray (n_x + 1, 1)
        """
        from hubbeam_ctrl.linear.delay import delay_augmented
        return delay_augmented(self.A, self.B, self.dt, delay)

    @property
    def quasi_static_gain(self) -> np.ndarray:
        """Modal deflection per unit hub acceleration [m/(rad/s^2)], shape (n_modes,).

        The beam's quasi-static bending under a slowly varying hub acceleration ``a``:
        ``q2 = -K_22^-1 M_21 a`` (the elastic rows without their inertia).
        """
        return -np.linalg.solve(self.K2[1:, 1:], self.M2[1:, 0])

    def reference_states(self, reference, elastic: bool = True) -> np.ndarray:
        """Reference states ``[theta, q2, theta_dot, q2_dot]`` at the reference's samples.

        Parameters
        ----------
        reference : controllers.Reference
        elastic : bool
            Include the deflection the reference plans (:attr:`controllers.Reference.elastic`: its first
            modes, the rest 0; the assumed modes are the same whatever their number) or else
            the quasi-static deflection ``q2 = g theta_ddot``
            (and its rate) that the reference acceleration necessarily causes; otherwise ``q2 = 0``.

        Returns
        -------
        ndarray (K, n_x)
        """
        n = self.n_x // 2
        X = np.zeros((len(reference.theta), self.n_x))
        X[:, 0] = reference.theta
        X[:, n] = reference.theta_dot
        planned = getattr(reference, "elastic", None)
        if elastic and planned is not None and len(planned) == len(reference.theta):
            # the assumed modes do not depend on their number: keep the first min(m, m_planned)
            m_p, k = planned.shape[1] // 2, min(planned.shape[1] // 2, n - 1)
            X[:, 1:1 + k], X[:, n + 1:n + 1 + k] = planned[:, :k], planned[:, m_p:m_p + k]
        elif elastic and len(reference.theta) > 1:
            g = self.quasi_static_gain
            acc = reference.theta_ddot
            X[:, 1:n] = np.outer(acc, g)
            X[:, n + 1:] = np.outer(np.gradient(acc, reference.dt), g)
        return X
