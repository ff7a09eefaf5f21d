"""MPC: DAQP called directly against CasADi's conic solvers on the same QPs."""

import math

import numpy as np
import pytest

from controllers import MPC, DesignModel, MPCSettings, slew_reference
from controllers.mpc import DirectDAQP
from hubbeam_ctrl import Params

P2 = Params(n_axial=2, n_transverse=2)
DT, TAU_MAX = 0.01, 200.0


@pytest.fixture(scope="module")
def slew():
    design = DesignModel.build(P2, 0.0, DT)
    J = P2.total_inertia
    angle = TAU_MAX * 10.0 ** 2 / (2 * math.pi * J)
    return design, slew_reference(angle, 10.0, J, TAU_MAX, DT, 12.0)


def _first_moves(design, ref, solvers, steps, **settings):
    """First moves of each solver's MPC along the trajectory of the first one (linear model)."""
    mpcs = {s: MPC(design, MPCSettings(solver=s, tau_max=TAU_MAX, **settings), ref) for s in solvers}
    for m in mpcs.values():
        m.reset()
    x = np.zeros(design.n_x)
    moves = {s: [] for s in solvers}
    for k in range(steps):
        t = k * DT
        for s, m in mpcs.items():
            moves[s].append(m(t, x))
        x = design.Ad @ x + design.Bd[:, 0] * moves[solvers[0]][-1]
    for m in mpcs.values():
        assert m.stats()["qp_fallbacks"] == 0
    return {s: np.array(v) for s, v in moves.items()}


@pytest.mark.parametrize("steps_from", [0, 480])     # start of the slew, and its braking (saturated)
def test_direct_daqp_agrees_with_conic_solvers(slew, steps_from):
    design, ref = slew
    moves = _first_moves(design, ref, ("daqp", "daqp-casadi", "qpoases"), steps_from + 40, horizon=50)
    for other in ("daqp-casadi", "qpoases"):
        assert np.max(np.abs(moves["daqp"] - moves[other])) <= 1e-6      # N m
    assert np.max(np.abs(moves["daqp"])) > 10.0                           # the plans do work


def test_direct_daqp_agrees_with_soft_tip_bound(slew):
    design, ref = slew
    moves = _first_moves(design, ref, ("daqp", "daqp-casadi"), 120, horizon=30, tip_bound=0.05,
                         tip_bound_weight=1e8)
    assert np.max(np.abs(moves["daqp"] - moves["daqp-casadi"])) <= 1e-6


def test_direct_daqp_small_qp_and_failure():
    qp = DirectDAQP(2 * np.eye(2), np.array([[1.0, 1.0]]), -np.ones(2), np.ones(2))
    # min z'z + g'z, |z_i| <= 1, z_1 + z_2 <= 0.2: optimum of the projection of -g/2
    z = qp.solve(np.array([-1.0, -1.0]), np.array([-np.inf]), np.array([0.2]))
    np.testing.assert_allclose(z, [0.1, 0.1], atol=1e-12)
    z = qp.solve(np.array([-1.0, 4.0]), np.array([-np.inf]), np.array([np.inf]))
    np.testing.assert_allclose(z, [0.5, -1.0], atol=1e-12)
    with pytest.raises(RuntimeError, match="QP failed: daqp exit flag"):
        qp.solve(np.zeros(2), np.array([5.0]), np.array([6.0]))      # infeasible: z_1 + z_2 <= 2
