"""Converged natural frequencies: the assumed-mode model refined, with an error estimate.

The assumed-mode models are Rayleigh-Ritz discretisations: with ``n`` modes a frequency
approaches its limit from above as about ``C n^-p``. The clamped-free eigenfunctions do not
satisfy the tip-mass boundary condition, so the bending frequencies converge with ``p``
about 3 and the axial ones (sine basis) with ``p`` about 1. On the paper's beam (Table 1,
``m_t = 0.1 kg``) five modes put the third bending frequency 0.11 %, the fourth 0.34 % and
the fifth 0.84 % above the exact Euler-Bernoulli value; twenty put them within 0.011 %,
while the second axial frequency is still 0.07 % high.

:func:`converged_modes` therefore computes the frequencies with many assumed modes
(default :data:`~hubbeam_ctrl.plant.params.MAX_MODES`) and estimates the error of each from
the same frequency at three mode counts (``n/2``, ``3n/4``, ``n``): the order ``p`` from the
ratio of the two differences, then the remaining error ``(f_3n/4 - f_n) / ((4/3)^p - 1)``
(Richardson). Where the differences are not a clean geometric sequence (gyroscopic coupling
at spin, mode crossings) the estimate falls back to ``p = 1``, the slowest order seen.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.modal import _params_of, modal_analysis
from hubbeam_ctrl.plant.models import HubBeamModel
from hubbeam_ctrl.plant.params import MAX_MODES, Params

__all__ = ["CONVERGENCE_TARGET", "CLI_ASSUMED_MODES", "ConvergedModes", "converged_modes", "richardson_error"]

#: Relative accuracy a reported frequency should have [-] (0.05 %).
CONVERGENCE_TARGET = 5e-4

#: Assumed modes of ``hubbeam modes`` by default: on Table 1's beam 16 put the fifth bending
#: frequency 0.021 % above its limit (20: 0.011 %, 12: 0.046 %) for 0.7 s of CPU in all (20:
#: 1.05 s; the 5-mode model alone: 0.39 s).
CLI_ASSUMED_MODES = 16

#: Orders of convergence the estimate accepts (outside: the fallback ``p = 1``).
_P_RANGE = (0.5, 8.0)


@dataclass(frozen=True)
class ConvergedModes:
    """Natural frequencies of a refined assumed-mode model with their estimated errors.

    Attributes
    ----------
    model, hub : str
        Model name and hub condition (``free`` or ``prescribed``).
    spin : float
        [rad/s]
    assumed_modes : int
        Axial and transverse modes of the model the frequencies come from.
    bending_hz, axial_hz : ndarray
        The first requested frequencies of that model [Hz], ascending.
    bending_error, axial_error : ndarray
        Estimated relative error of each [-] (frequency minus its converged value, over the
        converged value; >= 0 for a Rayleigh-Ritz sequence); NaN where the coarser models
        lack the mode.
    unstable : bool
        As in :class:`~hubbeam_ctrl.plant.modal.ModalResult`.
    """

    model: str
    hub: str
    spin: float
    assumed_modes: int
    bending_hz: np.ndarray
    axial_hz: np.ndarray
    bending_error: np.ndarray
    axial_error: np.ndarray
    unstable: bool

    def converged(self, target: float = CONVERGENCE_TARGET) -> tuple:
        """Which frequencies are estimated within ``target`` of their limit.

        Parameters
        ----------
        target : float
            Relative accuracy [-] (default 0.05 %).

        Returns
        -------
        (ndarray of bool, ndarray of bool)
            Bending and axial.
        """
        return (np.abs(self.bending_error) <= target, np.abs(self.axial_error) <= target)


def richardson_error(f_coarse, f_mid, f_fine, n_coarse: int, n_mid: int, n_fine: int) -> np.ndarray:
    """Estimated relative error of ``f_fine`` from the same frequencies at three mode counts.

    With ``f_n = f + C n^-p``: ``p`` from ``(f_coarse - f_mid) / (f_mid - f_fine)``, then
    ``f_fine - f = (f_mid - f_fine) / ((n_fine / n_mid)^p - 1)``. When the two differences do
    not have one sign or ``p`` leaves 0.5..8, ``p = 1`` (conservative).

    Parameters
    ----------
    f_coarse, f_mid, f_fine : array_like
        The same frequencies [Hz] with ``n_coarse < n_mid < n_fine`` assumed modes.
    n_coarse, n_mid, n_fine : int
        The mode counts.

    Returns
    -------
    ndarray
        ``(f_fine - f_limit) / f_limit`` [-].

    Examples
    --------
    >>> f = lambda n: 10.0 + 2.0 * n ** -3.0
    >>> round(float(richardson_error([f(10)], [f(15)], [f(20)], 10, 15, 20)[0]) * 1e5, 6)   # 2/8000/10
    2.5
    """
    f1, f2, f3 = (np.asarray(f, dtype=float) for f in (f_coarse, f_mid, f_fine))
    if not 0 < n_coarse < n_mid < n_fine:
        raise ParameterError(f"mode counts must increase, got {n_coarse}, {n_mid}, {n_fine}")
    d1, d2 = f1 - f2, f2 - f3
    out = np.empty_like(f3)
    for i in range(f3.size):
        p = 1.0
        tiny = 1e-13 * abs(f3[i])
        if abs(d2[i]) <= tiny:
            out[i] = abs(d2[i]) / max(abs(f3[i]), 1e-300)
            continue
        if d1[i] * d2[i] > 0 and abs(d1[i]) > tiny:
            ratio = d1[i] / d2[i]
            lo, hi = _P_RANGE
            g = lambda q: (n_coarse ** -q - n_mid ** -q) / (n_mid ** -q - n_fine ** -q) - ratio  # noqa: E731
            if g(lo) * g(hi) < 0:          # g increases with q; bisection
                for _ in range(60):
                    mid = 0.5 * (lo + hi)
                    lo, hi = (mid, hi) if g(mid) < 0 else (lo, mid)
                p = 0.5 * (lo + hi)
        err = d2[i] / ((n_fine / n_mid) ** p - 1.0)
        out[i] = err / (f3[i] - err)
    return out


def _counts(assumed_modes: int) -> tuple:
    return (max(1, (assumed_modes + 1) // 2), max(2, (3 * assumed_modes + 3) // 4), assumed_modes)


def converged_modes(model="foam", spin: float = 0.0, hub: str = "prescribed", params: Params | None = None,
                    n_bending: int | None = None, n_axial: int | None = None,
                    assumed_modes: int = MAX_MODES) -> ConvergedModes:
    """The first natural frequencies from a model with ``assumed_modes`` modes, with their errors.

    Parameters
    ----------
    model : str
        ``tlam``, ``foam``, ``cfoam`` or ``sfoam``.
    spin : float
        Spin rate [rad/s] (see :func:`~hubbeam_ctrl.plant.modal.modal_analysis`).
    hub : {"prescribed", "free"}
    params : Params, optional
        Physical parameters (default Table 1); their mode counts are the default numbers of
        frequencies reported.
    n_bending, n_axial : int, optional
        How many bending and axial frequencies to report, 1..``assumed_modes``.
    assumed_modes : int
        Axial and transverse modes of the model, 4..MAX_MODES (default 20). The error
        estimate also builds the models with about half and three quarters as many.

    Returns
    -------
    ConvergedModes

    Examples
    --------
    >>> r = converged_modes("foam", params=Params(), n_axial=1)
    >>> round(float(r.bending_hz[2]), 3), bool(r.converged()[0].all())   # exact: 7.5032 Hz
    (7.503, True)
    """
    if isinstance(model, HubBeamModel):
        raise ParameterError("model must be a model name (the frequencies need models with other mode counts)")
    base = _params_of(model, params)
    if isinstance(assumed_modes, bool) or not isinstance(assumed_modes, (int, np.integer)) \
            or not 4 <= assumed_modes <= MAX_MODES:
        raise ParameterError(f"assumed_modes must be an integer in 4..{MAX_MODES}, got {assumed_modes!r}")
    assumed_modes = int(assumed_modes)
    wanted = {}
    for name, value, default in (("n_bending", n_bending, base.n_transverse), ("n_axial", n_axial, base.n_axial)):
        value = default if value is None else value
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 1 <= value <= assumed_modes:
            raise ParameterError(f"{name} must be an integer in 1..assumed_modes ({assumed_modes}), got {value!r}")
        wanted[name] = int(value)
    runs = [modal_analysis(model, spin, hub, base.replace(n_axial=n, n_transverse=n))
            for n in _counts(assumed_modes)]
    fine = runs[-1]

    def family(attr, k):
        f3 = getattr(fine, attr)[:k]
        err = np.full(f3.shape, np.nan)
        m = min(len(getattr(r, attr)) for r in runs)
        m = min(m, len(f3))
        if m:
            err[:m] = richardson_error(*(getattr(r, attr)[:m] for r in runs), *_counts(assumed_modes))
        return f3, err

    bending, bending_err = family("bending_hz", wanted["n_bending"])
    axial, axial_err = family("axial_hz", wanted["n_axial"])
    return ConvergedModes(model=fine.model, hub=hub, spin=fine.spin, assumed_modes=assumed_modes,
                          bending_hz=bending, axial_hz=axial, bending_error=bending_err,
                          axial_error=axial_err, unstable=fine.unstable)
