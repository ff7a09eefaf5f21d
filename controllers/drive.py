"""Commanding a DC motor: a torque design's output turned into the drive's voltage.

The designs compute a hub torque. A rig with a DC motor and gearbox is driven in volts
through back-EMF, resistance and the gear's efficiency
(:mod:`hubbeam_ctrl.sim.hardware`). :class:`VoltageCommand` inverts that static relation at
every sample with the measured hub rate, ``V = R tau / (N k_t eta) + k_e N theta_dot``,
clipped at the amplifier's ``V_max``: back-EMF compensation, the standard inner loop of a
servo drive. What the inversion misses (the clip, the current limit, a wrong constant,
friction) is a torque error the integral action of :mod:`controllers.integral` removes.
"""

from __future__ import annotations

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
        self._rate_index = 1 if inner.measurement == "sensors" else inner.state_modes + 1
        self.last_torque = float("nan")

    def __getattr__(self, name):             # name, dt, design, n_modes, settings, reference...
        if name in ("inner", "hardware"):
            raise AttributeError(name)
        return getattr(self.inner, name)

    def reset(self) -> None:
        """Reset the torque controller."""
        self.inner.reset()
        self.last_torque = float("nan")

    def stats(self) -> dict:
        """The torque controller's statistics."""
        return dict(self.inner.stats()) if hasattr(self.inner, "stats") else {}

    def feedback_matrices(self) -> tuple:
        """The torque law's (the inversion makes the drive a unit gain from torque to torque)."""
        return self.inner.feedback_matrices()

    def __call__(self, t: float, y) -> float:
        """Voltage [V] at time ``t`` [s] from measurement ``y``."""
        tau = float(self.inner(t, y))
        self.last_torque = tau
        return self.hardware.voltage_for_torque(tau, float(np.asarray(y)[self._rate_index]))
