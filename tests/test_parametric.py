"""Parameters as inputs: one set of functions per model family and mode counts."""

import numpy as np
import pytest

from hubbeam_ctrl import Params, build_model
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.basis import modal_basis
from hubbeam_ctrl.plant.models import pair_map, parameter_layout, parametric_model, reduced_foreshortening
from hubbeam_ctrl.sim.stepper import StepperSettings, step_functions

P_A = Params(n_axial=3, n_transverse=3, m_t=0.1)
P_B = Params(n_axial=3, n_transverse=3, m_t=0.45, l=0.6, damping_ratio=0.02)


@pytest.mark.parametrize("name", ["cfoam", "foam", "tlam", "sfoam"])
def test_functions_are_shared_across_parameters(name):
    a, b = build_model(name, P_A), build_model(name, P_B)
    assert a.parametric is b.parametric is parametric_model(name, a.n_axial, a.n_transverse)
    assert a.p.shape == (a.parametric.n_p,) and not np.array_equal(a.p, b.p)
    step_a, jac_a, _ = step_functions(a, StepperSettings(), "vm")
    step_b, jac_b, _ = step_functions(b, StepperSettings(), "vm")
    assert step_a is step_b and jac_a is jac_b


@pytest.mark.parametrize("name", ["cfoam", "foam", "tlam", "sfoam"])
def test_parameter_vector_carries_the_moments(name):
    m = build_model(name, P_B)
    tot = m.basis.total
    M0 = m.mass_matrix(np.zeros(m.n_q))
    assert M0[0, 0] == pytest.approx(P_B.J_h + tot.J, rel=1e-14)              # J_h + int s^2 dmu
    sl2 = m.transverse_slice
    np.testing.assert_allclose(M0[sl2, sl2], tot.M2, rtol=1e-13)
    np.testing.assert_allclose(M0[0, sl2], tot.V2, rtol=1e-13)
    # at rest with the hub still: c(q, 0) = K q (stiffness only)
    q = np.zeros(m.n_q)
    q[sl2] = [1e-3, -2e-3, 5e-4]
    c = m.bias(q, np.zeros(m.n_q))
    K2 = m.basis.K2
    np.testing.assert_allclose(c[sl2], K2 @ q[sl2], rtol=1e-9, atol=1e-12 * np.abs(K2).max())
    # the damping: c(0, v) elastic part = C v
    v = np.zeros(m.n_q)
    v[sl2] = 1.0
    zeta = P_B.damping_ratio
    expected = 2 * zeta * np.sqrt(np.diag(m.basis.K2) * np.diag(m.basis.beam.M2))
    assert np.all(expected > 0)
    c_v = m.bias(np.zeros(m.n_q), v)[sl2]
    np.testing.assert_allclose(c_v, expected, rtol=1e-12)


@pytest.mark.parametrize("axial", ["dynamic", "quasi-static"])
def test_cfoam_on_mx_equals_cfoam_on_sx(axial):
    """The MX build (dense products on the pair moments) gives the SX build's numbers: every
    model function, the stepper's step and iteration matrix, IDAS's Jacobian."""
    import casadi as ca

    from hubbeam_ctrl.plant.models import ParametricModel
    from hubbeam_ctrl.sim.simulate import _residual_jacobian
    from hubbeam_ctrl.sim.stepper import _fast_step_function, _iteration_matrix_function
    sx, mx = (ParametricModel("cfoam", 3, 4, axial, symbols=k) for k in ("SX", "MX"))
    assert sx.sym is ca.SX and mx.sym is ca.MX
    p = build_model("cfoam", Params(n_axial=3, n_transverse=4, m_t=0.3), axial).p
    rng = np.random.default_rng(5)
    q, v, a = (0.05 * rng.standard_normal(sx.n_q) for _ in range(3))
    v[0] = 2.0

    def close(x, y):
        x, y = np.array(x, dtype=float), np.array(y, dtype=float)
        np.testing.assert_allclose(y, x, rtol=1e-12, atol=1e-13 * np.abs(x).max())

    close(sx.inverse_dynamics(q, v, a, p), mx.inverse_dynamics(q, v, a, p))
    def outputs(f):
        out = f(q, v, p)
        return out if isinstance(out, tuple) else (out,)

    for name in ("energy", "momentum", "q_theta", "bias"):
        for x, y in zip(outputs(getattr(sx, name)), outputs(getattr(mx, name))):
            close(x, y)
    if axial == "dynamic":
        st = StepperSettings()
        s = np.concatenate([q, v, a, a])
        J = np.array(_iteration_matrix_function(sx, st)(s, 3.0, p))
        close(J, _iteration_matrix_function(mx, st)(s, 3.0, p))
        u, Ji = np.full((1, st.substeps), 3.0), np.linalg.inv(J)
        close(_fast_step_function(sx, st)(s, u, Ji, p)[0], _fast_step_function(mx, st)(s, u, Ji, p)[0])
        for x, y in zip(_residual_jacobian(sx)(q, v, a, p, 0)[:3], _residual_jacobian(mx)(q, v, a, p, 0)[:3]):
            close(x, y)


