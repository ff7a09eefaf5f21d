"""Modal basis: eigenfunctions, analytic integrals, quadrature convergence."""

import numpy as np
import pytest

from hubbeam_ctrl import Params, modal_basis
from hubbeam_ctrl.plant.basis import axial_shapes, clamped_free_roots, transverse_shapes


def test_clamped_free_roots():
    roots = np.array(clamped_free_roots(20))
    np.testing.assert_allclose(roots[:5], [1.875104069, 4.694091133, 7.854757438,
                                           10.99554073, 14.13716839], rtol=1e-9)
    assert np.max(np.abs(np.cos(roots) * np.cosh(roots) + 1) / np.cosh(roots)) < 1e-13


def test_eigenfunctions_accurate_to_20_modes():
    """Boundary conditions and tip values hold to machine precision up to mode 20."""
    L, n = 8.0, 20
    f = transverse_shapes([0.0, L], n, L)
    d1 = transverse_shapes([0.0], n, L, 1)
    d2 = transverse_shapes([L], n, L, 2)
    assert np.max(np.abs(f[0])) < 1e-12 and np.max(np.abs(d1)) < 1e-12
    np.testing.assert_allclose(np.abs(f[1]), 2.0, rtol=1e-12)        # |f(L)| = 2
    beta = np.array(clamped_free_roots(n)) / L
    assert np.max(np.abs(d2[0]) / beta ** 2) < 1e-10                 # moment-free end


def test_analytic_integrals():
    p = Params(m_t=0.0, n_axial=20, n_transverse=20)
    b = modal_basis(p)
    rhoAL = p.rhoA * p.L
    np.testing.assert_allclose(b.beam.M2, rhoAL * np.eye(20), atol=1e-12 * rhoAL)
    np.testing.assert_allclose(b.beam.M1, rhoAL / 2 * np.eye(20), atol=1e-12 * rhoAL)
    beta = np.array(clamped_free_roots(20)) / p.L
    np.testing.assert_allclose(np.diag(b.K2), p.EI * beta ** 4 * p.L, rtol=1e-11)
    k = (2 * np.arange(1, 21) - 1) * np.pi / (2 * p.L)
    np.testing.assert_allclose(np.diag(b.K1), p.EA * k ** 2 * p.L / 2, rtol=1e-11)
    assert b.J_b == pytest.approx(p.rhoA * ((p.r + p.L) ** 3 - p.r ** 3) / 3, rel=1e-13)
    # S(L) = int f2'^T f2' dx;  D is symmetric positive definite
    S_L = b.S([p.L])[0]
    np.testing.assert_allclose(S_L, b.S_tip)
    assert np.all(np.linalg.eigvalsh(b.beam.D) > 0)


@pytest.mark.parametrize("n", [5, 20])
def test_quadrature_converged(n):
    """Doubling the quadrature changes no modal integral by more than 1e-10 relative."""
    p = Params(n_axial=n, n_transverse=n)
    b1, b2 = modal_basis(p), modal_basis(p, refine=2)
    for name in ("V1", "V2", "M1", "M2", "R", "D", "E", "G", "F"):
        a1, a2 = getattr(b1.total, name), getattr(b2.total, name)
        assert np.max(np.abs(a1 - a2)) <= 1e-10 * np.max(np.abs(a2)), name
    for a1, a2 in ((b1.K1, b2.K1), (b1.K2, b2.K2)):
        assert np.max(np.abs(a1 - a2)) <= 1e-10 * np.max(np.abs(a2))


def test_tip_moments_are_point_values():
    p = Params(m_t=0.3, l=5.0)
    b = modal_basis(p)
    f2 = transverse_shapes([5.0], 5, 8.0)[0]
    f1 = axial_shapes([5.0], 5, 8.0)[0]
    np.testing.assert_allclose(b.tip.M2, 0.3 * np.outer(f2, f2), atol=1e-14)
    np.testing.assert_allclose(b.tip.V1, 0.3 * 5.5 * f1, atol=1e-14)
    np.testing.assert_allclose(b.tip.D, 0.3 * 5.5 * b.S([5.0])[0], atol=1e-14)
    assert b.tip.J == pytest.approx(0.3 * 5.5 ** 2)
