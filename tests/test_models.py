"""Models from energies: term-by-term check against the paper's FOAM, conservation laws."""

import numpy as np
import pytest

from hubbeam_ctrl import Params, build_model, simulate
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.basis import axial_shapes, foreshortening_matrices, transverse_shapes


def paper_foam(params, q, v):
    """The paper's Eqs. (24)-(34) without the Delta terms, plus the appendix's tip mass
    (A1)-(A10) with r_A + l, written out by hand. Returns (M, bias) with bias = 2 thd G v +
    K q - Q so that M a + bias = [tau, 0, 0]."""
    from hubbeam_ctrl.plant.basis import modal_basis
    b = modal_basis(params)
    n1, n2 = params.n_axial, params.n_transverse
    m, l, r = params.m_t, params.tip_position, params.r
    f1 = axial_shapes([l], n1, params.L)[0]
    f2 = transverse_shapes([l], n2, params.L)[0]
    S = foreshortening_matrices([l], n2, params.L)[0]
    bm = b.beam
    # beam plus the appendix's tip terms, each written from point values
    J = bm.J + m * (r + l) ** 2
    M1 = bm.M1 + m * np.outer(f1, f1)
    M2 = bm.M2 + m * np.outer(f2, f2)
    V1 = bm.V1 + m * (r + l) * f1
    V2 = bm.V2 + m * (r + l) * f2
    R = bm.R + m * np.outer(f1, f2)
    D = bm.D + m * (r + l) * S
    th_d = v[0]
    q1, q2 = q[1:1 + n1], q[1 + n1:]
    q1d, q2d = v[1:1 + n1], v[1 + n1:]
    n = 1 + n1 + n2
    M = np.zeros((n, n))
    M[0, 0] = params.J_h + J + q1 @ M1 @ q1 + q2 @ M2 @ q2 + 2 * V1 @ q1 - q2 @ D @ q2   # (25)
    M[1:1 + n1, 0] = M[0, 1:1 + n1] = -R @ q2                                          # (26)
    M[1 + n1:, 0] = M[0, 1 + n1:] = V2 + q1 @ R                                        # (27)
    M[1:1 + n1, 1:1 + n1] = M1
    M[1 + n1:, 1 + n1:] = M2
    G = np.zeros((n, n))
    G[1:1 + n1, 1 + n1:] = -R                                                          # (29)
    G[1 + n1:, 1:1 + n1] = R.T
    K = np.zeros((n, n))
    K[1:1 + n1, 1:1 + n1] = b.K1 - th_d ** 2 * M1                                      # (30)
    K[1 + n1:, 1 + n1:] = b.K2 - th_d ** 2 * M2 + th_d ** 2 * D                        # (31)
    Q = np.zeros(n)
    Q[0] = -2 * th_d * (q1 @ M1 @ q1d + q2 @ M2 @ q2d + V1 @ q1d - q2 @ D @ q2d)        # (32)
    Q[1:1 + n1] = th_d ** 2 * V1                                                       # (33)
    return M, 2 * th_d * G @ v + K @ q - Q, Q[0]


@pytest.mark.parametrize("params", [Params(m_t=0.0), Params(), Params(m_t=0.5, l=3.0, n_axial=3, n_transverse=4)])
def test_foam_equals_paper_equations(params):
    model = build_model("foam", params)
    rng = np.random.default_rng(1)
    for _ in range(5):
        q = rng.normal(size=model.n_q) * np.r_[1.0, 1e-3 * np.ones(model.n_q - 1)]
        v = rng.normal(size=model.n_q) * np.r_[3.0, 1e-2 * np.ones(model.n_q - 1)]
        M_ref, bias_ref, q_theta_ref = paper_foam(params, q, v)
        M = model.mass_matrix(q)
        np.testing.assert_allclose(M, M_ref, rtol=1e-12, atol=1e-12 * np.abs(M_ref).max())
        bias = model.bias(q, v)
        np.testing.assert_allclose(bias, bias_ref, rtol=1e-10, atol=1e-10 * np.abs(bias_ref).max())
        assert model.q_theta(q, v) == pytest.approx(q_theta_ref, rel=1e-10, abs=1e-14)


def test_tlam_is_foam_without_foreshortening(table1):
    foam, tlam = build_model("foam", table1), build_model("tlam", table1)
    D = foam.basis.total.D
    q = np.r_[0.3, 1e-4 * np.ones(5), 0.02 * np.ones(5)]
    v = np.r_[2.0, np.zeros(10)]
    dM = foam.mass_matrix(q) - tlam.mass_matrix(q)
    assert dM[0, 0] == pytest.approx(-q[6:] @ D @ q[6:], rel=1e-12)
    db = foam.bias(q, v) - tlam.bias(q, v)
    np.testing.assert_allclose(db[6:], 4.0 * D @ q[6:], rtol=1e-10)


