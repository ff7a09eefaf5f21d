"""Modal analysis: frequencies at a spin rate, Campbell sweeps, TLAM critical speed.

Frequencies are those of the linearisation about steady rotation
(:mod:`hubbeam_ctrl.plant.linearization`): the undamped natural frequencies of the oscillatory
eigenvalues of the first-order system, split into bending (transverse) and axial modes
by where the eigenvector's kinetic energy lies. With the hub prescribed (Table 2's
convention, a clamped root turning at the given rate) and no tip mass, FOAM's bending
frequencies are those of ``(M2, K2 - spin^2 M2 + spin^2 D)`` up to the tiny gyroscopic
coupling to the axial modes.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.progress import progress_bar
from hubbeam_ctrl.core.stored import stored_array
from hubbeam_ctrl.core.validation import check_array
from hubbeam_ctrl.plant.linearization import first_order_matrices, second_order_linearization
from hubbeam_ctrl.plant.models import HubBeamModel, resolve_model
from hubbeam_ctrl.plant.params import MAX_MODES, Params, check_spin

__all__ = ["ModalResult", "modal_analysis", "natural_frequencies", "campbell",
           "critical_speed", "critical_speed_map", "converged_bending_hz"]

#: Eigenvalues with |lambda| below this [rad/s] count as rigid-body (zero) modes.
RIGID_TOL = 1e-6


@dataclass(frozen=True)
class ModalResult:
    """Frequencies of a model linearised about steady spin.

    Attributes
    ----------
    model, hub : str
    spin : float
        [rad/s]
    bending_hz, axial_hz : ndarray
        Undamped natural frequencies [Hz], ascending.
    damping_ratios : ndarray
        Damping ratios of the bending modes [-] (0 without modal damping).
    unstable : bool
        True when an eigenvalue has a positive real part (e.g. TLAM above its critical speed).
    n_rigid : int
        Number of zero eigenvalues (2 for a free hub: the rigid rotation).
    """

    model: str
    hub: str
    spin: float
    bending_hz: np.ndarray
    axial_hz: np.ndarray
    damping_ratios: np.ndarray
    unstable: bool
    n_rigid: int


def modal_analysis(model="foam", spin: float = 0.0, hub: str = "prescribed",
                   params: Params | None = None) -> ModalResult:
    """Natural frequencies of a model about steady rotation.

    Parameters
    ----------
    model : str or HubBeamModel
    spin : float
        Spin rate [rad/s], ``|spin| <= params.max_spin``.
    hub : {"prescribed", "free"}
        ``prescribed``: clamped root turning at ``spin`` (Table 2); ``free``: the hub is
        free to turn (its inertia takes part; one rigid mode at zero).
    params : Params, optional

    Returns
    -------
    ModalResult
        Bending and axial frequencies [Hz], the bending modes' damping ratios, stability.

    Examples
    --------
    >>> from hubbeam_ctrl import Params, modal_analysis
    >>> r = modal_analysis("foam", spin=1.0, params=Params(m_t=0.0))
    >>> [round(float(f), 3) for f in r.bending_hz[:2]]
    [0.471, 2.929]
    """
    spin = check_spin("spin", spin, _params_of(model, params))   # before the model is built
    m = resolve_model(model, params)
    lin = second_order_linearization(m, spin, hub)
    A, _, _ = first_order_matrices(lin)
    lam, vec = np.linalg.eig(A)
    n = lin.M.shape[0]
    rigid = np.abs(lam) < RIGID_TOL * max(1.0, np.abs(lam).max() * 1e-6)
    # rounding puts real parts of order eps * max|lambda| on every eigenvalue: not instability
    unstable = bool(np.any(lam.real > 1e-9 * np.maximum(1.0, np.abs(lam)) + 1e-11 * np.abs(lam).max()))
    names = lin.coordinate_names
    is_axial_coord = np.array([c.startswith("q1_") for c in names])
    bending, axial, zetas = [], [], []
    for k in np.nonzero(~rigid & (lam.imag >= 0))[0]:
        x = vec[n:, k] if abs(lam[k]) > 0 else vec[:n, k]
        energy = np.real(np.conj(x) * (lin.M @ x))
        share_axial = energy[is_axial_coord].sum() / max(energy.sum(), 1e-300)
        wn = abs(lam[k])
        if abs(lam[k].imag) < 1e-12 * max(wn, 1.0):   # real eigenvalue (overdamped/unstable)
            continue
        if share_axial > 0.5:
            axial.append(wn / (2 * np.pi))
        else:
            bending.append(wn / (2 * np.pi))
            zetas.append(-lam[k].real / wn)
    order = np.argsort(bending)
    return ModalResult(model=m.name, hub=hub, spin=float(spin),
                       bending_hz=np.array(bending)[order], axial_hz=np.sort(axial),
                       damping_ratios=np.array(zetas)[order], unstable=unstable,
                       n_rigid=int(rigid.sum()))


def _params_of(model, params) -> Params:
    """The parameters a model will be built with (without building it)."""
    if isinstance(model, HubBeamModel):
        return model.params
    if params is not None and not isinstance(params, Params):
        raise ParameterError(f"params must be a Params, got {type(params).__name__}")
    return params if params is not None else Params()


def natural_frequencies(model="foam", spin: float = 0.0, hub: str = "prescribed",
                        params: Params | None = None) -> np.ndarray:
    """Bending natural frequencies [Hz] at ``spin`` [rad/s] (see :func:`modal_analysis`).

    Parameters
    ----------
    model : str
        ``tlam``, ``foam``, ``cfoam`` or ``sfoam``.
    spin : float
        Spin rate [rad/s].
    hub : {"prescribed", "free"}
        Hub held at the spin rate, or free (its inertia takes part).
    params : Params, optional
        Default: Table 1.
    """
    return modal_analysis(model, spin, hub, params).bending_hz


def campbell(model="foam", spins=np.linspace(0, 5, 26), hub: str = "prescribed",
             params: Params | None = None, progress: bool = False) -> np.ndarray:
    """Campbell diagram: bending frequencies over spin rates.

    Parameters
    ----------
    model : str or HubBeamModel
    spins : array_like
        Spin rates [rad/s].
    hub : {"prescribed", "free"}
    params : Params, optional
    progress : bool
        Show a progress bar on stderr (only when stderr is a terminal).

    Returns
    -------
    ndarray (len(spins), n2)
        Frequencies [Hz]; NaN where a mode has lost its stiffness (unstable).
    """
    spins = check_array("spins", spins, "rad/s")
    m = resolve_model(model, params)
    out = np.full((len(spins), m.n_transverse), np.nan)
    with progress_bar(len(spins), f"campbell {m.name}", enabled=progress) as bar:
        for i, s in enumerate(spins):
            f = modal_analysis(m, s, hub).bending_hz
            out[i, m.n_transverse - len(f):] = f if len(f) else []
            bar.update(1)
    return out


def critical_speed(model="tlam", params: Params | None = None,
                   max_spin: float = 1000.0) -> float | None:
    """Spin rate at which the bending stiffness ``K_q2q2(spin)`` loses positive definiteness.

    In TLAM, FOAM and SFOAM the bending stiffness at steady spin is
    ``K(spin) = K(0) + spin^2 (K(1) - K(0))`` exactly (checked here), so the critical speed
    is ``1/sqrt(mu_max)`` with ``mu_max`` the largest eigenvalue of ``K(0)^-1 (K(0) - K(1))``.

    Parameters
    ----------
    model : {"tlam", "foam", "sfoam"} or HubBeamModel
    params : Params, optional
    max_spin : float
        Speeds above this [rad/s] are reported as ``None``.

    Returns
    -------
    float or None
        Critical speed [rad/s]; ``None`` if the model keeps its stiffness up to ``max_spin``.
    """
    m = resolve_model(model, params)
    if m.name == "cfoam":
        raise ParameterError("model must be tlam, foam or sfoam for critical-speed (CFOAM's "
                             "stiffness is not quadratic in the spin)")
    def k22(spin):
        lin = second_order_linearization(m, spin, "prescribed")
        idx = np.array([c.startswith("q2_") for c in lin.coordinate_names])
        return lin.K[np.ix_(idx, idx)]

    K0, K1, K2 = k22(0.0), k22(1.0), k22(2.0)
    if not np.allclose(K2, K0 + 4 * (K1 - K0), rtol=1e-9, atol=1e-9 * np.abs(K0).max()):
        raise ParameterError(f"{m.name}: bending stiffness is not quadratic in the spin")
    mu = np.linalg.eigvals(np.linalg.solve(K0, K0 - K1)).real.max()
    if mu <= 0 or 1 / np.sqrt(mu) > max_spin:
        return None
    return float(1 / np.sqrt(mu))


def critical_speed_map(tip_masses, tip_positions, model="tlam", params: Params | None = None,
                       progress: bool = False) -> np.ndarray:
    """TLAM critical speed as a function of tip mass and its position (the paper's Fig. 9).

    Parameters
    ----------
    tip_masses : array_like
        Tip masses [kg].
    tip_positions : array_like
        Tip-mass positions along the beam [m], in [0, L].
    model : str
    params : Params, optional
        Base parameters (``m_t`` and ``l`` are replaced).
    progress : bool
        Show a progress bar on stderr (only when stderr is a terminal).

    Returns
    -------
    ndarray (len(tip_masses), len(tip_positions))
        Critical speeds [rad/s] (NaN where there is none).
    """
    base = params if params is not None else Params()
    masses = np.atleast_1d(tip_masses)
    positions = np.atleast_1d(tip_positions)
    out = np.full((len(masses), len(positions)), np.nan)
    with progress_bar(out.size, "critical speed map", enabled=progress) as bar:
        for i, mt in enumerate(masses):
            for j, pos in enumerate(positions):
                w = critical_speed(model, base.replace(m_t=float(mt), l=float(pos)))
                out[i, j] = np.nan if w is None else w
                bar.update(1)
    return out


@lru_cache(maxsize=32)
def _converged_bending_hz(params: Params, spin: float) -> np.ndarray:
    p = params.replace(n_transverse=MAX_MODES, n_axial=1)
    # kept in the build cache: the 20-mode linearisation took 0.2 s of every comparison's start
    return stored_array(("converged_bending_hz", p, spin), lambda: modal_analysis("sfoam", spin, "free", p).bending_hz)


def converged_bending_hz(params: Params, spin: float = 0.0) -> np.ndarray:
    """Bending frequencies of the free-hub beam with the most modes the basis allows [Hz].

    SFOAM with :data:`~hubbeam_ctrl.plant.params.MAX_MODES` transverse modes, linearised
    about ``spin`` (at the slew's design point, spin 0, SFOAM's bending frequencies equal
    FOAM's and CFOAM's). Used to count the modes below a sampling frequency; cached.

    Parameters
    ----------
    params : Params
        Physical parameters (the mode counts are ignored).
    spin : float
        Spin rate [rad/s].

    Returns
    -------
    ndarray (MAX_MODES,)
        Ascending, read-only.

    Examples
    --------
    >>> f = converged_bending_hz(Params())
    >>> int((f < 100.0).sum())      # the paper's beam: nine modes below 100 Hz
    9
    """
    if not isinstance(params, Params):
        raise ParameterError(f"params must be a Params, got {type(params).__name__}")
    if not np.isfinite(spin):
        raise ParameterError(f"spin must be finite [rad/s], got {spin}")
    return _converged_bending_hz(params, float(spin))
