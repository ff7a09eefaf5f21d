"""Hub maneuvers: the paper's spin-up (Eq. 43, corrected) and torque (Eq. 44) profiles.

A maneuver is either *prescribed* (it gives ``theta(t)``, ``theta_dot(t)``,
``theta_ddot(t)``; the hub is driven kinematically) or *torque* (it gives ``tau(t)`` on a
free hub). Each built-in works both on NumPy arrays and on CasADi symbols, so the whole
integration stays inside compiled CasADi code.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.settings import Settings, setting

__all__ = ["SpinUp", "TorquePulse", "ConstantSpin", "UserManeuver", "spinup_rate"]


def _is_symbolic(t) -> bool:
    return isinstance(t, (ca.SX, ca.MX, ca.DM))


def _where(cond, a, b, t):
    return ca.if_else(cond, a, b) if _is_symbolic(t) else np.where(cond, a, b)


def _sin(z, t):
    return ca.sin(z) if _is_symbolic(t) else np.sin(z)


def _cos(z, t):
    return ca.cos(z) if _is_symbolic(t) else np.cos(z)


@dataclass(frozen=True)
class SpinUp(Settings):
    """Kane-Ryan-Banerjee spin-up, the paper's Eq. (43) with its lost factor ``t`` restored.

    ``thd = (w_f/t_f) t - (w_f/2pi) sin(2pi t/t_f)`` for ``0 <= t <= t_f``, ``w_f`` after;
    ``theta = (w_f/t_f)[t^2/2 + (t_f/2pi)^2 (cos(2pi t/t_f) - 1)]`` up to ``t_f``.
    """

    w_f: float = setting(3.0, unit="rad/s", doc="Final hub rate.")
    t_f: float = setting(30.0, unit="s", lo=0.0, lo_open=True, doc="Spin-up time.")
    kind = "prescribed"

    def __call__(self, t):
        """Return ``(theta [rad], theta_dot [rad/s], theta_ddot [rad/s^2])`` at ``t`` [s]."""
        wf, tf = self.w_f, self.t_f
        w = 2 * math.pi / tf
        theta_in = (wf / tf) * (t ** 2 / 2 + (_cos(w * t, t) - 1) / w ** 2)
        theta_out = (wf / tf) * (tf ** 2 / 2) + wf * (t - tf)
        thd_in = (wf / tf) * t - (wf / (2 * math.pi)) * _sin(w * t, t)
        thdd_in = (wf / tf) * (1 - _cos(w * t, t))
        inside = t <= tf
        return (_where(inside, theta_in, theta_out, t),
                _where(inside, thd_in, wf + 0 * t, t),
                _where(inside, thdd_in, 0 * t, t))


def spinup_rate(t, w_f: float, t_f: float):
    """Hub rate of the corrected Eq. (43) spin-up [rad/s] at times ``t`` [s]."""
    return SpinUp(w_f, t_f)(np.asarray(t, dtype=float))[1]


@dataclass(frozen=True)
class TorquePulse(Settings):
    """The paper's Eq. (44): ``tau = tau_m sin(2 pi t / t_f)`` for ``t <= t_f``, then 0.

    One full sine period (``T = t_f``): the hub starts and ends at rest after turning by
    the rigid-body angle ``tau_m t_f^2 / (2 pi J_total)``.
    """

    tau_m: float = setting(200.0, unit="N m", lo=0.0, lo_open=True, doc="Torque amplitude.")
    t_f: float = setting(10.0, unit="s", lo=0.0, lo_open=True, doc="Maneuver time (one sine period).")
    kind = "torque"

    def __call__(self, t):
        """Hub torque [N m] at ``t`` [s]."""
        return _where(t <= self.t_f, self.tau_m * _sin(2 * math.pi * t / self.t_f, t), 0 * t, t)

    def rigid_angle(self, total_inertia: float) -> float:
        """Rest-to-rest rigid-body rotation ``tau_m t_f^2 / (2 pi J)`` [rad]."""
        return self.tau_m * self.t_f ** 2 / (2 * math.pi * total_inertia)


@dataclass(frozen=True)
class ConstantSpin(Settings):
    """Hub turning at a constant rate (prescribed)."""

    spin: float = setting(0.0, unit="rad/s", doc="Hub rate.")
    kind = "prescribed"

    def __call__(self, t):
        """Return ``(theta [rad], theta_dot [rad/s], theta_ddot [rad/s^2])`` at ``t`` [s]."""
        return self.spin * t, self.spin + 0 * t, 0 * t


class UserManeuver:
    """Wrap a user function of time as a maneuver.

    Parameters
    ----------
    func : callable
        ``func(t)``: for ``kind="torque"`` the hub torque [N m]; for ``kind="prescribed"``
        a tuple ``(theta, theta_dot, theta_ddot)`` [rad, rad/s, rad/s^2]. If ``func``
        accepts a CasADi symbol (plain arithmetic, ``numpy`` ufuncs or ``casadi``
        functions do) it is used exactly; otherwise it is tabulated on ``table_dt`` and
        interpolated linearly.
    kind : {"torque", "prescribed"}
    table_dt : float
        Tabulation step [s] for functions that are not CasADi-compatible.
    """

    def __init__(self, func, kind: str = "torque", table_dt: float = 1e-3):
        if kind not in ("torque", "prescribed"):
            raise ParameterError(f"kind must be 'torque' or 'prescribed', got {kind!r}")
        if not callable(func):
            raise ParameterError("maneuver must be callable")
        self.func, self.kind, self.table_dt = func, kind, table_dt
        self._t_end = None

    def bind(self, t_end: float):
        """Prepare tabulation up to ``t_end`` [s] if the function is not symbolic."""
        self._t_end = t_end
        return self

    def __call__(self, t):
        if not _is_symbolic(t):
            return self.func(t)
        try:
            out = self.func(t)
            outs = out if isinstance(out, tuple) else (out,)
            outs = tuple(ca.SX(o) if not isinstance(o, (ca.SX, ca.MX)) else o for o in outs)
            return outs if self.kind == "prescribed" else outs[0]
        except Exception:
            if self._t_end is None:
                raise
        grid = np.arange(0.0, self._t_end + 2 * self.table_dt, self.table_dt)
        values = [np.asarray(self.func(tk), dtype=float) for tk in grid]
        cols = np.atleast_2d(np.array(values).T) if self.kind == "prescribed" else [np.array(values)]
        interps = [ca.interpolant(f"user{k}", "linear", [grid], np.asarray(c).ravel().tolist())
                   for k, c in enumerate(cols)]
        outs = tuple(f(t) for f in interps)
        return outs if self.kind == "prescribed" else outs[0]