def test_sfoam_is_foam_without_axial_and_q_theta(table1):
    foam, sfoam = build_model("foam", table1), build_model("sfoam", table1)
    rng = np.random.default_rng(2)
    q2, q2d = 0.05 * rng.normal(size=5), 0.05 * rng.normal(size=5)
    qf = np.r_[0.2, np.zeros(5), q2]
    vf = np.r_[1.5, np.zeros(5), q2d]
    qs, vs = np.r_[0.2, q2], np.r_[1.5, q2d]
    keep = np.r_[0, 6:11]
    np.testing.assert_allclose(sfoam.mass_matrix(qs), foam.mass_matrix(qf)[np.ix_(keep, keep)], rtol=1e-13)
    bf, bs = foam.bias(qf, vf), sfoam.bias(qs, vs)
    np.testing.assert_allclose(bs[1:], bf[6:], rtol=1e-12)
    assert bs[0] == 0.0                                           # Q_theta dropped
    assert sfoam.q_theta(qs, vs) == pytest.approx(-bf[0], rel=1e-12)  # but still reported


def test_cfoam_differs_from_foam_at_third_order(table1):
    """CFOAM's extra terms are of order >= 3 in the elastic coordinates."""
    foam, cfoam = build_model("foam", table1), build_model("cfoam", table1)
    rng = np.random.default_rng(3)
    q0, v0 = rng.normal(size=11), rng.normal(size=11)
    q0[0], v0[0] = 0.0, 0.0
    gaps = []
    for eps in (1e-2, 1e-3):
        q, v = eps * q0, eps * v0
        gaps.append(abs(cfoam.energy(q, v) - foam.energy(q, v)))
    assert gaps[0] > 0
    assert gaps[1] / gaps[0] < 1.1e-3                                 # at least cubic


def _deflected_spinning_state(model, spin=2.0):
    x0 = model.steady_state(spin)
    x0[model.transverse_slice] = np.r_[0.05, -0.01, 0.002, np.zeros(model.n_transverse)][:model.n_transverse]
    x0[model.n_q + model.transverse_slice.start] = 0.02
    return x0


def _check_conservation(name, params, t_end, axial="dynamic"):
    model = build_model(name, params, axial)
    res = simulate(model, None, t_end, x0=_deflected_spinning_state(model), rtol=1e-8, atol=1e-8)
    assert not res.diverged
    E, H = res.energy, res.angular_momentum
    assert np.max(np.abs(E - E[0])) / abs(E[0]) < 1e-6
    assert np.max(np.abs(H - H[0])) / abs(H[0]) < 1e-6
    # the elastic motion is real: the bending energy exchanges with the hub
    assert np.ptp(res.v_tip) > 0.1 and np.ptp(res.theta_dot) > 1e-5


@pytest.mark.parametrize("name", ["tlam", "foam", "cfoam"])
def test_free_unforced_conserves_energy_and_momentum_small(name):
    """Fast tier: 2 + 2 modes for 10 s (measured drift <= 1.4e-8 of T + U)."""
    _check_conservation(name, Params(n_axial=2, n_transverse=2), 10.0)


@pytest.mark.parametrize("name", ["tlam", "foam", "cfoam"])
def test_quasi_static_axial_conserves_energy_and_momentum(name):
    """The condensed Lagrangian (axial coordinates from their static balance) is still a
    Lagrangian: Jacobi's energy and the angular momentum stay constant (fast tier, 2 + 2 modes)."""
    _check_conservation(name, Params(n_axial=2, n_transverse=2), 10.0, axial="quasi-static")


