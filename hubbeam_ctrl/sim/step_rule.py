"""The accuracy of the generalized-alpha scheme, and the substep rule built on it.

The coefficients of the scheme (:func:`generalized_alpha_coefficients`), its relative period
error on an undamped mode (:func:`period_error`), the largest step for a mode
(:func:`max_step_for_frequency`) and the number of steps per sample that keeps every mode of
a plant within a tolerance (:func:`substep_rule`, :class:`SubstepRule`). The integrator itself
is :class:`~hubbeam_ctrl.sim.stepper.PlantStepper` (:mod:`hubbeam_ctrl.sim.stepper`), which
re-exports these names.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.validation import check_positive as _check_positive
from hubbeam_ctrl.plant.params import MAX_MODES

__all__ = ["generalized_alpha_coefficients", "period_error", "max_step_for_frequency", "SubstepRule",
           "substep_rule", "MAX_SUBSTEPS", "SUBSTEP_BUDGET", "substep_cap"]

#: Largest number of integration steps per sample that :func:`substep_rule` accepts (the step runs them in a
#: compiled loop, ``mapaccum``: the count costs run time, which the comparison's budget checks, not code).
MAX_SUBSTEPS = 1000
#: The steps per sample a plant of ``plant.params.MAX_MODES`` (20) modes may take (:func:`substep_cap`), and the
#: default evaluation plant and design keep within 90 % of (adding or dropping modes,
#: :func:`~hubbeam_ctrl.sim.evaluation.default_plant_modes`).
SUBSTEP_BUDGET = 200


def substep_cap(n_modes: int) -> int:
    """The most integration steps per sample a plant of ``n_modes`` bending modes may take: the work of
    the largest plant (``plant.params.MAX_MODES`` modes at :data:`SUBSTEP_BUDGET` steps), at most
    :data:`MAX_SUBSTEPS`.

    Found on a random slow boom (3.8 m at 5 Hz, modes 10 and 62 Hz): its 2-mode plant, the fewest the
    default rules allow, needed 226 steps a sample and every run was refused while every plant's cap
    was 200; a 20-mode plant keeps 200.

    Parameters
    ----------
    n_modes : int
        The plant's bending modes, >= 1.

    Returns
    -------
    int

    Examples
    --------
    >>> substep_cap(20), substep_cap(10), substep_cap(2)
    (200, 400, 1000)
    """
    return int(min(MAX_SUBSTEPS, max(SUBSTEP_BUDGET, SUBSTEP_BUDGET * MAX_MODES // max(int(n_modes), 1))))


def generalized_alpha_coefficients(rho_inf: float) -> tuple:
    """Chung-Hulbert parameters ``(alpha_m, alpha_f, gamma, beta)`` for ``rho_inf`` in [0, 1].

    Parameters
    ----------
    rho_inf : float
        Spectral radius of the amplification matrix at infinite frequency [-]; 1 keeps
        every mode undamped (trapezoidal rule), smaller values damp the high frequencies.

    Returns
    -------
    tuple of float
    """
    am = (2 * rho_inf - 1) / (rho_inf + 1)
    af = rho_inf / (rho_inf + 1)
    gamma = 0.5 + af - am
    beta = 0.25 * (gamma + 0.5) ** 2
    return am, af, gamma, beta


def _amplification_matrix(omega_h: float, rho_inf: float) -> np.ndarray:
    """One step of the method on ``a + w^2 q = 0`` (step 1, ``w = omega_h``), state ``[q, v, a, p]``."""
    am, af, gamma, beta = generalized_alpha_coefficients(rho_inf)
    w2 = omega_h * omega_h
    c1 = (1 - af) / (1 - am)
    G = np.empty((4, 4))
    for j, (q0, v0, a0, p0) in enumerate(np.eye(4)):
        c0 = (af * a0 - am * p0) / (1 - am)
        q_pred = q0 + v0 + (0.5 - beta) * p0 + beta * c0
        a1 = -w2 * q_pred / (1 + w2 * beta * c1)
        p1 = c1 * a1 + c0
        G[:, j] = [q_pred + beta * c1 * a1, v0 + (1 - gamma) * p0 + gamma * p1, a1, p1]
    return G


def period_error(omega_h: float, rho_inf: float = 0.9) -> float:
    """Relative frequency error of the generalized-alpha method on an undamped oscillator.

    Measured from the method's amplification matrix on ``a + w^2 q = 0`` with step ``h``:
    its principal eigenvalue pair ``|lambda| exp(+-i w_num h)`` gives the frequency the
    integrator reproduces, ``w_num``.

    Parameters
    ----------
    omega_h : float
        Frequency times step, ``w h`` [rad], > 0.
    rho_inf : float
        Spectral radius at infinity [-], 0..1.

    Returns
    -------
    float
        ``w_num / w - 1`` [-] (negative: the simulated oscillation is too slow).

    Examples
    --------
    >>> round(period_error(0.2, 1.0), 5)      # trapezoidal rule: about -(w h)^2 / 12
    -0.00331
    """
    lam = np.linalg.eigvals(_amplification_matrix(float(omega_h), float(rho_inf)))
    principal = lam[np.argmax(np.abs(lam.imag))]
    return float(abs(np.angle(principal)) / omega_h - 1.0)


@lru_cache(maxsize=32)
def _largest_omega_h(tolerance: float, rho_inf: float) -> float:
    """Largest ``w h`` whose :func:`period_error` stays within ``tolerance`` (bisection)."""
    lo, hi = 1e-4, 2.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if abs(period_error(mid, rho_inf)) <= tolerance else (lo, mid)
    return lo


def max_step_for_frequency(frequency_hz: float, tolerance: float = 0.005, rho_inf: float = 0.9) -> float:
    """Largest step [s] that integrates an oscillation of ``frequency_hz`` within ``tolerance``.

    Parameters
    ----------
    frequency_hz : float
        Natural frequency [Hz], > 0.
    tolerance : float
        Largest accepted relative frequency error [-], in (0, 0.1].
    rho_inf : float
        Spectral radius at infinity of the method [-].

    Returns
    -------
    float
        Step [s].

    Examples
    --------
    >>> round(1e3 * max_step_for_frequency(100.0), 4)    # 0.5 % at 100 Hz
    0.3892
    """
    _check_positive("frequency_hz", frequency_hz, "Hz")
    if not (isinstance(tolerance, (int, float)) and 0 < tolerance <= 0.1):
        raise ParameterError(f"frequency_tolerance must be in (0, 0.1] [-], got {tolerance!r}")
    return _largest_omega_h(float(tolerance), float(rho_inf)) / (2 * np.pi * frequency_hz)


@dataclass(frozen=True)
class SubstepRule:
    """The integration step of the closed loop and why (see :func:`substep_rule`).

    Attributes
    ----------
    substeps : int
        Integration steps per sample.
    step_s : float
        Integration step ``dt / substeps`` [s].
    mode : int
        The bending mode that sets the step (the highest, 1-based).
    frequency_hz : float
        Its frequency from modal analysis [Hz].
    frequency_error : float
        The method's relative frequency error at that mode and step [-].
    tolerance : float
        The accepted relative frequency error [-].
    """

    substeps: int
    step_s: float
    mode: int
    frequency_hz: float
    frequency_error: float
    tolerance: float

    @property
    def reason(self) -> str:
        """One sentence for reports and result settings."""
        return (f"{self.substeps} steps of {1e3 * self.step_s:.4g} ms per sample: the highest bending "
                f"mode ({self.mode}, {self.frequency_hz:.4g} Hz by modal analysis) is integrated with a "
                f"frequency error of {100 * self.frequency_error:+.3f} % (limit "
                f"{100 * self.tolerance:g} %); lower modes are more accurate, axial modes are "
                "followed quasi-statically")

    def to_dict(self) -> dict:
        """Plain-data summary (JSON-ready)."""
        return {"substeps": self.substeps, "step_s": self.step_s, "step_mode": self.mode,
                "step_mode_hz": self.frequency_hz, "step_mode_frequency_error": self.frequency_error,
                "frequency_tolerance": self.tolerance, "step_reason": self.reason}


def substep_rule(frequencies_hz, dt: float, *, tolerance: float = 0.005, rho_inf: float = 0.9,
                 max_substeps: int | None = None) -> SubstepRule:
    """Integration steps per sample that keep every bending frequency within ``tolerance``.

    The generalized-alpha method's frequency error grows with ``w h`` (about
    ``-0.084 (w h)^2`` at ``rho_inf = 0.9``, :func:`period_error`), so the highest mode sets
    the step: ``substeps = ceil(dt / h_max)`` with ``h_max`` from :func:`max_step_for_frequency`.

    Parameters
    ----------
    frequencies_hz : array_like
        Bending frequencies of the plant [Hz] (e.g. ``modal_analysis(...).bending_hz``).
    dt : float
        Sample period [s], > 0.
    tolerance : float
        Largest accepted relative frequency error [-] (default 0.5 %).
    rho_inf : float
        Spectral radius at infinity of the method [-].
    max_substeps : int, optional
        Largest accepted count (default :func:`substep_cap` of the plant's modes: 200 for 20 modes,
        1000 for 2).

    Returns
    -------
    SubstepRule

    Raises
    ------
    ParameterError
        If the highest mode needs more than ``max_substeps`` steps per sample; the message
        names the mode, its frequency and the options.

    Examples
    --------
    >>> substep_rule([0.46, 2.66, 113.9], 0.01).substeps
    30
    """
    f = np.asarray(frequencies_hz, dtype=float).ravel()
    if not f.size or not np.all(np.isfinite(f)) or np.any(f <= 0):
        raise ParameterError("frequencies_hz must hold at least one finite frequency > 0 [Hz]")
    _check_positive("dt", dt, "s")
    k = int(np.argmax(f))
    max_substeps = substep_cap(f.size) if max_substeps is None else max_substeps
    h_max = max_step_for_frequency(f[k], tolerance, rho_inf)
    n = max(1, int(np.ceil(dt / h_max * (1 - 1e-12))))
    if n > max_substeps:
        raise ParameterError(
            f"plant bending mode {k + 1} at {f[k]:.4g} Hz needs {n} integration steps per "
            f"{1e3 * dt:g} ms sample to stay within {100 * tolerance:g} % of its frequency "
            f"(at most {max_substeps}); use fewer plant modes (plant_modes / --plant-modes) "
            f"or a smaller sample time (dt / --dt)")
    h = dt / n
    return SubstepRule(n, h, k + 1, float(f[k]), period_error(2 * np.pi * f[k] * h, rho_inf),
                       float(tolerance))
