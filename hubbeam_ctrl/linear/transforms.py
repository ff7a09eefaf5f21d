"""New models from a :class:`~hubbeam_ctrl.linear.statespace.LinearModel`: sampled
(:func:`discretize`) and reduced (:func:`reduce`, modal or balanced truncation).
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.validation import check_in_range, check_integer
from hubbeam_ctrl.linear.poles import continuous_poles, split_rigid
from hubbeam_ctrl.linear.statespace import DT_RANGE, LinearModel, named_ss
from hubbeam_ctrl.plant.linearization import velocity_name

__all__ = ["discretize", "reduce"]


def discretize(lm: LinearModel, dt: float, method: str = "zoh") -> LinearModel:
    """Sample a continuous model (zero-order hold by default).

    Parameters
    ----------
    lm : LinearModel
        Continuous-time model.
    dt : float
        Sample time [s], in [1e-6, 10]; refused when a growing mode overflows the sampled
        matrices.
    method : {"zoh", "foh", "impulse", "tustin", "bilinear", "euler", "backward_diff"}
        Passed to :meth:`control.StateSpace.sample` (default zero-order hold).

    Returns
    -------
    LinearModel
        Same state, input and output names; ``sys.dt == dt``; name ``<name>_d``.
    """
    if not isinstance(lm, LinearModel):
        raise ParameterError(f"model must be a LinearModel, got {type(lm).__name__}")
    dt = check_in_range("dt", dt, "s", DT_RANGE[0], DT_RANGE[1])
    if lm.is_discrete:
        raise ParameterError(f"model must be continuous-time to discretize, it has dt = {lm.dt}")
    methods = ("zoh", "foh", "impulse", "tustin", "bilinear", "euler", "backward_diff")
    if method not in methods:
        raise ParameterError(f"method must be one of {', '.join(methods)}, got {method!r}")
    with np.errstate(all="ignore"), warnings.catch_warnings():   # overflow is checked below
        warnings.simplefilter("ignore", RuntimeWarning)
        sysd = lm.sys.sample(dt, method=method, name=f"{lm.name}_d", copy_names=True)
    if not all(np.all(np.isfinite(np.asarray(M))) for M in (sysd.A, sysd.B, sysd.C, sysd.D)):
        growth = float(np.max(continuous_poles(lm).real))
        raise ParameterError(f"dt = {dt:g} s is too long for this model: its fastest-growing mode "
                             f"(real part {growth:.4g} 1/s) overflows the sampled matrices")
    sysd = named_ss(sysd.A, sysd.B, sysd.C, sysd.D, dt, lm.state_names, lm.output_names, sysd.name)
    return dataclasses.replace(lm, sys=sysd)


# -- reduction ------------------------------------------------------------------
def _modal_basis(A: np.ndarray):
    """Real modal coordinates of a free-hub model.

    Returns ``P`` (columns: rigid angle, rigid rate, then per mode ``eta``, ``eta_dot``) and
    the s-plane eigenvalue pairs of the modes, sorted by undamped natural frequency.
    ``x = P xi`` with ``xi = [rigid, rigid_dot, eta_1, eta_dot_1, ...]``.
    """
    n2 = A.shape[0]
    n = n2 // 2
    # rigid rotation: A r1 = 0 (r1 = unit hub angle), A r2 = r1 (Jordan chain)
    r1 = np.zeros(n2)
    r1[0] = 1.0
    scale = max(np.abs(A).max(), 1.0)
    if np.abs(A @ r1).max() > 1e-10 * scale:
        raise ParameterError("model: the hub angle is not a rigid-body coordinate (hub not free)")
    r2 = np.linalg.lstsq(A, r1, rcond=None)[0]
    r2 -= r2[0] * r1
    if np.abs(A @ r2 - r1).max() > 1e-8:
        raise ParameterError("model: no rigid-body double integrator found (hub not free)")
    lam, V = np.linalg.eig(A)
    rigid, rest = split_rigid(lam, 2)
    lam, V = lam[rest], V[:, rest]
    # pair the eigenvalues: conjugate pairs, and real ones (lost stiffness) by shape
    used = np.zeros(len(lam), bool)
    pairs = []
    disp = V[:n]
    for i in np.argsort(np.abs(lam), kind="stable"):
        if used[i]:
            continue
        used[i] = True
        cand = np.nonzero(~used)[0]
        if abs(lam[i].imag) > 1e-9 * abs(lam[i]):
            j = cand[np.argmin(np.abs(lam[cand] - np.conj(lam[i])))]
        else:
            cand = cand[np.abs(lam[cand].imag) <= 1e-9 * np.abs(lam[cand])]
            if not len(cand):
                raise ParameterError("model: an unpaired real pole prevents modal reduction")
            a = disp[:, i] / np.linalg.norm(disp[:, i])
            cos = [abs(np.vdot(a, disp[:, c])) / np.linalg.norm(disp[:, c]) for c in cand]
            j = cand[int(np.argmax(cos))]
        used[j] = True
        if lam[i].imag < 0:
            i, j = j, i
        pairs.append((i, j))
    cols, mode_lams = [r1, r2], []
    for i, j in pairs:
        la, lb = lam[i], lam[j]
        va, vb = V[:, i].copy(), V[:, j].copy()
        # normalise: displacement part's largest elastic component = 1 (eta in metres)
        k = 1 + np.argmax(np.abs(va[1:n]))
        va /= va[k]
        vb /= vb[k]
        Pk = np.column_stack([va, vb]) @ np.linalg.inv(np.array([[1, 1], [la, lb]]))
        cols += [Pk[:, 0].real, Pk[:, 1].real]
        mode_lams.append((la, lb))
    return np.column_stack(cols), mode_lams


def reduce(lm: LinearModel, n_modes: int, method: str = "modal") -> LinearModel:
    """Reduced-order model keeping the rigid rotation and ``n_modes`` flexible modes.

    Parameters
    ----------
    lm : LinearModel
        Continuous-time, free-hub model (from :func:`linearize`).
    n_modes : int
        Flexible modes to keep, 1..(number of modes of ``lm``).
    method : {"modal", "balanced"}
        ``modal``: modal truncation keeping the ``n_modes`` lowest-frequency modes of the
        coupled system exactly (their poles and residues are those of ``lm``). States
        ``[rigid, mode_1..mode_k, rigid_dot, mode_dot_1..mode_dot_k]``: ``rigid`` [rad] is
        the rigid-body hub angle, ``mode_i`` [m] the amplitude of mode i with its
        displacement shape scaled so that its largest elastic coordinate (q1 or q2) is 1;
        each mode obeys ``mode_i'' + 2 zeta_i w_i mode_i' + w_i^2 mode_i = b_i tau``.
        ``balanced``: the rigid block is kept exactly and the flexible part is reduced
        by balanced truncation to ``2 n_modes`` states (``control.balred`` when slycot is
        installed, else a square-root algorithm on SciPy). States ``rigid``,
        ``rigid_dot``, ``xb_1..``. Needs ``damping_ratio > 0`` (undamped modes have no
        finite Gramians).

    Returns
    -------
    LinearModel
        ``reduction`` is ``"modal:K"`` or ``"balanced:K"``.
    """
    if not isinstance(lm, LinearModel):
        raise ParameterError(f"model must be a LinearModel, got {type(lm).__name__}")
    if lm.is_discrete:
        raise ParameterError("model must be continuous-time to reduce (reduce, then discretize)")
    if lm.reduction != "none":
        raise ParameterError(f"model is already reduced ({lm.reduction}); reduce the full model")
    if method not in ("modal", "balanced"):
        raise ParameterError(f"method must be 'modal' or 'balanced', got {method!r}")
    A, B, C, D = lm.A, lm.B, lm.C, lm.D
    n_flex = A.shape[0] // 2 - 1
    n_modes = check_integer("n_modes", n_modes, 1, n_flex)
    P, mode_lams = _modal_basis(A)
    T = np.linalg.inv(P)
    Bm, Cm = T @ B, C @ P
    if method == "modal":
        k = n_modes
        Ar = np.zeros((2 * k + 2, 2 * k + 2))
        # reorder xi = [rigid, rigid_dot, eta_1, eta_dot_1, ...] to positions then rates
        pos = [0] + [2 + 2 * i for i in range(k)]
        vel = [1] + [3 + 2 * i for i in range(k)]
        idx = pos + vel
        m = k + 1
        Ar[0, m] = 1.0
        for i, (la, lb) in enumerate(mode_lams[:k], start=1):
            Ar[i, m + i] = 1.0
            Ar[m + i, i] = -(la * lb).real
            Ar[m + i, m + i] = (la + lb).real
        Br, Cr = Bm[idx], Cm[:, idx]
        states = ["rigid"] + [f"mode_{i}" for i in range(1, k + 1)]
        states = states + [velocity_name(s) for s in states]
    else:
        zeta = lm.params.damping_ratio
        if zeta <= 0:
            raise ParameterError("damping_ratio must be > 0 for balanced reduction (undamped "
                                 "modes have no finite Gramians), got 0")
        Af = T[2:] @ A @ P[:, 2:]
        if np.linalg.eigvals(Af).real.max() >= 0:
            raise ParameterError("model: balanced reduction needs stable flexible modes "
                                 "(this one has lost its stiffness)")
        Ab, Bb, Cb = _balanced_truncation(Af, Bm[2:], Cm[:, 2:], 2 * n_modes)
        r = Ab.shape[0]
        Ar = np.zeros((r + 2, r + 2))
        Ar[0, 1] = 1.0
        Ar[2:, 2:] = Ab
        Br = np.vstack([Bm[:2], Bb])
        Cr = np.hstack([Cm[:, :2], Cb])
        states = ["rigid", "rigid_dot"] + [f"xb_{i}" for i in range(1, r + 1)]
    sysr = named_ss(Ar, Br, Cr, D, 0, states, lm.output_names,
                    f"{lm.name}_{method}{n_modes}")
    return dataclasses.replace(lm, sys=sysr, reduction=f"{method}:{n_modes}")


def _balanced_truncation(A, B, C, order):
    """Balanced truncation of a stable system to ``order`` states."""
    import control
    try:
        red = control.balred(control.ss(A, B, C, np.zeros((C.shape[0], B.shape[1]))), order)
        return np.asarray(red.A), np.asarray(red.B), np.asarray(red.C)
    except (ImportError, control.exception.ControlSlycot):
        pass
    import scipy.linalg as sla
    Wc = sla.solve_continuous_lyapunov(A, -B @ B.T)
    Wo = sla.solve_continuous_lyapunov(A.T, -C.T @ C)
    Lc = _psd_factor(Wc)
    Lo = _psd_factor(Wo)
    U, s, Vt = np.linalg.svd(Lo.T @ Lc)
    S = np.diag(s[:order] ** -0.5)
    Tl = S @ U[:, :order].T @ Lo.T          # reduced = Tl x
    Tr = Lc @ Vt[:order].T @ S              # x ~ Tr reduced
    return Tl @ A @ Tr, Tl @ B, C @ Tr


def _psd_factor(W):
    """``L`` with ``W = L L'`` for a symmetric positive semidefinite ``W``."""
    w, V = np.linalg.eigh(0.5 * (W + W.T))
    return V * np.sqrt(np.clip(w, 0, None))