def test_large_cfoam_graph_does_not_grow():
    """From MX_FROM_TRANSVERSE modes on CFOAM is MX: its residual is the same graph at 8 and 16
    modes (the SX residual of 10 + 10 has 67k instructions), and builds in well under a second."""
    import time

    from hubbeam_ctrl.plant.models import MX_FROM_TRANSVERSE, ParametricModel
    sizes = []
    for n2 in (MX_FROM_TRANSVERSE, 2 * MX_FROM_TRANSVERSE):
        t0 = time.process_time()
        pm = ParametricModel("cfoam", 2, n2)
        sizes.append(pm.inverse_dynamics.n_nodes())
        assert time.process_time() - t0 < 1.0
    assert sizes[0] == sizes[1] < 1000
    assert parametric_model("cfoam", 2, MX_FROM_TRANSVERSE - 1).sym.__name__ == "SX"


def test_bound_function_equals_parametric_evaluation():
    m = build_model("cfoam", P_B)
    rng = np.random.default_rng(3)
    q, v, a = (0.05 * rng.standard_normal(m.n_q) for _ in range(3))
    bound = np.array(m.inverse_dynamics_function(q, v, a)).ravel()
    direct = np.array(m.parametric.inverse_dynamics(q, v, a, m.p)).ravel()
    np.testing.assert_allclose(bound, direct, rtol=1e-12, atol=1e-12 * np.abs(direct).max())


def test_reduced_foreshortening_is_exact():
    n2 = 4
    mom = modal_basis(Params(n_axial=2, n_transverse=n2, m_t=0.2)).total
    red = reduced_foreshortening(mom)
    rng = np.random.default_rng(7)
    q, qd = rng.standard_normal(n2), rng.standard_normal(n2)
    pairs = [(i, j) for i in range(n2) for j in range(i, n2)]
    y = np.array([q[i] * q[j] for i, j in pairs])
    yd = np.array([0.5 * (q[i] * qd[j] + q[j] * qd[i]) for i, j in pairs])
    Fm = mom.F.reshape(n2 * n2, n2 * n2)
    qq, qqd = np.outer(q, q).ravel(), np.outer(q, qd).ravel()
    assert y @ red["F_r"] @ y == pytest.approx(qq @ Fm @ qq, rel=1e-12)
    assert yd @ red["F_r"] @ yd == pytest.approx(qqd @ Fm @ qqd, rel=1e-12)
    np.testing.assert_allclose(red["E_r"] @ yd, mom.E.reshape(2, -1) @ qqd, rtol=1e-12)
    np.testing.assert_allclose(y @ red["G_r"], qq @ mom.G.reshape(n2 * n2, n2), rtol=1e-12)
    W = pair_map(n2)
    assert W.shape == (16, 10) and W.sum() == 16


def test_parameter_layout_and_bad_values():
    layout = parameter_layout("cfoam", 2, 3)
    names = [k for k, _ in layout]
    assert names[:2] == ["J_h", "J"] and names[-3:] == ["E_r", "G_r", "F_r"]
    assert dict(layout)["F_r"] == (6, 6)
    assert "F_r" not in dict(parameter_layout("foam", 2, 3))
    pm = parametric_model("foam", 2, 3)
    fields = build_model("foam", Params(n_axial=2, n_transverse=3))._parameter_fields()
    fields["M2"] = np.zeros((2, 2))
    with pytest.raises(ParameterError, match=r"parameter M2 must have shape \(3, 3\)"):
        pm.values(fields)


def test_functions_are_built_on_first_use():
    """A family's functions are built when first used, once; an unknown name is an AttributeError."""
    from hubbeam_ctrl.plant.models import ParametricModel
    pm = ParametricModel("foam", 1, 2)
    assert not any(name in pm.__dict__ for name in ParametricModel.FUNCTIONS)
    f = pm.energy
    assert f is pm.energy and f.name() == "energy" and "energy" in pm.__dict__ and "bias" not in pm.__dict__
    with pytest.raises(AttributeError, match="no attribute 'energi'"):
        pm.energi