@pytest.mark.parametrize("name", ["tlam", "foam", "cfoam"])
def test_quasi_static_axial_solves_the_static_balance(name):
    """q1* makes dL/dq1 = 0 of the dynamic model's Lagrangian with the axial rates zero (central
    differences of T - U), and at a steady spin it is the static stretch."""
    params = Params(n_axial=3, n_transverse=4, m_t=0.2, l=6.5)
    qs, dyn = build_model(name, params, "quasi-static"), build_model(name, params)
    assert qs.n_q == 1 + 4 and dyn.n_q == 1 + 3 + 4
    rng = np.random.default_rng(11)
    q, v = 0.05 * rng.normal(size=qs.n_q), rng.normal(size=qs.n_q)
    v[0] = 4.0
    q1 = qs.axial_coordinates(q, v)

    def lagrangian(q1_):
        qf, vf = np.r_[q[0], q1_, q[1:]], np.r_[v[0], np.zeros(3), v[1:]]
        T, U, _ = (float(x) for x in dyn.parametric.energy(qf, vf, dyn.p))
        return T - U

    def gradient(q1_, h=1e-7):
        return np.array([(lagrangian(q1_ + h * e) - lagrangian(q1_ - h * e)) / (2 * h) for e in np.eye(3)])

    assert np.max(np.abs(gradient(q1))) < 1e-6 * np.max(np.abs(gradient(0 * q1)))
    x = qs.steady_state(7.0)
    np.testing.assert_allclose(qs.axial_coordinates(x[:qs.n_q], x[qs.n_q:]), dyn.static_axial_stretch(7.0),
                               rtol=1e-12)
    # the tip sees the stretch: u_tip = f1(l) q1* - q2' S(l) q2 / 2
    v_tip, u_tip = qs.tip(q, v)
    ref = dyn.tip(np.r_[q[0], q1, q[1:]])
    assert (v_tip, u_tip) == pytest.approx(ref, rel=1e-12)
    Q, V = 0.05 * rng.normal(size=(20, qs.n_q)), rng.normal(size=(20, qs.n_q))
    series = qs.tip_series(Q, V)
    np.testing.assert_allclose(np.array([qs.tip(a, b) for a, b in zip(Q, V)]).T, series, rtol=1e-12, atol=1e-16)


def test_quasi_static_axial_refuses_bad_input():
    with pytest.raises(ParameterError, match=r"^axial must be one of dynamic, quasi-static, got 'static'$"):
        build_model("foam", Params(), "static")
    with pytest.raises(ParameterError, match=r"^axial = 'quasi-static' needs a model with axial modes"):
        build_model("sfoam", Params(), "quasi-static")
    qs = build_model("foam", Params(n_axial=2, n_transverse=2), "quasi-static")
    with pytest.raises(ParameterError, match=r"^v \(the velocities\) is needed"):
        qs.tip(np.zeros(qs.n_q))
    with pytest.raises(ParameterError, match=r"^axial = 'dynamic' differs from the model's own"):
        simulate(qs, None, 1.0, axial="dynamic")


@pytest.mark.slow
@pytest.mark.parametrize("name", ["tlam", "foam", "cfoam"])
def test_free_unforced_conserves_energy_and_momentum(name, table1):
    """Full tier: Table 1 with 5 + 5 modes for 12 s (about 5 periods of the first bending mode; was
    30 s, cut for the suite's 10-minute budget: the drift bound is the same and the 10 s fast tier
    covers the long run's mechanism on 2 + 2 modes)."""
    _check_conservation(name, table1, 12.0)


def test_sfoam_does_not_conserve(table1):
    """Dropping Q_theta breaks the conservation that FOAM keeps from the same start."""
    drifts = {}
    for name in ("sfoam", "foam"):
        model = build_model(name, table1)
        x0 = model.steady_state(2.0)
        x0[model.transverse_slice.start] = 0.05
        x0[model.n_q + model.transverse_slice.start] = 0.02
        res = simulate(model, None, 20.0, x0=x0)
        E, H = res.energy, res.angular_momentum
        drifts[name] = (np.max(np.abs(E - E[0])) / abs(E[0]), np.max(np.abs(H - H[0])) / abs(H[0]))
    assert drifts["sfoam"][0] > 100 * drifts["foam"][0] and drifts["sfoam"][0] > 1e-7
    assert drifts["sfoam"][1] > 100 * drifts["foam"][1] and drifts["sfoam"][1] > 1e-7


def test_state_derivative_and_hub_torque(table1):
    model = build_model("cfoam", table1)
    rng = np.random.default_rng(4)
    q, v = 0.01 * rng.normal(size=11), 0.01 * rng.normal(size=11)
    xdot = model.state_derivative(np.r_[q, v], tau=12.0)
    np.testing.assert_array_equal(xdot[:11], v)
    assert model.hub_torque(q, v, xdot[11:]) == pytest.approx(12.0, rel=1e-9)


@pytest.mark.parametrize("name", ["tlam", "foam", "cfoam", "sfoam"])
def test_tip_series_is_the_tip_function_on_every_sample(name):
    """The closed loop's vectorised NumPy tip equals the CasADi tip function sample by sample."""
    model = build_model(name, Params(n_axial=3, n_transverse=4, m_t=0.2))
    q = 0.05 * np.random.default_rng(7).normal(size=(50, model.n_q))
    v_tip, u_tip = model.tip_series(q)
    ref = np.array([model.tip(row) for row in q])
    np.testing.assert_allclose(v_tip, ref[:, 0], rtol=1e-13, atol=1e-16)
    np.testing.assert_allclose(u_tip, ref[:, 1], rtol=1e-12, atol=1e-16)
    assert np.ptp(u_tip) > 0 and np.ptp(v_tip) > 0
