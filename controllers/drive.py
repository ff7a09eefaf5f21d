"""Commanding a DC motor: a torque design's output turned into the drive's voltage.

The designs compute a hub torque. A rig with a DC motor and gearbox is driven in volts
through back-EMF, resistance and the gear's efficiency
(:mod:`hubbeam_ctrl.sim.hardware`). :class:`VoltageCommand` inverts that static relation at
every sample with the measured hub rate, ``V = R tau / (N k_t eta) + k_e N theta_dot``,
clipped at the amplifier's ``V_max``: back-EMF compensation, the standard inner loop of a
servo drive. What the inversion misses (the clip, the current limit, a wrong constant,
friction) is a torque error the integral action of :mod:`controllers.integral` removes.

A design model that carries the drive's back-EMF as hub damping
(:attr:`controllers.DesignModel.hub_damping`, on rigs where the cancellation one sample late
would feed the rate back: :func:`hubbeam_ctrl.study.rig_loop.design_hub_damping`) commands the
torque at rest instead: ``V = R tau / (N k_t eta)``, no back-EMF term.
"""

from __future__ import annotations

import math

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.sim.hardware import Hardware

__all__ = ["VoltageCommand"]


class VoltageCommand:
    """A torque controller driving a DC motor: ``V = drive^-1(tau, theta_dot_measured)``.

    Parameters
    ----------
    inner : Controller
        The torque controller; its attributes (``name``, ``dt``, ``design``, ``measurement``...)
        are this controller's.
    hardware : Hardware
        The rig's drive (:meth:`Hardware.voltage_for_torque`).

    Attributes
    ----------
    command : str
        ``"voltage"``: the output is in volts.
    """

    command = "voltage"

    def __init__(self, inner, hardware: Hardware):
        if not isinstance(hardware, Hardware):
            raise ParameterError(f"hardware must be a Hardware, got {type(hardware).__name__}")
        if hardware.command != "voltage":
            raise ParameterError("VoltageCommand needs a rig with a DC motor (motor.kind = 'dc_motor')")
        self.inner = inner
        self.hardware = hardware
        #: the design carries the back-EMF (DesignModel.hub_damping): the static inverse leaves it out
        self.cancels_back_emf = not getattr(getattr(inner, "design", None), "hub_damping", 0.0)
        self._emf = hardware.back_emf_constant() if self.cancels_back_emf else 0.0
        if inner.measurement != "sensors":
            self._rate_index = inner.state_modes + 1
        else:
            signals = getattr(inner, "signals", None) or ("theta", "theta_dot")
            self._rate_index = list(signals).index("theta_dot") if "theta_dot" in signals else None
            if self._rate_index is None and not hasattr(inner, "estimator"):
                raise ParameterError(f"controller {getattr(inner, 'name', '?')!r} on a DC motor needs the hub rate: "
                                     "the rig has no sensors.rate and the controller no estimator")
        self.last_torque = float("nan")
        self._last_rate = 0.0

    def __getattr__(self, name):             # name, dt, design, n_modes, settings, reference...
        if name in ("inner", "hardware"):
            raise AttributeError(name)
        return getattr(self.inner, name)

    def reset(self) -> None:
        """Reset the torque controller."""
        self.inner.reset()
        self.last_torque = float("nan")
        self._last_rate = 0.0

    def stats(self) -> dict:
        """The torque controller's statistics."""
        return dict(self.inner.stats()) if hasattr(self.inner, "stats") else {}

    def feedback_matrices(self) -> tuple:
        """The voltage law, sensors -> volts: ``V = tau / g + k_e N theta_dot``, with ``g`` the
        drive's torque per volt (:meth:`~hubbeam_ctrl.sim.hardware.Hardware.torque_per_volt`) and the
        measured hub rate (or the estimator's, at the instant the command acts, on a rig without a
        rate sensor); ``V = tau / g`` when the design carries the back-EMF."""
        Ak, Bk, Ck, Dk, states, inputs = self.inner.feedback_matrices()
        g, emf = self.hardware.torque_per_volt(), self._emf
        Ck, Dk = np.atleast_2d(Ck) / g, np.atleast_2d(Dk) / g
        if self._rate_index is not None:
            Dk = Dk.copy()
            Dk[0, list(inputs).index("theta_dot")] += emf
        else:
            est = self.inner.estimator
            r = self.rate_row()[None, :]
            M = np.eye(est.A.shape[0]) - est.L @ est.C
            Ck = Ck + emf * r @ M
            Dk = Dk + emf * r @ est.L
        return Ak, Bk, Ck, Dk, states, inputs

    def rate_row(self) -> np.ndarray:
        """The estimated hub rate where the command acts as a row on the filter's state
        (:meth:`controllers.DesignModel.acting_state`, with the estimated disturbance of integral
        action acting with the previous command).

        Returns
        -------
        ndarray (nz,)
            [rad/s per filter state unit].
        """
        est, fm = self.inner.estimator, self.inner.filter_model
        r = fm.action_gain(np.eye(fm.n_x)[fm.n_x // 2][None, :])[0]
        row = np.r_[r, np.zeros(est.A.shape[0] - len(r))]
        if getattr(self.inner, "integral", False) and fm.delay > 0.0:
            row[-1] += float(fm.action_map()[1][fm.n_x // 2])
        return row

    def _rate(self, y) -> float:
        """The hub rate [rad/s] the back-EMF is compensated with."""
        if self._rate_index is not None:
            return float(np.asarray(y)[self._rate_index])
        fm = self.inner.filter_model
        x_hat = self.inner.estimator.x_hat
        d = float(x_hat[-1]) if getattr(self.inner, "integral", False) else 0.0
        return float(fm.acting_state(x_hat, d)[fm.n_x // 2]) + fm.spin

    def __call__(self, t: float, y) -> float:
        """Voltage [V] at time ``t`` [s] from measurement ``y``."""
        tau = float(self.inner(t, y))
        self.last_torque = tau
        self._last_rate = self._rate(y)
        if not self.cancels_back_emf:
            return self._torque_at_rest(tau)
        clipped = self.hardware.clipped_torque(tau, self._last_rate)
        if clipped is not None and hasattr(self.inner, "applied"):
            # the voltage clipped at V_max (the back-EMF eats the rest) gives less torque than the law's:
            # its filter predicts with that torque (without it the filter wound up and the command
            # chattered between the limit and a fraction of it: servo_payload at 1.1 T*, 9.8 V steps)
            self.inner.applied(clipped)
        return self.hardware.voltage_for_torque(tau, self._last_rate)

    def _torque_at_rest(self, tau: float) -> float:
        """The voltage [V] whose torque at rest is ``tau`` [N m] (the gear's efficiency for the
        direction of the power at the hub rate), clipped at ``V_max``; past it the filter predicts
        with the torque at rest of ``+-V_max``."""
        rate = self._last_rate
        v = float(self.hardware.voltage_needed(tau, rate)) - self.hardware.back_emf_constant() * rate
        v_max = self.hardware.drive.V_max
        if abs(v) > v_max:
            if hasattr(self.inner, "applied"):
                self.inner.applied(tau * v_max / abs(v))
            return math.copysign(v_max, v)
        return v

    def applied(self, command: float) -> None:
        """The drive gave ``command`` [V], not the voltage just returned (an amplifier's slew-rate
        limit): the torque law's filter predicts with the torque it makes at the rate it was computed
        for (the drive linearised while motoring).

        Parameters
        ----------
        command : float
            The voltage applied [V].
        """
        if hasattr(self.inner, "applied"):
            g = self.hardware.torque_per_volt()
            self.inner.applied(g * (float(command) - self._emf * self._last_rate))
