"""Assumed-mode basis: shape functions and their modal integrals.

Shape functions (``x`` measured from the beam root, 0 <= x <= L):

* axial, fixed-free rod: ``f1_i(x) = sin((2i-1) pi x / (2L))``; normalised so that
  ``int_0^L f1_i^2 dx = L/2`` (the natural amplitude: ``f1_i(L) = +-1``);
* transverse, clamped-free Euler-Bernoulli eigenfunctions
  ``f2_i(x) = cosh(b x) - cos(b x) - s_i (sinh(b x) - sin(b x))`` with
  ``1 + cos(b L) cosh(b L) = 0``; normalised so that ``int_0^L f2_i^2 dx = L``, which
  gives ``|f2_i(L)| = 2``. The hyperbolic part is evaluated as
  ``((1-s) e^{bx} + (1+s) e^{-bx}) / 2`` with ``1-s`` formed without cancellation, so the
  functions stay accurate to machine precision up to 20 modes.

The modal coordinates ``q1`` and ``q2`` therefore have units of metres.

All inertia integrals are taken over a *mass measure*: the beam's ``rho A dx`` plus,
optionally, a point mass. :class:`MassMoments` holds them; the beam's and the tip mass's
moments add, so every model includes the tip mass through the same kinematics.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from hubbeam_ctrl.plant.params import Params

__all__ = [
    "clamped_free_roots",
    "axial_shapes",
    "transverse_shapes",
    "MassMoments",
    "ModalBasis",
    "modal_basis",
]


@lru_cache(maxsize=None)
def clamped_free_roots(n: int) -> tuple:
    """Roots ``beta_i L`` of ``1 + cos(z) cosh(z) = 0``, i = 1..n (dimensionless).

    Newton's method on ``cos(z) + 1/cosh(z)`` (same roots, no overflow) from
    ``(2i - 1) pi / 2``, to the last bit (NumPy only: SciPy's optimizer package costs a
    second of start-up).
    """
    roots = []
    for i in range(1, n + 1):
        z = (2 * i - 1) * np.pi / 2
        for _ in range(50):
            step = (np.cos(z) + 1.0 / np.cosh(z)) / (-np.sin(z) - np.tanh(z) / np.cosh(z))
            z -= step
            if abs(step) <= 1e-16 * z:
                break
        roots.append(float(z))
    return tuple(roots)


def axial_shapes(x, n: int, L: float, derivative: int = 0) -> np.ndarray:
    """Axial shape functions ``f1`` (or their derivatives) at points ``x``.

    Parameters
    ----------
    x : array_like
        Positions along the beam [m].
    n : int
        Number of modes.
    L : float
        Beam length [m].
    derivative : {0, 1}
        Order of the x-derivative.

    Returns
    -------
    ndarray, shape (len(x), n)
        Values [-] (derivative 1: [1/m]).
    """
    x = np.atleast_1d(np.asarray(x, dtype=float))
    k = (2 * np.arange(1, n + 1) - 1) * np.pi / (2 * L)
    z = np.outer(x, k)
    if derivative == 0:
        return np.sin(z)
    if derivative == 1:
        return np.cos(z) * k
    raise ValueError("derivative must be 0 or 1")


def transverse_shapes(x, n: int, L: float, derivative: int = 0) -> np.ndarray:
    """Clamped-free beam eigenfunctions ``f2`` (or derivatives) at points ``x``.

    Parameters
    ----------
    x : array_like
        Positions along the beam [m], 0 <= x <= L.
    n : int
        Number of modes (accurate up to at least 20).
    L : float
        Beam length [m].
    derivative : {0, 1, 2}
        Order of the x-derivative.

    Returns
    -------
    ndarray, shape (len(x), n)
        Values [-] (derivative k: [1/m^k]), normalised to ``int_0^L f2_i^2 dx = L``.
    """
    x = np.atleast_1d(np.asarray(x, dtype=float))
    bl = np.array(clamped_free_roots(n))
    b = bl / L
    # s = (cosh bL + cos bL)/(sinh bL + sin bL); 1 - s and 1 + s without cancellation
    e = np.exp(-bl)
    den = 1.0 - e * e + 2.0 * np.sin(bl) * e          # 2 e^{-bL} (sinh bL + sin bL)
    s = (1.0 + e * e + 2.0 * np.cos(bl) * e) / den
    one_minus_s_scaled = 2.0 * (np.sin(bl) - np.cos(bl) - e) / den  # (1 - s) e^{bL}
    z = np.outer(x, b)
    grow = one_minus_s_scaled * np.exp(z - bl)        # (1-s) e^{z}
    decay = (1.0 + s) * np.exp(-z)                    # (1+s) e^{-z}
    if derivative == 0:
        out = 0.5 * (grow + decay) - np.cos(z) + s * np.sin(z)
    elif derivative == 1:
        out = b * (0.5 * (grow - decay) + np.sin(z) + s * np.cos(z))
    elif derivative == 2:
        out = b ** 2 * (0.5 * (grow + decay) + np.cos(z) - s * np.sin(z))
    else:
        raise ValueError("derivative must be 0, 1 or 2")
    return out  # this form already has int f^2 dx = L


def _gauss_nodes(L: float, n_modes: int, refine: int = 1):
    """Composite Gauss-Legendre rule on [0, L]: nodes, weights, segment edges."""
    segments = refine * max(8, 2 * n_modes)
    p = 16
    xi, wi = np.polynomial.legendre.leggauss(p)
    edges = np.linspace(0.0, L, segments + 1)
    h = np.diff(edges)
    nodes = (edges[:-1, None] + 0.5 * h[:, None] * (xi[None, :] + 1.0)).ravel()
    weights = (0.5 * h[:, None] * wi[None, :]).ravel()
    return nodes, weights, edges, (xi, wi)


def foreshortening_matrices(x, n: int, L: float, refine: int = 1) -> np.ndarray:
    """``S(x) = int_0^x f2'(xi)^T f2'(xi) dxi`` at points ``x``.

    Parameters
    ----------
    x : float or array_like
        Positions along the beam [m], in [0, L].
    n : int
        Transverse modes.
    L : float
        Beam length [m].
    refine : int
        Subdivisions of each quadrature segment (accuracy checks).

    Returns
    -------
    ndarray, shape (len(x), n, n)
        [1/m], symmetric positive semidefinite. Exact to quadrature accuracy (~1e-14).
    """
    x = np.atleast_1d(np.asarray(x, dtype=float))
    _, _, edges, (xi, wi) = _gauss_nodes(L, n, refine)
    # integrals over whole segments, cumulated
    seg = np.zeros((len(edges), n, n))
    for k in range(len(edges) - 1):
        a, b = edges[k], edges[k + 1]
        pts = a + 0.5 * (b - a) * (xi + 1.0)
        d = transverse_shapes(pts, n, L, 1)
        seg[k + 1] = seg[k] + 0.5 * (b - a) * np.einsum("g,gi,gj->ij", wi, d, d)
    k = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(edges) - 2)
    a = edges[k]
    pts = a[:, None] + 0.5 * (x - a)[:, None] * (xi[None, :] + 1.0)   # (m, p)
    d = transverse_shapes(pts.ravel(), n, L, 1).reshape(len(x), len(xi), n)
    part = 0.5 * (x - a)[:, None, None] * np.einsum("g,mgi,mgj->mij", wi, d, d)
    return seg[k] + part


@dataclass(frozen=True)
class MassMoments:
    """Inertia integrals of a mass measure ``mu`` (beam ``rho A dx`` and/or point masses).

    With ``s = r + x`` the distance from the hub centre [m]:

    ========  =====================================  ==================
    ``J``     ``int s^2 dmu``                        [kg m^2]
    ``V1``    ``int s f1 dmu``  (n1,)                [kg m]
    ``V2``    ``int s f2 dmu``  (n2,)                [kg m]
    ``M1``    ``int f1^T f1 dmu`` (n1, n1)           [kg]
    ``M2``    ``int f2^T f2 dmu`` (n2, n2)           [kg]
    ``R``     ``int f1^T f2 dmu`` (n1, n2)           [kg]
    ``D``     ``int s S dmu`` (n2, n2)               [kg]
    ``E``     ``int f1_i S_jk dmu`` (n1, n2, n2)     [kg/m]
    ``G``     ``int S_ij f2_k dmu`` (n2, n2, n2)     [kg/m]
    ``F``     ``int S_ij S_kl dmu`` (n2,n2,n2,n2)    [kg/m^2]
    ========  =====================================  ==================

    Attributes
    ----------
    J : float
        ``int s^2 dmu`` [kg m^2].
    V1 : ndarray (n1,)
        ``int s f1 dmu`` [kg m].
    V2 : ndarray (n2,)
        ``int s f2 dmu`` [kg m].
    M1 : ndarray (n1, n1)
        ``int f1^T f1 dmu`` [kg].
    M2 : ndarray (n2, n2)
        ``int f2^T f2 dmu`` [kg].
    R : ndarray (n1, n2)
        ``int f1^T f2 dmu`` [kg].
    D : ndarray (n2, n2)
        ``int s S dmu`` [kg].
    E : ndarray (n1, n2, n2)
        ``int f1_i S_jk dmu`` [kg/m].
    G : ndarray (n2, n2, n2)
        ``int S_ij f2_k dmu`` [kg/m].
    F : ndarray (n2, n2, n2, n2)
        ``int S_ij S_kl dmu`` [kg/m^2].
    """

    J: float
    V1: np.ndarray
    V2: np.ndarray
    M1: np.ndarray
    M2: np.ndarray
    R: np.ndarray
    D: np.ndarray
    E: np.ndarray
    G: np.ndarray
    F: np.ndarray

    def __add__(self, other: "MassMoments") -> "MassMoments":
        return MassMoments(*(getattr(self, k) + getattr(other, k) for k in self.__dataclass_fields__))

    def scaled(self, factor: float) -> "MassMoments":
        """Every moment times ``factor`` (moments per unit mass per length -> of a beam).

        Parameters
        ----------
        factor : float
            Multiplier, e.g. ``rho A`` [kg/m].
        """
        return MassMoments(*(factor * getattr(self, k) for k in self.__dataclass_fields__))


def _moments(x, w, r, f1, f2, S) -> MassMoments:
    s = r + x
    return MassMoments(
        J=float(np.sum(w * s * s)),
        V1=np.einsum("g,g,gi->i", w, s, f1),
        V2=np.einsum("g,g,gi->i", w, s, f2),
        M1=np.einsum("g,gi,gj->ij", w, f1, f1),
        M2=np.einsum("g,gi,gj->ij", w, f2, f2),
        R=np.einsum("g,gi,gj->ij", w, f1, f2),
        D=np.einsum("g,g,gij->ij", w, s, S),
        E=np.einsum("g,gi,gjk->ijk", w, f1, S),
        G=np.einsum("g,gij,gk->ijk", w, S, f2),
        F=np.einsum("g,gij,gkl->ijkl", w, S, S),
    )


@dataclass(frozen=True)
class ModalBasis:
    """Modal integrals of a :class:`~hubbeam_ctrl.plant.params.Params` (see module docstring).

    Attributes
    ----------
    params : Params
        The beam the integrals are of.
    beam : MassMoments
        Moments of the beam alone (``J.J`` is the paper's ``J_b``).
    tip : MassMoments
        Moments of the point tip mass ``m_t`` at ``l``.
    K1 : ndarray (n1, n1)
        Axial stiffness ``int EA f1'^T f1' dx`` [N/m].
    K2 : ndarray (n2, n2)
        Bending stiffness ``int EI f2''^T f2'' dx`` [N/m].
    f1_tip, f2_tip : ndarray
        Shape functions at the free end x = L [-] (tip outputs).
    S_tip : ndarray (n2, n2)
        ``S(L)`` [1/m] (foreshortening of the free end).
    f2pp_root : ndarray (n2,)
        ``f2''(0)`` [1/m^2] (root bending moment ``EI f2''(0) q2``).
    """

    params: Params
    beam: MassMoments
    tip: MassMoments
    K1: np.ndarray
    K2: np.ndarray
    f1_tip: np.ndarray
    f2_tip: np.ndarray
    S_tip: np.ndarray
    f2pp_root: np.ndarray

    @property
    def total(self) -> MassMoments:
        """Moments of beam plus tip mass (what the models use)."""
        return self.beam + self.tip

    @property
    def J_b(self) -> float:
        """Beam inertia about the hub centre ``int rho A (r+x)^2 dx`` [kg m^2]."""
        return self.beam.J

    def S(self, x) -> np.ndarray:
        """Foreshortening matrix ``S(x)`` [1/m] at positions ``x`` [m], shape (len(x), n2, n2).

        Parameters
        ----------
        x : float or array_like
            Positions along the beam [m].
        """
        p = self.params
        return foreshortening_matrices(x, p.n_transverse, p.L)


@lru_cache(maxsize=32)
def _unit_integrals(L: float, r: float, n1: int, n2: int, refine: int) -> tuple:
    """The integrals that depend only on the geometry and mode counts (per unit rho A, EA, EI).

    A new tip mass, tip position, density, area or modulus then costs only the tip's moments
    and three scalings (the foreshortening moments of 20 modes take ~0.2 s to integrate).
    """
    x, w, _, _ = _gauss_nodes(L, max(n1, n2), refine)
    f1 = axial_shapes(x, n1, L)
    f2 = transverse_shapes(x, n2, L)
    S = foreshortening_matrices(x, n2, L, refine)
    beam = _moments(x, w, r, f1, f2, S)
    d1 = axial_shapes(x, n1, L, 1)
    d2 = transverse_shapes(x, n2, L, 2)
    xL = np.array([L])
    out = (beam, np.einsum("g,gi,gj->ij", w, d1, d1), np.einsum("g,gi,gj->ij", w, d2, d2),
           axial_shapes(xL, n1, L)[0], transverse_shapes(xL, n2, L)[0],
           foreshortening_matrices(xL, n2, L, refine)[0], transverse_shapes(np.array([0.0]), n2, L, 2)[0])
    for a in [getattr(beam, k) for k in beam.__dataclass_fields__] + list(out[1:]):
        if isinstance(a, np.ndarray):
            a.setflags(write=False)
    return out


def _build_basis(params: Params, refine: int = 1) -> ModalBasis:
    p = params
    n1, n2, L = p.n_axial, p.n_transverse, p.L
    beam, K1, K2, f1_tip, f2_tip, S_tip, f2pp_root = _unit_integrals(float(L), float(p.r), n1, n2, refine)
    xt = np.array([p.tip_position])
    tip = _moments(xt, np.array([p.m_t]), p.r, axial_shapes(xt, n1, L),
                   transverse_shapes(xt, n2, L), foreshortening_matrices(xt, n2, L, refine))
    return ModalBasis(params=p, beam=beam.scaled(p.rhoA), tip=tip, K1=p.EA * K1, K2=p.EI * K2,
                      f1_tip=f1_tip, f2_tip=f2_tip, S_tip=S_tip, f2pp_root=f2pp_root)


@lru_cache(maxsize=64)
def modal_basis(params: Params, refine: int = 1) -> ModalBasis:
    """Compute (and cache) the modal integrals for ``params``.

    Parameters
    ----------
    params : Params
    refine : int
        Multiplies the number of quadrature segments (1 is converged to ~1e-13
        relative up to 20 modes; tests compare against ``refine=2``).

    Returns
    -------
    ModalBasis

    Examples
    --------
    >>> b = modal_basis(Params(m_t=0.0))
    >>> round(b.J_b, 3)   # rho A ((r+L)^3 - r^3) / 3
    41.318
    """
    return _build_basis(params, refine)
