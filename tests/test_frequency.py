"""Laub's Hessenberg frequency response (controllers.frequency) against dense solves."""

import numpy as np
import pytest

from controllers.frequency import FEW_POINTS, FrequencyResponse, hessenberg_form, hessenberg_response


def _dense(A, B, C, z):
    eye = np.eye(len(A))
    return np.array([(C @ np.linalg.solve(zz * eye - A, B))[0, 0] for zz in z])


@pytest.mark.parametrize("n", [1, 2, 7, 40])
def test_hessenberg_response_equals_dense_solves(n):
    """Random loops (rows swapped at some points and not at others) on and off the unit circle."""
    rng = np.random.default_rng(n)
    A = rng.standard_normal((n, n)) / np.sqrt(n)
    B, C = rng.standard_normal((n, 1)), rng.standard_normal((1, n))
    z = np.concatenate([np.exp(1j * np.linspace(0.01, np.pi, 300)), 2.5 * np.exp(1j * np.linspace(0, 3, 50))])
    got = hessenberg_response(*hessenberg_form(A, B, C), z)
    ref = _dense(A, B, C, z)
    assert np.max(np.abs(got / ref - 1)) < 1e-10


def test_an_ill_conditioned_modal_form_takes_the_hessenberg_solves():
    """Three Jordan blocks and nothing else (no modal form, nothing to split off): every point is
    solved, in batches through the Hessenberg form and one by one below FEW_POINTS, the same values."""
    A = np.diag([0.9, 0.9, 0.5, 0.5, -0.3, -0.3])
    A[0, 1] = A[2, 3] = A[4, 5] = 1.0
    rng = np.random.default_rng(0)
    T = rng.standard_normal((6, 6))
    A = T @ A @ np.linalg.inv(T)
    B, C = rng.standard_normal((6, 1)), rng.standard_normal((1, 6))
    fr = FrequencyResponse(A, B, C, 0.25)
    assert fr._modal is None and fr._split is None
    z = np.exp(1j * np.linspace(0.05, np.pi, 400))
    ref = _dense(A, B, C, z) + 0.25
    assert np.max(np.abs(fr(z) / ref - 1)) < 1e-10 and fr._hessenberg is not None
    few = z[:FEW_POINTS - 1]
    np.testing.assert_allclose(fr(few, precise=True), ref[:FEW_POINTS - 1], rtol=1e-12)


def test_a_zero_pivot_is_swapped_away():
    """At z = 0.5 the first pivot of zI - H is exactly zero: only the row exchange solves it."""
    H = np.array([[0.5, 1.0, 0.3], [1.0, 0.2, -0.4], [0.0, 0.7, 0.1]])
    b, c = np.array([1.0, -2.0, 0.5]), np.array([0.3, 1.0, -1.0])
    z = np.array([0.5, 0.5 + 1e-3j, -0.8j])
    ref = [c @ np.linalg.solve(zz * np.eye(3) - H, b) for zz in z]
    np.testing.assert_allclose(hessenberg_response(H, b, c, z), ref, rtol=1e-12)
