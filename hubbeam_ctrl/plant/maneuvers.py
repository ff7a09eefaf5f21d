"""Hub maneuvers: the paper's spin-up (Eq. 43, corrected) and torque (Eq. 44) profiles.

A maneuver is either *prescribed* (it gives ``theta(t)``, ``theta_dot(t)``,
``theta_ddot(t)``; the hub is driven kinematically) or *torque* (it gives ``tau(t)`` on a
free hub). Each built-in works both on NumPy arrays and on CasADi symbols, so the whole
integration stays inside compiled CasADi code.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import casadi as ca
import numpy as np

from hubbeam_ctrl.core.errors import ParameterError, UserFunctionError
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

    w_f: float = setting(3.0, unit="rad/s", lo=-1e4, hi=1e4,
                         doc="Final hub rate; a simulation also needs abs(w_f) <= Params.max_spin.")
    t_f: float = setting(30.0, unit="s", lo=1e-3, hi=1e6, doc="Spin-up time.")
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
    """Hub rate of the corrected Eq. (43) spin-up [rad/s] at times ``t`` [s].

    Parameters
    ----------
    t : float or array_like
        Time(s) [s].
    w_f : float
        Final rate [rad/s].
    t_f : float
        Spin-up time [s].
    """
    return SpinUp(w_f, t_f)(np.asarray(t, dtype=float))[1]


@dataclass(frozen=True)
class TorquePulse(Settings):
    """The paper's Eq. (44): ``tau = tau_m sin(2 pi t / t_f)`` for ``t <= t_f``, then 0.

    One full sine period (``T = t_f``): the hub starts and ends at rest after turning by
    the rigid-body angle ``tau_m t_f^2 / (2 pi J_total)``.
    """

    tau_m: float = setting(200.0, unit="N m", lo=0.0, lo_open=True, hi=1e9,
                           doc="Torque amplitude; a simulation also needs the peak rigid rate "
                               "tau_m t_f / (pi J_total) <= Params.max_spin.")
    t_f: float = setting(10.0, unit="s", lo=1e-3, hi=1e6, doc="Maneuver time (one sine period).")
    kind = "torque"

    def __call__(self, t):
        """Hub torque [N m] at ``t`` [s]."""
        return _where(t <= self.t_f, self.tau_m * _sin(2 * math.pi * t / self.t_f, t), 0 * t, t)

    def rigid_angle(self, total_inertia: float) -> float:
        """Rest-to-rest rigid-body rotation ``tau_m t_f^2 / (2 pi J)`` [rad].

        Parameters
        ----------
        total_inertia : float
            Rigid-body inertia about the hub axis ``J_total`` [kg m^2].
        """
        return self.tau_m * self.t_f ** 2 / (2 * math.pi * total_inertia)


@dataclass(frozen=True)
class ConstantSpin(Settings):
    """Hub turning at a constant rate (prescribed)."""

    spin: float = setting(0.0, unit="rad/s", lo=-1e4, hi=1e4,
                          doc="Hub rate; a simulation also needs abs(spin) <= Params.max_spin.")
    kind = "prescribed"

    def __call__(self, t):
        """Return ``(theta [rad], theta_dot [rad/s], theta_ddot [rad/s^2])`` at ``t`` [s]."""
        return self.spin * t, self.spin + 0 * t, 0 * t


def _function_name(func) -> str:
    name = getattr(func, "__qualname__", None) or getattr(func, "__name__", None)
    return str(name) if name else type(func).__name__


_NUMERIC = (int, float, np.ndarray, np.integer, np.floating)

#: Largest number of points a user function is tabulated on (the step grows beyond it).
MAX_TABLE_POINTS = 1_000_000


class UserManeuver:
    """Wrap a user function of time as a maneuver.

    Parameters
    ----------
    func : callable
        ``func(t)``: for ``kind="torque"`` the hub torque [N m]; for ``kind="prescribed"``
        a tuple ``(theta, theta_dot, theta_ddot)`` [rad, rad/s, rad/s^2]. Each value may
        be a number, a NumPy scalar or 0-d array (a constant), or an expression of ``t``.
        If ``func`` accepts a CasADi symbol (plain arithmetic, ``numpy`` ufuncs or
        ``casadi`` functions do) it is used exactly; otherwise it is tabulated on
        ``table_dt`` and interpolated linearly.
    kind : {"torque", "prescribed"}
    table_dt : float
        Tabulation step [s] for functions that are not CasADi-compatible (grown so that
        the table has at most :data:`MAX_TABLE_POINTS` points).
    name : str, optional
        Name used in messages (default: the function's ``__qualname__``).

    Notes
    -----
    A function that raises or returns a non-finite value or not one number per output
    raises :class:`~hubbeam_ctrl.core.errors.UserFunctionError` naming it and the time.
    When it does so only after some time, :meth:`bind` records where (``valid_until``,
    ``failure``) and :func:`~hubbeam_ctrl.sim.simulate.simulate` stops there, keeping what
    was computed. Wrapped functions are not cached (every run builds its own integrator).

    Examples
    --------
    >>> m = UserManeuver(lambda t: 100.0)
    >>> float(m(2.0))
    100.0
    >>> UserManeuver(lambda t: float("nan"), name="bad")(0.0)
    Traceback (most recent call last):
    ...
    hubbeam_ctrl.core.errors.UserFunctionError: torque function bad returned nan at t = 0 s
    """

    __hash__ = None   # the tabulation depends on bind(): never a cache key

    def __init__(self, func, kind: str = "torque", table_dt: float = 1e-3, name: str | None = None):
        if kind not in ("torque", "prescribed"):
            raise ParameterError(f"kind must be 'torque' or 'prescribed', got {kind!r}")
        if not callable(func):
            raise ParameterError(f"maneuver must be callable, got {type(func).__name__}")
        if isinstance(table_dt, bool) or not isinstance(table_dt, (int, float, np.number)) \
                or not 1e-6 <= table_dt <= 1.0:
            raise ParameterError(f"table_dt must be a number in [1e-06, 1] [s], got {table_dt!r}")
        self.func, self.kind, self.table_dt = func, kind, float(table_dt)
        self.name = str(name) if name is not None else _function_name(func)
        self.n_out = 3 if kind == "prescribed" else 1
        self._t_end = None
        self.valid_until = None
        self.failure = None

    @property
    def label(self) -> str:
        """``"torque function NAME"`` or ``"maneuver function NAME"`` (for messages)."""
        return f"{'torque' if self.kind == 'torque' else 'maneuver'} function {self.name}"

    def __repr__(self):
        return f"UserManeuver({self.name}, kind={self.kind!r})"

    # -- numeric evaluation --------------------------------------------------------
    def _parts(self, out) -> tuple:
        """Split one return value into its ``n_out`` parts, or raise naming the function."""
        if self.kind == "prescribed":
            if isinstance(out, (tuple, list)) and len(out) == 3:
                return tuple(out)
            arr = np.asarray(out, dtype=object) if not _is_symbolic(out) else None
            if arr is not None and arr.shape[:1] == (3,):
                return tuple(arr)
            raise UserFunctionError(f"{self.label} must return (theta, theta_dot, theta_ddot), "
                                    f"got {_what(out)}")
        return (out,)

    def _scalar(self, value, t: float) -> float:
        """One part of a return value at one time as a float, or raise naming the function."""
        arr = None
        if not isinstance(value, (list, tuple, dict, set, str, bytes, bool, np.bool_)):
            try:
                arr = np.asarray(value, dtype=float)
            except (TypeError, ValueError, OverflowError):
                pass
        if arr is None or arr.size != 1:
            raise UserFunctionError(f"{self.label} must return a number at t = {t:g} s, got "
                                    f"{_what(value)}", t)
        x = float(arr.reshape(()))
        if not math.isfinite(x):
            raise UserFunctionError(f"{self.label} returned {x} at t = {t:g} s", t)
        return x

    def _call(self, t):
        try:
            return self.func(t)
        except Exception as exc:   # the caller's code: report it with its name and the time
            tt = float(np.asarray(t).ravel()[0]) if np.size(t) == 1 else None
            detail = str(exc).splitlines()[0][:200] if str(exc) else ""
            text = f"{self.label} raised {type(exc).__name__}" + (f": {detail}" if detail else "")
            at = f" at t = {tt:g} s" if tt is not None else ""
            raise UserFunctionError(text + at, tt) from exc

    def evaluate(self, t) -> tuple:
        """Values at the times ``t`` [s], stopping at the first bad one.

        Parameters
        ----------
        t : array_like (N,)

        Returns
        -------
        values : ndarray (n_out, k)
            The values at the first ``k`` times (``k = N`` when all are good).
        error : UserFunctionError or None
            Why the evaluation stopped at ``t[k]``.
        """
        t = np.atleast_1d(np.asarray(t, dtype=float))
        values = self._vectorized(t)
        if values is not None:
            return values, None
        out = np.empty((self.n_out, len(t)))
        for k, tk in enumerate(t):
            try:
                out[:, k] = [self._scalar(v, tk) for v in self._parts(self._call(tk))]
            except UserFunctionError as exc:
                if exc.t is None:
                    exc.t = float(tk)
                return out[:, :k], exc
        return out, None

    def _vectorized(self, t):
        """All values from one call on the whole array, or None (then element by element)."""
        try:
            parts = self._parts(self.func(t))
            if not all(isinstance(p, _NUMERIC) and not isinstance(p, bool) and np.asarray(p).dtype.kind in "fiu"
                       and np.shape(p) in ((), t.shape) for p in parts):
                return None
            cols = [np.broadcast_to(np.asarray(p, dtype=float), t.shape) for p in parts]
        except Exception:
            return None
        values = np.array(cols)
        return values if np.all(np.isfinite(values)) else None

    def __call__(self, t):
        if isinstance(t, (ca.SX, ca.MX)):
            return self._symbolic(t)
        scalar = np.ndim(t) == 0
        values, error = self.evaluate(t)
        if error is not None:
            raise error
        outs = tuple(v[0] if scalar else v for v in values)
        return outs if self.kind == "prescribed" else outs[0]

    # -- symbolic use in the integrators -------------------------------------------
    def bind(self, t_end: float):
        """Prepare tabulation up to ``t_end`` [s] if the function is not symbolic.

        Parameters
        ----------
        t_end : float
            End of the run [s].
        """
        self._t_end = float(t_end)
        self.valid_until = self.failure = None
        return self

    def _symbolic(self, t):
        try:
            parts, trusted = self._trace(t)
        except UserFunctionError:
            raise
        except Exception:
            return self._tabulated(t)
        if not trusted:
            return self._tabulated(t)
        outs = []
        for p in parts:
            if isinstance(p, type(t)):
                if p.numel() != 1:
                    raise UserFunctionError(f"{self.label} must return a number, got {p.shape} values")
                outs.append(p)
            elif isinstance(p, (ca.SX, ca.MX)) and not p.is_constant():
                return self._tabulated(t)          # an expression of other symbols
            else:                                  # a constant: the same at every time...
                try:
                    outs.append(type(t)(self._scalar(ca.DM(p) if _is_symbolic(p) else p, 0.0)))
                except UserFunctionError:          # ...or math.sin(SX symbol), which gives NaN:
                    return self._tabulated(t)      # the table says which
        return tuple(outs) if self.kind == "prescribed" else outs[0]

    def _trace(self, t) -> tuple:
        """``(parts, trusted)`` of ``func`` called on the symbol ``t``, no warning let through.

        NumPy functions on a CasADi symbol (``50 * np.sin(t)``) give the CasADi expression
        with CasADi's FutureWarning about NumPy interoperability: the expression is kept, the
        warning dropped. Any other warning raised while tracing (the user's code reacting to a
        symbol) makes the trace untrusted: the function is then evaluated on numbers only.
        """
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            parts = self._parts(self.func(t))
        trusted = all(_casadi_numpy_warning(w) for w in caught)
        return parts, trusted

    def _tabulated(self, t):
        if self._t_end is None:
            raise UserFunctionError(f"{self.label} does not accept a CasADi symbol; call bind(t_end) "
                                    "first so that it can be tabulated")
        step = max(self.table_dt, (self._t_end + 2 * self.table_dt) / MAX_TABLE_POINTS)
        grid = np.arange(0.0, self._t_end + 2 * step, step)
        values, error = self.evaluate(grid)
        if error is not None:
            k = values.shape[1]
            if k < 2:
                raise error
            self.valid_until, self.failure = float(grid[k - 1]), str(error)
            values = np.hstack([values, np.repeat(values[:, -1:], len(grid) - k, axis=1)])
        interps = [ca.interpolant(f"user{k}", "linear", [grid], row.tolist())
                   for k, row in enumerate(values)]
        outs = tuple(f(t) for f in interps)
        return outs if self.kind == "prescribed" else outs[0]


def _casadi_numpy_warning(w) -> bool:
    """Whether a recorded warning is CasADi's note on a NumPy function called on its value."""
    return issubclass(w.category, FutureWarning) and "numpy function was called on a casadi value" in str(w.message)


def _what(value) -> str:
    """Short description of a bad return value."""
    if isinstance(value, (list, tuple)):
        return f"a {type(value).__name__} of {len(value)}"
    if isinstance(value, np.ndarray) or _is_symbolic(value):
        return f"an array of shape {tuple(value.shape)}"
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."
