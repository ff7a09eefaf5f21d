"""The rig's DC drive, viscous friction and computation delay in the NMPC's prediction (issue 40 item 1).

On a rig whose motor is a DC drive commanded in volts (``motor.kind = "dc_motor"``), the NMPC's
decision variable is the voltage ``V`` [V], and its shooting map carries what stands between the
voltage and the hub:

* the drive's hub torque is the plant's own map (:func:`hubbeam_ctrl.sim.hardware.hub_torque`:
  ``V`` clipped to ``V_max``, the current ``(V - k_e N thd) / R`` clipped to ``I_max``, the gear
  ``N k_t`` with its efficiency switching from ``eta_forward`` while motoring to ``1 / eta_backward``
  while back-driven), minus the viscous friction ``b thd``, with the hardware's numbers of
  :meth:`~hubbeam_ctrl.sim.hardware.Hardware.values` but **Coulomb friction (and its breakaway)
  set to zero**: a sign function has no useful derivative for a Gauss-Newton step, and the constant
  torque it leaves is what the rig's filter estimates as an input disturbance and cancels
  (:class:`ObservedNMPC`, offset-free);
* the current limit ``|V - k_e N thd| <= R I_max`` as a path constraint, affine in the command and
  the predicted hub rate (at the start of each stage), and the voltage box ``|V| <= V_max``;
* the computation delay ``d`` (``timing.delay``, a fraction of the sample in [0, 1]): the command in
  flight ``V_prev`` is an input of the step, which first predicts the state where this sample's
  command starts to act, ``x(t_k + d dt)``, by RK4 on the nonlinear model under ``V_prev``
  (:attr:`DrivePrediction._G`); on that grid, shifted by the delay, each stage is one sample under
  one command, exactly (the fractional-delay hold of :func:`hubbeam_ctrl.linear.delay.delay_augmented`
  and the linear designs' :meth:`~controllers.DesignModel.acting_state`, here on the nonlinear
  model). Predicting the command in flight once a step rather than in every stage (the state
  augmented with it) halves the shooting's work: measured on ``servo_link``, 157 000 against 66 000
  instructions a stage, 1.84 against 0.41 ms for the 20 stages as C.

The terminal cost is the Riccati solution of the LQR of the same weights on the same model
linearised (:func:`controllers.loop_plant.hardware_plant`: the drive's torque per volt and its
back-EMF plus viscous damping, sampled on the grid shifted by the delay), the command weight the
torque's times the drive's torque per volt squared (the same cost for the same torque).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.sim.hardware import HW_LAYOUT, Hardware, hub_torque

from .base import saturate
from .integral import ObservedFeedback

__all__ = ["PredictionDrive", "DrivePrediction", "ObservedNMPC", "drive_lqr", "nmpc_on_drive"]


@dataclass(frozen=True)
class PredictionDrive:
    """The drive stage as the NMPC predicts it (see the module docstring).

    Attributes
    ----------
    hardware : Hardware
        The rig's.
    values : ndarray
        :meth:`Hardware.values` with Coulomb friction and breakaway set to 0 (:data:`HW_LAYOUT`).
    delay : float
        Computation delay as a fraction of the sample [-].
    """

    hardware: Hardware
    values: np.ndarray
    delay: float

    @classmethod
    def from_hardware(cls, hardware: Hardware) -> "PredictionDrive":
        """The prediction's drive of ``hardware`` (a DC motor commanded in volts).

        Parameters
        ----------
        hardware : Hardware
        """
        if not isinstance(hardware, Hardware):
            raise ParameterError(f"hardware must be a Hardware, got {type(hardware).__name__}")
        if hardware.command != "voltage":
            raise ParameterError("the NMPC's drive stage needs a rig with a DC motor (motor.kind = 'dc_motor')")
        v = hardware.values().copy()
        v[HW_LAYOUT.index("coulomb")] = 0.0
        v[HW_LAYOUT.index("breakaway")] = 0.0
        return cls(hardware, v, float(hardware.delay))

    def resolved(self, step_s: float, inertia: float) -> "PredictionDrive":
        """This drive with the gear's efficiency switch spread so that RK4 steps of ``step_s`` resolve it.

        The plant switches the gear factor from ``eta_forward`` (motoring) to ``1 / eta_backward``
        (back-driven) over ``v_eps`` of hub rate, the friction's regularisation (1 mrad/s): in the
        prediction that is a torque slope in the hub rate of up to ``0.77 (1 / eta_backward -
        eta_forward) N k_t I_max / v_eps`` [N m s/rad], which on the hub's own inertia is far beyond
        RK4's reach near rest, and flips the Gauss-Newton step's torque per volt by the ratio of the
        two factors (1.6 on ``servo_payload``) between samples. Measured there (full-sample delay,
        30 mN m of Coulomb friction): the NMPC was "not settled", and with a fine encoder its tip
        grew at 5.6 /s; with the switch spread it settles (1.5 s), as it does with an ideal gear.
        The switch's scale becomes ``max(v_eps, 0.77 (1 / eta_backward - eta_forward) N k_t I_max
        step_s / (inertia RK4_REACH))``; away from rest the map is the plant's.

        Parameters
        ----------
        step_s : float
            The shooting's RK4 step [s].
        inertia : float
            The hub's own inertia ``J_h`` [kg m^2] (what the drive's torque meets first).

        Returns
        -------
        PredictionDrive
        """
        from .nmpc_rti import RK4_REACH
        d = self.hardware.drive
        jump = abs(1.0 / d.eta_backward - d.eta_forward) * d.N * d.k_torque * d.I_max
        k = HW_LAYOUT.index("v_eps")
        values = self.values.copy()
        values[k] = max(values[k], 0.77 * jump * step_s / (inertia * RK4_REACH))
        return PredictionDrive(self.hardware, values, self.delay)

    @property
    def v_max(self) -> float:
        """Voltage limit [V]."""
        return float(self.hardware.drive.V_max)

    @property
    def emf(self) -> float:
        """Back-EMF per hub rate ``k_e N`` [V s/rad]."""
        return float(self.hardware.back_emf_constant())

    @property
    def current_bound(self) -> float:
        """``R I_max`` [V]: the current limit on ``V - k_e N thd``."""
        d = self.hardware.drive
        return float(d.R * d.I_max)

    @property
    def gain(self) -> float:
        """Hub torque per volt while motoring [N m/V] (:meth:`Hardware.torque_per_volt`)."""
        return float(self.hardware.torque_per_volt())

    def torque(self, u, thd):
        """Hub torque [N m] at voltage ``u`` [V] and hub rate ``thd`` [rad/s]: the plant's drive minus
        viscous friction (:func:`~hubbeam_ctrl.sim.hardware.hub_torque`, Coulomb friction left out).

        Parameters
        ----------
        u : float or casadi.SX
            Voltage [V].
        thd : float or casadi.SX
            Hub rate [rad/s].

        Returns
        -------
        float or casadi.SX
            [N m].
        """
        return hub_torque(u, thd, self.values)

    def volts(self, tau, thd):
        """The voltage [V] that makes the hub torque ``tau`` [N m] (after viscous friction) at hub rate
        ``thd`` [rad/s]: the drive's static inverse (:meth:`Hardware.voltage_for_torque`), clipped.

        Parameters
        ----------
        tau : float
            Hub torque [N m].
        thd : float
            Hub rate [rad/s].

        Returns
        -------
        float
            [V].
        """
        b = float(self.hardware.friction.viscous)
        return self.hardware.voltage_for_torque(float(tau) + b * float(thd), float(thd))

    def current_window(self, thd: float) -> tuple:
        """``(lo, hi)`` [V]: the voltages within both the box and the current limit at hub rate ``thd``.

        Parameters
        ----------
        thd : float
            Hub rate [rad/s].

        Returns
        -------
        tuple of float
            [V].
        """
        c = self.emf * float(thd)
        return max(-self.v_max, c - self.current_bound), min(self.v_max, c + self.current_bound)

    def clip(self, u: float, thd: float) -> float:
        """``u`` [V] within :meth:`current_window` at ``thd`` [rad/s] (the box first when they miss).

        Parameters
        ----------
        u, thd : float
            Voltage [V] and hub rate [rad/s], as :meth:`torque`.

        Returns
        -------
        float
            [V].
        """
        lo, hi = self.current_window(thd)
        return saturate(u, self.v_max) if lo > hi else min(max(u, lo), hi)


def drive_lqr(design, weights, drive: PredictionDrive) -> tuple:
    """The LQR of ``weights`` on ``design`` with the drive linearised, on the grid shifted by the delay.

    Parameters
    ----------
    design : DesignModel
    weights : Weights
        The torque design's; the command weight becomes ``R g^2`` [1/V^2] with ``g`` the drive's
        torque per volt.
    drive : PredictionDrive

    Returns
    -------
    K : ndarray (n_x,)
        Gain [V per state unit] on the state where the command acts.
    P : ndarray (n_x, n_x)
        The Riccati solution.
    """
    from .design_model import _zoh
    from .loop_plant import hardware_plant
    from .riccati import dlqr
    A, B, _ = hardware_plant(design.A, design.B, drive.hardware, "voltage")
    Q, R = weights.matrices(design)
    Ad, Bd = _zoh(A, B, design.dt)
    K, P, _ = dlqr(Ad, Bd, Q, np.asarray(R, dtype=float) * drive.gain ** 2)
    return np.asarray(K).ravel(), np.asarray(P)


class DrivePrediction:
    """The NMPC's drive stage (a mixin of :class:`controllers.NMPC`, which sets ``drive``, ``_lag``
    and the reference tables): its shooting map, weights and reference in volts."""

    def _drive_shooting(self, model) -> ca.Function:
        """``(x, V) -> (x+, dx+/dx, dx+/dV)``: one sample under ``V`` through the drive
        (:mod:`controllers.nmpc_drive`); with a delay also :attr:`_G`, ``(x, V_prev) -> x(delay dt)``
        (the state where this sample's command starts to act)."""
        x, u = ca.SX.sym("x", self._nx), ca.SX.sym("u")
        p, tq = ca.DM(model.p), self.drive.torque
        self._G = None
        if self._lag:
            early = max(1, math.ceil(self.substeps * self.drive.delay))
            self._G = ca.Function("nmpc_in_flight", [x, u],
                                  [self._rk4(model, x, u, p, tq, self.drive.delay * self.dt, early)], {"cse": True})
        return self._shooting_function("nmpc_shoot_v", model, p, tq)

    def _volts_at(self, k: int) -> float:
        """Feedforward voltage [V] of sample ``k``: the reference torque where the command acts (at
        ``k + delay``) through the drive's static inverse (:meth:`PredictionDrive.volts`)."""
        cached = self._vff.get(k)
        if cached is None:
            d, h = self.drive.delay, self.design.n_x // 2
            x0, t0 = self._reference_at(k)
            x1, t1 = self._reference_at(k + 1)
            tau, rate = (1.0 - d) * t0 + d * t1, (1.0 - d) * x0[h] + d * x1[h]
            cached = self._vff[k] = float(self.drive.volts(self._ff * tau, rate)) if self._ff else 0.0
        return cached

    def _drive_window(self, k: int, N: int) -> tuple:
        """``(x_ref, V_ff)`` over samples ``k .. k + N`` with the drive: the predicted states where the
        commands act (at ``k + j + delay``, interpolated) and the feedforward voltages."""
        d = self.drive.delay
        X = np.array([self._reference_at(k + j)[0][self._pick] for j in range(N + 2)])
        xr = X[:-1] if d == 0.0 else (1.0 - d) * X[:-1] + d * X[1:]
        return xr, np.array([self._volts_at(k + j) for j in range(N)])

    def _drive_setup(self, s, design) -> None:
        """Weights, terminal cost and residual gain in volts on the drive's model
        (:func:`controllers.nmpc_drive.drive_lqr`)."""
        from .nmpc_drive import drive_lqr
        from .residual import residual_design
        drv = self.drive
        self._lag = drv.delay > 0.0
        model, weights = (residual_design(design, s.weights, s.residual_modes) if s.residual_control
                          else (design, s.weights))
        K, P = drive_lqr(model, weights, drv)          # model: the LQR's (self.design)
        self.K_volts = K
        self.u_max, self.command = drv.v_max, "voltage"
        self._R = self._R * drv.gain ** 2
        self._Pt = P[np.ix_(self._pick, self._pick)]
        self._K_res = K.copy()
        self._K_res[self._pick] = 0.0
        self._K_res0 = self._K_res.copy()
        self._vff = {}
        self._acting = None

    def _acting_error(self, k: int, y) -> tuple:
        """``(e, thd)``: the design state's error from the reference where this sample's command acts
        (at ``k + delay``: :meth:`in_flight_map` under the command in flight) and the hub rate there."""
        y = np.asarray(y, dtype=float)
        x0, d = self._reference_at(k)[0], self.drive.delay
        if not self._lag:
            return y - x0, float(y[self.design.n_x // 2])
        if self._acting is None:
            self._acting = self.in_flight_map()
        Phi, G = self._acting
        x = Phi @ y + G * float(self._u_last)
        return x - ((1.0 - d) * x0 + d * self._reference_at(k + 1)[0]), float(x[self.design.n_x // 2])

    def in_flight_map(self) -> tuple:
        """``(Phi, Gamma)``: the design state where the command acts, ``Phi x + Gamma V_prev``, from
        the drive's model linearised (:func:`controllers.loop_plant.hardware_plant`) over the delay."""
        from .design_model import _zoh
        from .loop_plant import hardware_plant
        A, B, _ = hardware_plant(self.design.A, self.design.B, self.drive.hardware, "voltage")
        Phi, G = _zoh(A, B, self.drive.delay * self.dt)
        return Phi, G[:, 0]


class ObservedNMPC(ObservedFeedback):
    """An NMPC with the drive in its prediction, closed through the rig's Kalman filter.

    The filter (:class:`~controllers.integral.ObservedFeedback`'s, on the rig's sensors, with the
    input disturbance when ``disturbance_noise`` is given) gives the state at the sample, not where
    the command acts: the NMPC predicts the delay itself from the command in flight. The NMPC's
    voltage less the disturbance's (``d_hat / g``), within the drive's limits, is the command; the
    filter predicts with the hub torque it makes at the rate where it acts (the drive map of the
    prediction, :meth:`PredictionDrive.torque`).

    Parameters
    ----------
    inner : controllers.NMPC
        Built with ``hardware`` (its :attr:`~controllers.NMPC.drive`).
    noise : KalmanNoise
    disturbance_noise : float, optional
        [N m]; None: no integral action.
    """

    command = "voltage"

    def __init__(self, inner, noise, disturbance_noise: float | None = None):
        if getattr(inner, "drive", None) is None:
            raise ParameterError("ObservedNMPC wraps an NMPC built with the rig's hardware (a DC drive)")
        super().__init__(inner, noise, disturbance_noise)
        self.tau_max = inner.u_max

    def __call__(self, t: float, y) -> float:
        """Voltage [V] at time ``t`` [s] from the rig's sensors ``y``."""
        fm = self.filter_model
        drive = self.inner.drive
        k = int(round(t / self.dt))
        D = self._defect
        z = self.estimator.update(fm.sensor_deviation(y, t), self._tau,
                                  D[k - 1] if D is not None and 0 < k <= len(D) else None)
        x = np.asarray(z[:fm.n_x])[self._pick]
        v = float(self.inner(t, x))
        d = float(z[-1]) if self.integral else 0.0
        rate = float(fm.acting_state(z, d)[fm.n_x // 2])
        if self.integral:
            v = drive.clip(v - d / drive.gain, rate)
            # in flight, as the NMPC predicts the plant: the disturbance cancels its share
            self.inner.applied(v + d / drive.gain)
        self._tau = float(drive.torque(v, rate))
        return v

    def applied(self, command: float) -> None:
        """The drive gave ``command`` [V]: the NMPC's command in flight, and the filter's torque.

        Parameters
        ----------
        command : float
            [V].
        """
        self.inner.applied(command)

    def feedback_matrices(self) -> tuple:
        """The filter and the NMPC's law at the end point as one linear system, sensors -> volts.

        The law ``V = -K_z z_hat`` on the filter's state ``z = [x, V_prev, d]`` (``d / g`` for the
        disturbance); the filter's input is the torque of the drive linearised while motoring,
        ``g V - (g k_e N + b) thd`` at the acting state's rate.
        """
        fm, est = self.filter_model, self.estimator
        nz = est.A.shape[0]
        K_in = -np.asarray(self.inner.feedback_matrices()[3])[0]     # on [x_design, (V_prev)]
        Kz = np.zeros((1, nz))
        Kz[0, self._pick] = K_in[:len(self._pick)]
        if fm.carries_loop and len(K_in) > len(self._pick):      # the filter holds the torque in flight
            Kz[0, fm.n_x] = K_in[-1] / self.inner.drive.gain
        if self.integral:               # cancelled, and in flight with the command (acting_state)
            Kz[0, -1] = (1.0 + (K_in[-1] if fm.carries_loop and len(K_in) > len(self._pick) else 0.0)) \
                / self.inner.drive.gain
        g, damp = self.inner.drive.gain, self.inner.drive.hardware.hub_damping()
        r = fm.action_gain(np.eye(fm.n_x)[fm.n_x // 2][None, :])
        r = np.hstack([r, np.zeros((1, nz - r.shape[1]))])
        if self.integral and fm.delay > 0.0:
            r[0, -1] += float(fm.action_map()[1][fm.n_x // 2])
        Kf = g * Kz + damp * r                 # the filter's input: -Kf z_hat
        F = est.A - est.B @ Kf
        M = np.eye(nz) - est.L @ est.C
        states = [f"{s}_est" for s in fm.state_names] + (["u_prev"] if fm.carries_loop else [])
        if self.integral:
            states.append("d_est")
        return F @ M, F @ est.L, -Kz @ M, -Kz @ est.L, states, fm.sensor_labels



def nmpc_on_drive(controller, hardware: Hardware, noise, disturbance_noise: float | None = None) -> ObservedNMPC:
    """The NMPC ``controller`` built again with the rig's DC drive in its prediction, closed through
    the rig's filter (:class:`ObservedNMPC`).

    Parameters
    ----------
    controller : controllers.NMPC
        Designed for the beam (its design model on the rig, settings and reference).
    hardware : Hardware
        A DC motor commanded in volts.
    noise : KalmanNoise
    disturbance_noise : float, optional
        [N m]; None: no integral action.

    Returns
    -------
    ObservedNMPC
    """
    design, reference = controller.built_on
    nmpc = type(controller)(design, controller.settings, reference, hardware=hardware)
    return ObservedNMPC(nmpc, noise, disturbance_noise)
