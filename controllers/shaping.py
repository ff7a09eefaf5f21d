"""Input shapers (ZV, ZVD, EI), their multi-mode convolution and residual vibration.

An input shaper is a short train of impulses ``A_i delta(t - t_i)`` (``sum A_i = 1``,
``t_1 = 0``); convolving a command with it leaves (almost) no residual vibration in a
lightly damped mode. With the mode's natural frequency ``omega`` [rad/s], damping ratio
``zeta``, damped frequency ``omega_d = omega sqrt(1 - zeta^2)``, damped period
``T_d = 2 pi / omega_d`` and ``K = exp(-zeta pi / sqrt(1 - zeta^2))``:

* **ZV** (zero vibration): ``A = [1, K] / (1 + K)`` at ``t = [0, T_d/2]``;
* **ZVD** (zero vibration and derivative): ``A = [1, 2K, K^2] / (1 + K)^2`` at
  ``t = [0, T_d/2, T_d]``;
* **EI** (extra insensitive, Singer-Seering / Singhose): three impulses that leave the
  residual ``V_tol`` (e.g. 5 %) at the nominal frequency, where the residual has a local
  maximum (zero derivative), and exactly zero at two frequencies either side, which widens
  the band of frequencies where the residual stays below ``V_tol``. For ``zeta = 0`` the
  closed form is ``A = [(1 + V), 2 (1 - V), (1 + V)] / 4`` at ``t = [0, T_d/2, T_d]``.
  For ``zeta > 0`` this module solves the defining equations numerically (six equations
  for ``A_1, A_3, t_2, t_3`` and the two zero-residual frequencies: ``V(omega) = V_tol``,
  ``dV/domega = 0`` there, and both components of the residual zero at the side
  frequencies; Powell's hybrid method from the undamped form, by continuation in ``zeta``).
  Keeping the zero derivative makes the nominal frequency the top of the hump, so the
  residual stays below ``V_tol`` over the whole band between the side frequencies.
  Singhose's published curve fit for damped EI shapers instead fixes ``t_3 = T_d`` and
  drops the derivative condition; the amplitudes of the two agree to about 1e-3 and the
  times to 1 % of ``T_d`` for ``zeta <= 0.2`` (checked in the tests).

The *percentage residual vibration* of a shaper for a mode (Singer and Seering 1990) is
the amplitude of the vibration left after the last impulse ``t_N``, relative to that of a
single unit impulse observed the same time after it is applied (so a damped mode's
natural decay over the shaper's length does not count as suppression)::

    V(omega, zeta) = exp(-zeta omega t_N) |sum_i A_i exp(zeta omega t_i) exp(j omega_d t_i)|

(``1`` = unshaped, ``0`` = none left). Several modes are shaped by convolving their
shapers (:meth:`Shaper.convolve`): the result's residual in each mode is at most that of
the mode's own shaper.

Examples
--------
>>> s = zv_shaper(2 * np.pi, 0.0)          # a 1 Hz undamped mode
>>> s.times.tolist(), s.amplitudes.tolist()
([0.0, 0.5], [0.5, 0.5])
>>> float(s.residual(2 * np.pi)) < 1e-15
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.validation import check_positive

__all__ = ["Shaper", "zv_shaper", "zvd_shaper", "ei_shaper", "make_shaper", "SHAPERS",
           "residual_vibration", "ei_side_frequencies", "design_modes", "design_shaper", "as_shaper",
           "shaper_sensitivity", "shape_reference"]

#: Shaper kinds understood by :func:`make_shaper`.
SHAPERS = ("zv", "zvd", "ei")

#: Impulses closer in time than this [s] are merged by :meth:`Shaper.convolve`.
MERGE_TOL = 1e-12


# -- validation ---------------------------------------------------------------------------
def _check_mode(frequency, damping) -> tuple:
    """Validate a mode: natural frequency > 0 [rad/s], damping ratio in [0, 1)."""
    w = check_positive("frequency", frequency, "rad/s")
    if isinstance(damping, bool) or not isinstance(damping, (int, float, np.floating, np.integer)) \
            or not math.isfinite(damping) or not 0.0 <= damping < 1.0:
        raise ParameterError(f"damping must be a finite number in [0, 1) [-], got {damping!r}")
    return w, float(damping)


def _check_tolerance(tolerance) -> float:
    if isinstance(tolerance, bool) or not isinstance(tolerance, (int, float, np.floating, np.integer)) \
            or not math.isfinite(tolerance) or not 0.0 < tolerance < 0.5:
        raise ParameterError(f"tolerance must be a finite number in (0, 0.5) [-] (the EI shaper's "
                             f"allowed residual, e.g. 0.05), got {tolerance!r}")
    return float(tolerance)


# -- the shaper -----------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Shaper:
    """A train of impulses ``sum_i A_i delta(t - t_i)`` with ``sum A_i = 1``.

    Attributes
    ----------
    times : ndarray (N,)
        Impulse times [s], ascending, the first at 0.
    amplitudes : ndarray (N,)
        Impulse amplitudes [-], summing to 1.
    name : str
        E.g. ``"zvd"`` or ``"zvd*zv"`` for a convolution.
    """

    times: np.ndarray
    amplitudes: np.ndarray
    name: str = "shaper"

    def __post_init__(self):
        t = np.asarray(self.times, dtype=float).ravel()
        a = np.asarray(self.amplitudes, dtype=float).ravel()
        if t.size == 0 or t.shape != a.shape or not (np.all(np.isfinite(t)) and np.all(np.isfinite(a))):
            raise ParameterError("shaper times and amplitudes must be finite arrays of equal, non-zero length")
        if abs(t[0]) > MERGE_TOL or np.any(np.diff(t) < 0):
            raise ParameterError("shaper times must be ascending from 0 [s]")
        if abs(a.sum() - 1.0) > 1e-9:
            raise ParameterError(f"shaper amplitudes must sum to 1, got {a.sum():.12g}")
        object.__setattr__(self, "times", t)
        object.__setattr__(self, "amplitudes", a)

    @property
    def duration(self) -> float:
        """Time of the last impulse [s]: the delay the shaper adds to a command."""
        return float(self.times[-1])

    def residual(self, frequency, damping: float = 0.0) -> np.ndarray:
        """Percentage residual vibration (as a fraction) for modes at ``frequency``.

        See :func:`residual_vibration`.

        Parameters
        ----------
        frequency : float or array_like
            Natural frequency of the mode(s) [rad/s].
        damping : float
            Damping ratio [-], 0 <= zeta < 1.
        """
        return residual_vibration(self, frequency, damping)

    def convolve(self, other: "Shaper") -> "Shaper":
        """The shaper of two shapers in series (multi-mode shaping).

        Impulse times add and amplitudes multiply; coincident impulses are merged.

        Parameters
        ----------
        other : Shaper

        Returns
        -------
        Shaper
            Duration ``self.duration + other.duration``; name ``"self*other"``.
        """
        if not isinstance(other, Shaper):
            raise ParameterError(f"other must be a Shaper, got {type(other).__name__}")
        t = (self.times[:, None] + other.times[None, :]).ravel()
        a = (self.amplitudes[:, None] * other.amplitudes[None, :]).ravel()
        order = np.argsort(t, kind="stable")
        t, a = t[order], a[order]
        new = np.r_[True, np.diff(t) > MERGE_TOL]
        groups = np.cumsum(new) - 1
        return Shaper(t[new], np.bincount(groups, weights=a), f"{self.name}*{other.name}")

    def apply(self, signal, t):
        """Shape a signal given as a function of time: ``sum_i A_i signal(t - t_i)``.

        Parameters
        ----------
        signal : callable
            ``signal(t)`` of an array of times [s] (it must accept negative times).
        t : array_like
            Times [s].

        Returns
        -------
        ndarray
        """
        t = np.asarray(t, dtype=float)
        return sum(a * np.asarray(signal(t - ti), dtype=float) for ti, a in zip(self.times, self.amplitudes))

    def __repr__(self):
        return (f"Shaper({self.name!r}, {len(self.times)} impulses over {self.duration:.6g} s, "
                f"min amplitude {self.amplitudes.min():.4g})")


def residual_vibration(shaper: Shaper, frequency, damping: float = 0.0) -> np.ndarray:
    """Percentage residual vibration of ``shaper`` for a mode, as a fraction.

    ``V = exp(-zeta omega t_N) |sum_i A_i exp(zeta omega t_i) exp(j omega_d t_i)|`` with
    ``omega_d = omega sqrt(1 - zeta^2)``: the amplitude of the vibration at ``t_N + s``
    relative to that of an unshaped unit impulse at time ``s`` after it (``V = 1``) [-].

    Parameters
    ----------
    shaper : Shaper
    frequency : float or array_like
        Natural frequency (or frequencies) ``omega`` of the mode [rad/s], > 0.
    damping : float
        Damping ratio ``zeta`` [-], 0 <= zeta < 1.

    Returns
    -------
    ndarray
        Same shape as ``frequency``.

    Examples
    --------
    >>> round(float(residual_vibration(zvd_shaper(1.0), 1.2)), 4)    # ZVD 20 % off
    0.0955
    """
    if not isinstance(shaper, Shaper):
        raise ParameterError(f"shaper must be a Shaper, got {type(shaper).__name__}")
    w = np.asarray(frequency, dtype=float)
    if not (np.all(np.isfinite(w)) and np.all(w > 0)):
        raise ParameterError("frequency must be finite numbers > 0 [rad/s]")
    _check_mode(1.0, damping)
    s = -damping * w[..., None] + 1j * w[..., None] * math.sqrt(1.0 - damping ** 2)
    # relative to the last impulse, so that the exponentials never overflow
    z = np.sum(shaper.amplitudes * np.exp(-s * (shaper.times - shaper.duration)), axis=-1)
    return np.abs(z)


# -- the closed forms -----------------------------------------------------------------------
def _damped(frequency, damping):
    w, z = _check_mode(frequency, damping)
    wd = w * math.sqrt(1.0 - z * z)
    K = math.exp(-z * math.pi / math.sqrt(1.0 - z * z))
    return 2 * math.pi / wd, K


def zv_shaper(frequency: float, damping: float = 0.0) -> Shaper:
    """Zero-vibration shaper: ``[1, K]/(1 + K)`` at ``[0, T_d/2]``.

    Parameters
    ----------
    frequency : float
        Natural frequency of the mode [rad/s], > 0.
    damping : float
        Damping ratio [-], 0 <= zeta < 1.

    Returns
    -------
    Shaper
    """
    Td, K = _damped(frequency, damping)
    return Shaper(np.array([0.0, 0.5 * Td]), np.array([1.0, K]) / (1.0 + K), "zv")


def zvd_shaper(frequency: float, damping: float = 0.0) -> Shaper:
    """Zero-vibration-and-derivative shaper: ``[1, 2K, K^2]/(1 + K)^2`` at ``[0, T_d/2, T_d]``
    (robust to a frequency error, twice as long as :func:`zv_shaper`).

    Parameters
    ----------
    frequency, damping : float
        As :func:`zv_shaper`.
    """
    Td, K = _damped(frequency, damping)
    return Shaper(np.array([0.0, 0.5 * Td, Td]), np.array([1.0, 2 * K, K * K]) / (1.0 + K) ** 2, "zvd")


# -- EI: the defining equations ---------------------------------------------------------------
def _ei_residuals(u, tol, beta):
    """Defining equations of the EI shaper in normalised form.

    ``u = [A1, A3, tau2, tau3, r_lo, r_hi]``: amplitudes, impulse times in units of the
    nominal damped period, and the two frequency ratios of zero residual. With
    ``p(r) = 2 pi r (beta + j)`` (``beta = zeta / sqrt(1 - zeta^2)``) the residual is
    ``z(r) = sum A_i exp(p(r) (tau_i - tau3))``; the equations are ``|z(1)| = tol``,
    ``d|z|^2/dr (1) = 0``, ``z(r_lo) = 0`` and ``z(r_hi) = 0`` (real and imaginary parts).
    """
    a1, a3, t2, t3, r_lo, r_hi = u
    A = np.array([a1, 1.0 - a1 - a3, a3])
    tau = np.array([0.0, t2, t3]) - t3
    c = 2 * math.pi * (beta + 1j)

    def z(r):
        return np.sum(A * np.exp(c * r * tau))

    z1 = z(1.0)
    dz1 = np.sum(A * c * tau * np.exp(c * tau))
    zl, zh = z(r_lo), z(r_hi)
    return np.array([abs(z1) - tol, 2 * (np.conj(z1) * dz1).real, zl.real, zl.imag, zh.real, zh.imag])


def _ei_undamped(tol):
    r_lo = math.acos(-(1.0 - tol) / (1.0 + tol)) / math.pi
    return np.array([(1 + tol) / 4, (1 + tol) / 4, 0.5, 1.0, r_lo, 2.0 - r_lo])


def _ei_solve(tol, damping):
    """Solve the EI equations by continuation in damping from the undamped closed form."""
    u = _ei_undamped(tol)
    if damping == 0.0:
        return u
    import scipy.optimize  # lazily: keeps the CLI's start-up light
    for z in np.linspace(0.0, damping, 1 + max(1, int(math.ceil(damping / 0.02))))[1:]:
        beta = z / math.sqrt(1.0 - z * z)
        sol = scipy.optimize.root(_ei_residuals, u, args=(tol, beta), method="hybr", tol=1e-14)
        u = sol.x
        err = np.max(np.abs(_ei_residuals(u, tol, beta)))
        A = np.array([u[0], 1 - u[0] - u[1], u[1]])
        if not (err < 1e-10 and np.all(A > 0) and 0 < u[2] < u[3] and u[4] < 1 < u[5]):
            raise ParameterError(f"damping = {damping:g}: no EI shaper found for tolerance {tol:g} "
                                 f"(defining equations left at {err:.1e}); use zvd")
    return u


def ei_shaper(frequency: float, damping: float = 0.0, tolerance: float = 0.05) -> Shaper:
    """Extra-insensitive (EI) shaper: three impulses, residual ``tolerance`` at the nominal mode.

    For ``damping = 0`` the closed form ``[(1+V)/4, (1-V)/2, (1+V)/4]`` at ``[0, T_d/2, T_d]``;
    otherwise the numerical solution of the defining equations (see the module docstring).

    Parameters
    ----------
    frequency : float
        Natural frequency of the mode [rad/s], > 0.
    damping : float
        Damping ratio [-], 0 <= zeta < 1 (solutions exist up to about 0.3).
    tolerance : float
        Allowed residual vibration ``V_tol`` [-], 0 < V_tol < 0.5 (e.g. 0.05 = 5 %).

    Returns
    -------
    Shaper
    """
    Td, _ = _damped(frequency, damping)
    tol = _check_tolerance(tolerance)
    if damping == 0.0:
        return Shaper(np.array([0.0, 0.5 * Td, Td]), np.array([1 + tol, 2 * (1 - tol), 1 + tol]) / 4, "ei")
    a1, a3, t2, t3 = _ei_solve(tol, float(damping))[:4]
    return Shaper(Td * np.array([0.0, t2, t3]), np.array([a1, 1.0 - a1 - a3, a3]), "ei")


def ei_side_frequencies(frequency: float, damping: float = 0.0, tolerance: float = 0.05) -> tuple:
    """The two frequencies [rad/s] where the EI shaper's residual is exactly zero.

    Between them lies the nominal frequency, where the residual is ``tolerance``: the
    shaper's insensitivity band.

    Parameters
    ----------
    frequency, damping, tolerance
        As :func:`ei_shaper`.

    Returns
    -------
    (float, float)
        ``(omega_lo, omega_hi)`` [rad/s].
    """
    w, z = _check_mode(frequency, damping)
    r_lo, r_hi = _ei_solve(_check_tolerance(tolerance), z)[4:]
    return w * r_lo, w * r_hi


def make_shaper(kind: str, frequency: float, damping: float = 0.0, tolerance: float = 0.05) -> Shaper:
    """Build a shaper by name.

    Parameters
    ----------
    kind : {"zv", "zvd", "ei"}
    frequency : float
        Natural frequency [rad/s], > 0.
    damping : float
        Damping ratio [-], 0 <= zeta < 1.
    tolerance : float
        EI only: allowed residual [-].

    Returns
    -------
    Shaper
    """
    if kind == "zv":
        return zv_shaper(frequency, damping)
    if kind == "zvd":
        return zvd_shaper(frequency, damping)
    if kind == "ei":
        return ei_shaper(frequency, damping, tolerance)
    raise ParameterError(f"shaper must be one of {', '.join(SHAPERS)}, got {kind!r}")


# -- shapers for the design model ---------------------------------------------------------------
def design_modes(design) -> tuple:
    """Natural frequencies and damping ratios of the design model's flexible modes.

    From the eigenvalues ``lambda`` of the continuous ``design.A`` (the rigid-body pair at
    zero left out): ``omega = |lambda|``, ``zeta = -Re(lambda) / |lambda|``; the damped
    frequency is ``Im(lambda)``.

    Parameters
    ----------
    design : DesignModel
        Linear SFOAM at its design spin (free hub).

    Returns
    -------
    frequency : ndarray (n_modes,)
        Natural frequencies [rad/s], ascending (mode 1 first).
    damping : ndarray (n_modes,)
        Damping ratios [-] (below 1e-10, round-off of an undamped model, set to 0).
    """
    from .base import DesignModel
    if not isinstance(design, DesignModel):
        raise ParameterError(f"design must be a DesignModel, got {type(design).__name__}")
    lam = np.linalg.eigvals(design.A)
    scale = max(1.0, float(np.abs(lam).max()))
    osc = lam[lam.imag > 1e-9 * scale]
    osc = osc[np.argsort(np.abs(osc))]
    w = np.abs(osc)
    zeta = -osc.real / w
    return w, np.where(zeta < 1e-10, 0.0, zeta)      # round-off of an undamped model -> 0


def _mode_numbers(modes, n: int) -> tuple:
    if isinstance(modes, (int, np.integer)) and not isinstance(modes, bool):
        modes = (int(modes),)
    try:
        modes = tuple(modes)
    except TypeError:
        modes = None
    if not modes or any(isinstance(m, bool) or not isinstance(m, (int, np.integer)) or not 1 <= m <= n
                        for m in modes) or len(set(modes)) != len(modes):
        raise ParameterError(f"modes must be distinct mode numbers in 1..{n} (the design model's "
                             f"flexible modes), got {modes!r}")
    return tuple(int(m) for m in modes)


def design_shaper(design, kind: str = "zvd", modes=(1,), tolerance: float = 0.05) -> Shaper:
    """Shaper for the design model's modes: one per mode, convolved.

    Parameters
    ----------
    design : DesignModel
        Its modes at the design spin give the frequencies and damping ratios
        (:func:`design_modes`).
    kind : {"zv", "zvd", "ei"}
    modes : int or sequence of int
        Mode numbers to shape, 1 = the first bending mode (default: the first only).
    tolerance : float
        EI only: allowed residual [-].

    Returns
    -------
    Shaper

    Examples
    --------
    >>> from controllers import DesignModel
    >>> s = design_shaper(DesignModel.build(n_modes=2), "zvd")
    >>> round(s.duration, 3)        # one damped period of the 0.46 Hz first mode
    2.175
    """
    w, z = design_modes(design)
    shaper = None
    for m in _mode_numbers(modes, len(w)):
        s = make_shaper(kind, float(w[m - 1]), float(z[m - 1]), tolerance)
        shaper = s if shaper is None else shaper.convolve(s)
    return shaper


def as_shaper(design, shaping) -> Shaper:
    """``shaping`` itself if it is a :class:`Shaper`, else the shaper of that kind for the first mode.

    Parameters
    ----------
    design : DesignModel
        Its first mode (at the design spin) gives the shaper of a kind (:func:`design_shaper`).
    shaping : {"zv", "zvd", "ei"} or Shaper

    Returns
    -------
    Shaper
    """
    return shaping if isinstance(shaping, Shaper) else design_shaper(design, shaping)


def shaper_sensitivity(design, kinds=SHAPERS, errors=np.linspace(-0.3, 0.3, 61), mode: int = 1,
                       tolerance: float = 0.05) -> dict:
    """Residual vibration of each shaper against the error of a mode's frequency.

    The shapers are designed for mode ``mode`` of the design model; the mode's actual
    frequency is ``(1 + error) omega`` (same damping ratio). The residual of a linear mode
    is exactly the shaper's percentage residual vibration (:func:`residual_vibration`).

    Parameters
    ----------
    design : DesignModel
    kinds : sequence of {"zv", "zvd", "ei"}
    errors : array_like
        Relative frequency errors [-], each > -1 (default -30 % .. +30 %).
    mode : int
        Mode number (1 = first bending mode).
    tolerance : float
        EI's allowed residual [-].

    Returns
    -------
    dict
        ``"errors"``: the errors [-]; ``"frequency"``, ``"damping"``: the nominal mode
        [rad/s, -]; and one array of residuals [-] per kind.
    """
    err = np.asarray(errors, dtype=float).ravel()
    if err.size == 0 or not np.all(np.isfinite(err)) or np.any(err <= -1):
        raise ParameterError("errors must be finite relative frequency errors > -1 [-]")
    w, z = design_modes(design)
    (m,) = _mode_numbers(mode, len(w))
    out = {"errors": err, "frequency": float(w[m - 1]), "damping": float(z[m - 1])}
    for kind in kinds:
        s = make_shaper(kind, float(w[m - 1]), float(z[m - 1]), tolerance)
        out[kind] = s.residual(w[m - 1] * (1 + err), float(z[m - 1]))
    return out


# -- the reference filter ------------------------------------------------------------------------
def _reference_channels(reference):
    """Functions of time of the reference's channels, linear between samples.

    Before ``t = 0`` every channel keeps its first value; after the last sample the angle
    continues at the final rate and the other channels keep their last value (as
    :class:`Reference` itself does).
    """
    t = reference.t
    t_last = t[-1]

    def channel(values, ramp=None):
        def f(s):
            out = np.interp(s, t, values)
            if ramp is not None:
                out = out + ramp * np.maximum(s - t_last, 0.0)
            return out
        return f

    return (channel(reference.theta, reference.theta_dot[-1]), channel(reference.theta_dot),
            channel(reference.theta_ddot), channel(reference.torque))


def shape_reference(reference, shaper: Shaper):
    """Filter a hub reference through an input shaper (reference shaping for feedback control).

    Every channel (angle, rate, acceleration, feedforward torque) is convolved with the
    shaper, so the shaped reference is still a rigid-body trajectory with its own
    feedforward, reaching the same end state ``shaper.duration`` later; the table grows by
    that many samples. Linear interpolation between the samples gives the delayed copies.

    Parameters
    ----------
    reference : Reference
    shaper : Shaper

    Returns
    -------
    Reference
    """
    from .base import Reference
    if not isinstance(reference, Reference):
        raise ParameterError(f"reference must be a Reference, got {type(reference).__name__}")
    if not isinstance(shaper, Shaper):
        raise ParameterError(f"shaper must be a Shaper, got {type(shaper).__name__}")
    n = len(reference.theta) + int(math.ceil(shaper.duration / reference.dt - 1e-9))
    t = reference.dt * np.arange(n)
    th, thd, thdd, tau = (shaper.apply(f, t) for f in _reference_channels(reference))
    return Reference(reference.dt, th, thd, thdd, tau,
                     f"{reference.description}, shaped by {shaper.name} ({shaper.duration:.4g} s)")
